"""Array inputs of the compiled kernels: real numbers as float64, checked once in front of the kernel."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def as_f64(value: Any, name: str) -> NDArray[np.float64]:
    """``value`` as a float64 array (no copy if it is one already); ValueError naming ``name`` for anything that is
    not real numbers (strings, complex, booleans, objects)."""
    if type(value) is np.ndarray and value.dtype == np.float64:
        return value
    raw = np.asarray(value)
    if raw.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be an array of real numbers, got dtype {raw.dtype}")
    return raw.astype(np.float64, copy=False)


def read_only(a: NDArray[Any]) -> NDArray[Any]:
    """A read-only view of ``a`` (kernel state handed out: in-place writes raise numpy's ValueError; ``a`` itself
    stays writeable for its owner)."""
    view = a.view()
    view.flags.writeable = False
    return view
