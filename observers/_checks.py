"""The observer validation layer's row checks: one pass over the rows of an array, compiled with numba.

:meth:`fawtgym.observers.base.Observer.update` checks every input and every estimate in front of and behind
the law; at N = 1 a numpy reduction per array costs about a microsecond, a compiled pass a few hundred
nanoseconds, so the checks that read every entry are kernels here.  Each returns the first bad row (or -1):
the Python caller words the one-line error, the same text at every N.  ``NUMBA_DISABLE_JIT=1`` runs them
as plain Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: a measured attitude R is a rotation if max |(R^T R - I)_ij| <= ROTATION_TOL and det R > 0.  Rotations built
#: from a unit quaternion in float64 are orthonormal to ~1e-15, from float32 entries to ~1e-7 (a flight log);
#: a 1.001-scaled rotation is off by 2e-3, a reflection has det -1.
ROTATION_TOL = 1e-6


@njit(cache=True)
def first_nonfinite_row(a: NDArray[np.float64]) -> int:
    """The first row (index along axis 0) of ``a`` (N, k) holding a NaN or an infinity; -1 if every entry is finite."""
    n, k = a.shape
    for i in range(n):
        for j in range(k):
            if not math.isfinite(a[i, j]):
                return i
    return -1


@njit(cache=True)
def first_large_row(a: NDArray[np.float64], bound: float) -> int:
    """The first row of ``a`` (N, k) with an entry that is not finite or exceeds ``bound`` in magnitude; -1 if none."""
    n, k = a.shape
    for i in range(n):
        for j in range(k):
            x = a[i, j]
            if not (abs(x) <= bound):        # NaN fails the comparison
                return i
    return -1


@njit(cache=True)
def first_non_rotation(r: NDArray[np.float64], tol: float, out: NDArray[np.float64]) -> int:
    """The first row of ``r`` (N, 3, 3) that is not a rotation, -1 if all are.

    A rotation: max_ij |(R^T R - I)_ij| <= ``tol`` and det R > 0 (a reflection, 2 I, zeros, a random matrix
    and a scaled rotation fail).  For the row returned, ``out`` (2,) receives (max |R^T R - I|, det R).
    """
    n = r.shape[0]
    for i in range(n):
        err = 0.0
        for a in range(3):
            for b in range(3):
                gram = r[i, 0, a] * r[i, 0, b] + r[i, 1, a] * r[i, 1, b] + r[i, 2, a] * r[i, 2, b]   # (R^T R)_ab
                d = abs(gram - (1.0 if a == b else 0.0))
                if not (d <= err):           # also catches NaN
                    err = d
        det = (r[i, 0, 0] * (r[i, 1, 1] * r[i, 2, 2] - r[i, 1, 2] * r[i, 2, 1])
               - r[i, 0, 1] * (r[i, 1, 0] * r[i, 2, 2] - r[i, 1, 2] * r[i, 2, 0])
               + r[i, 0, 2] * (r[i, 1, 0] * r[i, 2, 1] - r[i, 1, 1] * r[i, 2, 0]))
        if not (err <= tol and det > 0.0):
            out[0] = err
            out[1] = det
            return i
    return -1
