"""Parameter arrays that the PX4 cascade kernel reads from one packed constants vector.

:class:`PX4Agent` packs every law's parameter array into one vector (:func:`~fawtgym.agents.px4_cascade.
pack_constants`, one kernel argument) and gives each law a view of it back.  :class:`InPlaceArray` makes an
assignment to such an attribute (``agent.rate_control.params = new``) write the new values into the array the law
already holds (the view), so what the law computes on its own and what the cascade kernel reads stay one set of
numbers; without it the assignment would silently rebind the law to a new array the kernel never sees.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


class InPlaceArray:
    """A data descriptor for a float64 array attribute: the first assignment stores the array; a later one copies
    its values into the stored array (same shape, else ValueError naming both shapes); :meth:`bind` replaces the
    stored array itself (the agent binds the views of its packed vector)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        try:
            return obj.__dict__[self.name]
        except KeyError:
            raise AttributeError(self.name) from None

    def __set__(self, obj: Any, value: Any) -> None:
        new = np.array(value, dtype=float)
        current = obj.__dict__.get(self.name)
        if current is None:
            obj.__dict__[self.name] = new
            return
        if new.shape != current.shape:
            raise ValueError(f"{type(obj).__name__}.{self.name} must keep its shape {current.shape} (the PX4 cascade "
                             f"reads it from a packed vector), got shape {new.shape}")
        current[...] = new

    @staticmethod
    def bind(obj: Any, name: str, array: NDArray[np.float64]) -> None:
        """Make ``array`` (e.g. a view of a packed vector) the array ``obj.<name>`` holds."""
        obj.__dict__[name] = array
