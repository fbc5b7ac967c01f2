"""The observer validation layer's row checks: one pass over the rows of an array, compiled with numba.

:meth:`fawtgym.observers.base.Observer.update` checks every input and every estimate in front of and behind
the law; at N = 1 a numpy reduction per array costs about a microsecond, a compiled pass a few hundred
nanoseconds, so the checks that read every entry are kernels here (the rotation check is
:func:`fawtgym.core.so3_kernels.first_non_rotation`).  Each returns the first bad row (or -1):
the Python caller words the one-line error, the same text at every N.  ``NUMBA_DISABLE_JIT=1`` runs them
as plain Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: a measured attitude R is a rotation if max |(R^T R - I)_ij| <= ROTATION_TOL and det R > 0
#: (:func:`fawtgym.core.so3_kernels.first_non_rotation`).  Rotations built from a unit quaternion in float64 are
#: orthonormal to ~1e-15, from float32 entries to ~1e-7 (a flight log); a 1.001-scaled rotation is off by 2e-3,
#: a reflection has det -1.
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
def first_bad_wrench(force: NDArray[np.float64], torque: NDArray[np.float64], force_bound: float,
                     torque_bound: float) -> int:
    """Check an estimate's force and torque (N, 3) against their bounds (NaN and inf fail): -1 if both pass, else
    2 * row for the first bad force row, 2 * row + 1 for the first bad torque row (force checked first)."""
    row = first_large_row(force, force_bound)
    if row >= 0:
        return 2 * row
    row = first_large_row(torque, torque_bound)
    if row >= 0:
        return 2 * row + 1
    return -1


@njit(cache=True)
def first_bad_estimate(force: NDArray[np.float64], torque: NDArray[np.float64], force_bound: float,
                       torque_bound: float, buffer: NDArray[np.float64]) -> int:
    """:func:`first_bad_wrench`, then the finiteness of the buffer (N, k) the estimate's states are views of, in one
    call: -1 if all pass, the wrench's code if it fails, -2 if only the buffer holds a NaN or an infinity."""
    code = first_bad_wrench(force, torque, force_bound, torque_bound)
    if code >= 0:
        return code
    return -2 if first_nonfinite_row(buffer) >= 0 else -1


@njit(cache=True)
def first_nonfinite_input(thrust: NDArray[np.float64], torque: NDArray[np.float64]) -> int:
    """Check the known inputs, thrust (N,) and torque (N, 3): -1 if finite, else 2 * row for the first non-finite
    thrust, 2 * row + 1 for the first non-finite torque row (thrust checked first)."""
    for i in range(thrust.shape[0]):
        if not math.isfinite(thrust[i]):
            return 2 * i
    row = first_nonfinite_row(torque)
    return -1 if row < 0 else 2 * row + 1
