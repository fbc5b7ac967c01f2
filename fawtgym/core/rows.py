"""Row masks of batch-first state: validation and the masked write used by every per-row reset.

A batched law keeps its state with a leading row axis N (one row per vehicle).  Rows of a batched env
end at different times, so agents and observers reset chosen rows only (``reset(..., rows=mask)``);
loops that run at their own rate update only the rows that are due.  Both are a masked write:
``state = where(rows, new, old)`` over the row axis.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


def check_rows(rows: ArrayLike | None, n: int, who: str) -> NDArray[np.bool_] | None:
    """``rows`` as a bool mask (n,), or None for "all rows" (None or an all-True mask).

    Raises ValueError (one line, the same text at every n apart from the sizes) unless ``rows`` is
    None or a bool array of shape (n,).
    """
    if rows is None:
        return None
    mask = np.asarray(rows)
    if mask.dtype != np.bool_ or mask.shape != (n,):
        raise ValueError(f"{who}: rows must be None (all rows) or a bool mask of shape ({n},) (one entry per "
                         f"row of the batch), got dtype {mask.dtype} shape {mask.shape}")
    return None if mask.all() else mask


def masked(old: NDArray, new: NDArray, rows: NDArray[np.bool_] | None) -> NDArray:
    """``new`` where ``rows`` (N,) is True and ``old`` elsewhere, over the leading axis (``new`` if rows is None)."""
    if rows is None:
        return new
    return np.where(rows.reshape(rows.shape + (1,) * (np.ndim(new) - 1)), new, old)


def check_dt(dt: float | ArrayLike, who: str = "dt") -> float | NDArray[np.float64]:
    """A time step [s]: a finite positive float, or an array (N,) of them (one per row).

    Raises ValueError naming the value otherwise.
    """
    if isinstance(dt, (int, float)) and not isinstance(dt, bool):
        if math.isfinite(dt) and dt > 0:
            return float(dt)
    else:
        a = np.asarray(dt, dtype=float)
        if a.ndim == 0:
            return check_dt(float(a), who)
        if a.ndim == 1 and a.size and np.all(np.isfinite(a)) and np.all(a > 0):
            return a
    raise ValueError(f"{who} must be a finite positive number of seconds (or one per row), got {dt!r}")


def per_row(dt: float | NDArray[np.float64], ndim: int) -> float | NDArray[np.float64]:
    """A scalar dt as is; an (N,) dt shaped (N, 1, ...) to broadcast against an array of ``ndim`` dims."""
    if isinstance(dt, float):
        return dt
    return dt.reshape(dt.shape + (1,) * (ndim - 1))
