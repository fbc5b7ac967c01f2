"""Array inputs of the compiled kernels: real numbers as float64, checked once in front of the kernel."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

#: numpy dtype kinds accepted as real numbers (int, uint, float; bool "b", complex "c", str and objects refused)
REAL_KINDS = "iuf"


def as_array(value: Any) -> NDArray[Any]:
    """``np.asarray(value)``, or a 0-d object array for what numpy cannot make an array of (ragged nested sequences):
    the caller tests ``.dtype.kind`` against :data:`REAL_KINDS` and words its own error, naming its argument."""
    if type(value) is np.ndarray:
        return value
    try:
        return np.asarray(value)
    except (ValueError, TypeError):  # ragged nested sequences
        return np.asarray(None, dtype=object)


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


class ReadOnlyState:
    """A class attribute that hands out the instance's private array ``_<name>`` as a read-only view (kernel state:
    the compiled kernels read and write it by index and trust its shape, so it is never assigned from outside);
    assigning raises AttributeError with ``refusal.format(name=name)`` (one line saying what to use instead)."""

    def __init__(self, doc: str, refusal: str) -> None:
        self.__doc__, self.refusal = doc, refusal

    def __set_name__(self, owner: type, name: str) -> None:
        self.name, self.private = name, "_" + name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        return self if obj is None else read_only(getattr(obj, self.private))

    def __set__(self, obj: Any, value: object) -> None:
        raise AttributeError(self.refusal.format(name=self.name))
