"""Row masks of batch-first state: validation and the masked write used by every per-row reset.

A batched law keeps its state with a leading row axis N (one row per vehicle).  Rows of a batched env
end at different times, so agents and observers reset chosen rows only (``reset(..., rows=mask)``);
loops that run at their own rate update only the rows that are due.  Both are a masked write:
``state = where(rows, new, old)`` over the row axis.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown


def check_row_mask(rows: ArrayLike, n: int, who: str) -> NDArray[np.bool_]:
    """``rows`` as a bool mask of shape (n,); ValueError (one line, naming what was got) otherwise."""
    try:
        mask = np.asarray(rows)
    except ValueError:                      # ragged nested sequences
        mask = np.asarray(rows, dtype=object)
    if mask.dtype != np.bool_ or mask.shape != (n,):
        raise ValueError(f"{who}: rows must be None (all rows) or a bool array of shape ({n},), one entry per row "
                         f"of the batch; got dtype {mask.dtype} with shape {mask.shape}")
    return mask


def write_rows(state: Any, fresh: Any, rows: NDArray[np.bool_] | None) -> Any:
    """The masked write of a per-row reset: ``state`` with its rows where ``rows`` is True replaced by ``fresh``.

    ``state`` is an array with a leading row axis N, or a dict / tuple of them (of the same keys / length as
    ``fresh``); ``fresh`` holds one row per True entry of ``rows`` (N,), in order.  Returns new arrays (the
    rows where ``rows`` is False are copied bitwise; ``state`` itself is not modified, so arrays an estimate
    returned or a float cache refers to keep their values).  ``rows`` None returns ``fresh`` (a full reset).
    """
    if rows is None:
        return fresh
    if isinstance(fresh, Mapping):
        if not isinstance(state, Mapping) or set(state) != set(fresh):
            raise TypeError(f"write_rows: state keys {sorted(state)} differ from fresh keys {sorted(fresh)}")
        return {k: write_rows(state[k], v, rows) for k, v in fresh.items()}
    if isinstance(fresh, tuple):
        return tuple(write_rows(s, f, rows) for s, f in zip(state, fresh, strict=True))
    out = np.array(state, copy=True)
    out[rows] = fresh
    return out


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
    raise ValueError(f"{who} must be a finite positive number of seconds (or one per row), got {shown(dt)}")


def per_row(dt: float | NDArray[np.float64], ndim: int) -> float | NDArray[np.float64]:
    """A scalar dt as is; an (N,) dt shaped (N, 1, ...) to broadcast against an array of ``ndim`` dims."""
    if isinstance(dt, float):
        return dt
    return dt.reshape(dt.shape + (1,) * (ndim - 1))
