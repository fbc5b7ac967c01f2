"""The observer validation layer's row checks: one pass over the rows of an array, compiled with numba.

:meth:`fawtgym.observers.base.Observer.update` checks every input and every estimate in front of and behind
the law; at N = 1 a numpy reduction per array costs about a microsecond, a compiled pass a few hundred
nanoseconds, so the checks that read every entry are kernels here (the rotation check is
:func:`fawtgym.core.so3_kernels.first_non_rotation`).  Each returns the first bad row (or -1):
the Python caller words the one-line error, the same text at every N.  ``NUMBA_DISABLE_JIT=1`` runs them
as plain Python.

The update's input checks in one call: :data:`INPUT_CHECKS` is a small fixed family of kernels, one per kind of
measurement key set (with or without one attitude (N, 3, 3), and 1 to 4 rows-of-vectors keys (N, 3)), each checking
the shapes against N, thrust (N,) and torque (N, 3) finite, every vector row finite and the attitude a rotation
(:func:`fawtgym.core.so3_kernels.first_non_rotation` within :data:`ROTATION_TOL`): the same row checks as
:func:`fawtgym.observers.base.check_measurement` and :func:`fawtgym.observers.base.check_inputs`, in one compiled call
of exactly as many arguments as the observer has keys (at N = 1 a 7-argument call measured ~0.4 us, each argument
~0.03-0.06 us: one kernel taking every kind, with placeholders for the absent keys, would pass up to 5 more).  They
return only pass/fail: on a failure the Python checks run and word the error.
"""

from __future__ import annotations

import math

import numpy as np
from numba import boolean, int64, njit
from numpy.typing import NDArray

from fawtgym.core.kernel_types import ROTATIONS, ROWS, VALUES
from fawtgym.core.so3_kernels import ROTATION_TOL, first_non_rotation  # the one tolerance (re-exported here)


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


# ---- the update's input checks in one call (Observer.update's compiled fast path) ---------------------------------
@njit(cache=True)
def _inputs_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64]) -> bool:
    """thrust (n,) and torque (n, 3), finite (:func:`~fawtgym.observers.base.check_inputs`)."""
    return (thrust.shape[0] == n and torque.shape[0] == n and torque.shape[1] == 3
            and first_nonfinite_input(thrust, torque) < 0)


@njit(cache=True)
def _rows_pass(a: NDArray[np.float64], n: int) -> bool:
    """A vector key (n, 3), every row finite."""
    return a.shape[0] == n and a.shape[1] == 3 and first_nonfinite_row(a) < 0


@njit(cache=True)
def _rotations_pass(r: NDArray[np.float64], n: int) -> bool:
    """The attitude (n, 3, 3), every row a rotation (finite, max |R^T R - I| <= ROTATION_TOL, det R > 0)."""
    return r.shape[0] == n and r.shape[1] == 3 and r.shape[2] == 3 and first_non_rotation(r, ROTATION_TOL) < 0


@njit(cache=True)
def rows1_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], a: NDArray[np.float64]) -> bool:
    """Inputs and one vector key pass (the family: :data:`INPUT_CHECKS`)."""
    return _inputs_pass(n, thrust, torque) and _rows_pass(a, n)


@njit(cache=True)
def rows2_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], a: NDArray[np.float64],
               b: NDArray[np.float64]) -> bool:
    """Inputs and two vector keys pass."""
    return _inputs_pass(n, thrust, torque) and _rows_pass(a, n) and _rows_pass(b, n)


@njit(cache=True)
def rows3_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], a: NDArray[np.float64],
               b: NDArray[np.float64], c: NDArray[np.float64]) -> bool:
    """Inputs and three vector keys pass."""
    return _inputs_pass(n, thrust, torque) and _rows_pass(a, n) and _rows_pass(b, n) and _rows_pass(c, n)


@njit(cache=True)
def rows4_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], a: NDArray[np.float64],
               b: NDArray[np.float64], c: NDArray[np.float64], d: NDArray[np.float64]) -> bool:
    """Inputs and four vector keys pass."""
    return rows3_pass(n, thrust, torque, a, b, c) and _rows_pass(d, n)


@njit(cache=True)
def rotation_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], r: NDArray[np.float64]) -> bool:
    """Inputs and the attitude pass."""
    return _inputs_pass(n, thrust, torque) and _rotations_pass(r, n)


@njit(cache=True)
def rotation_rows1_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], r: NDArray[np.float64],
                        a: NDArray[np.float64]) -> bool:
    """Inputs, the attitude and one vector key pass."""
    return rows1_pass(n, thrust, torque, a) and _rotations_pass(r, n)


@njit(cache=True)
def rotation_rows2_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], r: NDArray[np.float64],
                        a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
    """Inputs, the attitude and two vector keys pass."""
    return rows2_pass(n, thrust, torque, a, b) and _rotations_pass(r, n)


@njit(cache=True)
def rotation_rows3_pass(n: int, thrust: NDArray[np.float64], torque: NDArray[np.float64], r: NDArray[np.float64],
                        a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64]) -> bool:
    """Inputs, the attitude and three vector keys pass."""
    return rows3_pass(n, thrust, torque, a, b, c) and _rotations_pass(r, n)


def _signature(rotation: bool, rows: int) -> object:
    """The one signature a check kernel is compiled for: n, thrust (N,), torque (N, 3), [attitude (N, 3, 3),]
    ``rows`` vector keys (N, 3); C-contiguous float64 arrays (:mod:`fawtgym.core.kernel_types`)."""
    return boolean(int64, VALUES, ROWS, *((ROTATIONS,) if rotation else ()), *(ROWS,) * rows)


#: (has an attitude key, number of vector keys) -> (check kernel, its signature); the kernel's arguments are n,
#: thrust, torque, then the attitude (if any), then the vector keys
INPUT_CHECKS = {(False, 1): (rows1_pass, _signature(False, 1)), (False, 2): (rows2_pass, _signature(False, 2)),
                (False, 3): (rows3_pass, _signature(False, 3)), (False, 4): (rows4_pass, _signature(False, 4)),
                (True, 0): (rotation_pass, _signature(True, 0)), (True, 1): (rotation_rows1_pass, _signature(True, 1)),
                (True, 2): (rotation_rows2_pass, _signature(True, 2)),
                (True, 3): (rotation_rows3_pass, _signature(True, 3))}
