"""Standard normal draws from a NumPy ``Generator``, by the faster of two library routines for the size.

:func:`standard_normals` returns the numbers of ``rng.standard_normal(shape)`` and leaves ``rng`` in the state that
call leaves it in, whichever routine draws them (tested bit for bit, ``tests/test_core_normals.py``):

- NumPy's own fill, ~8 ns a normal on the 2-vCPU VM of docs/performance.md (the C loop calls the bit generator
  through a pointer per number);
- numba's implementation of the same ``Generator.standard_normal`` (the same ziggurat, its tables and its tail,
  reading the same bit generator state through the generator's ctypes interface), ~2.5 ns a normal; but handing a
  ``Generator`` to a compiled function costs ~5 us (numba builds its view of the bit generator per call).

So draws of fewer than :data:`COMPILED_MIN` numbers go to NumPy and larger ones to the compiled draw (the crossover
was measured at ~900 numbers).  The law that uses the numbers is written once either way; this module only chooses
who fills the array.  Numba does not take the generator's lock: a generator drawn from here must not be drawn from
on another thread at the same time (the env's sensor and gust generators are each the env's own).  With
``NUMBA_DISABLE_JIT=1`` the compiled draw is NumPy's call itself.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: draws of at least this many numbers use the compiled routine (module docstring)
COMPILED_MIN = 1024


@njit(cache=True, nogil=True)
def _compiled_standard_normals(rng: np.random.Generator, size: int) -> NDArray[np.float64]:  # pragma: no cover
    """``size`` standard normals from ``rng`` (numba's ``Generator.standard_normal``)."""
    return rng.standard_normal(size)


def standard_normals(rng: np.random.Generator, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """A fresh float64 array of ``shape`` holding the numbers of ``rng.standard_normal(shape)`` (module docstring)."""
    size = math.prod(shape)
    if size < COMPILED_MIN:
        return rng.standard_normal(shape)
    return _compiled_standard_normals(rng, size).reshape(shape)
