"""Row helpers of SO(3), quaternions and Euler angles for compiled kernels (numba), written once.

Every function here works on ONE row (a 3-vector, a 3 x 3 matrix, a (w, x, y, z) quaternion) and writes
its result into an ``out`` array it is given (no allocation), so a kernel that loops over the rows of a
batch calls them per row: ``for i in range(n): exp_so3_row(h * w[i], r_step[i])``.  They are compiled
with ``@njit(cache=True)`` and inlined by numba into the kernels that call them; with
``NUMBA_DISABLE_JIT=1`` they run as plain Python.  The ``*_entries`` helpers take and return scalars instead
(``cross_entries``, ``mat_vec_entries``, the rigid-body ``gyroscopic_entries`` and
``known_angular_acceleration_entries``, ``quat_to_rot_entries``): the laws themselves, which the ``*_row`` helpers
and every kernel of the package call, so that e.g. the cross product is written once (a kernel that holds its
vectors as scalars calls the ``*_entries`` form; inlined, it compiles to the same instructions as the expressions
written out, in the same operation order, so results are bitwise those of the written-out form).

The batch-first functions of :mod:`fawtgym.core.so3` and :mod:`fawtgym.core.frames` with a counterpart here
(``exp_so3``, ``rot_to_euler``, ``quat_to_rot``, ``rot_to_quat``) call these helpers through the ``*_rows``
loops at the end of this module, so each formula exists once; ``tests/test_core_so3_kernels.py`` checks them
against independent references (scipy's Rotation, the defining identities).

Conventions (DESIGN.md): R maps body FRD to world NED; quaternions are (w, x, y, z); Euler angles are
Z-Y-X (roll, pitch, yaw) as PX4's ``matrix::Eulerf``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

#: below this squared angle [rad^2] the Rodrigues coefficients use their Taylor series (as core.so3)
SMALL_ANGLE_SQ = 1e-8
#: a measured attitude R is a rotation if max |(R^T R - I)_jk| <= ROTATION_TOL and det R > 0 (the tolerance the
#: callers of :func:`first_non_rotation` pass: the observers' input checks, the PX4 cascade's).  Rotations built from
#: a unit quaternion in float64 are orthonormal to ~1e-15, from float32 entries to ~1e-7 (a flight log); a
#: 1.001-scaled rotation is off by 2e-3, a reflection has det -1.
ROTATION_TOL = 1e-6


@njit(cache=True, inline="always")
def cross_entries(a0: float, a1: float, a2: float, b0: float, b1: float,
                  b2: float) -> tuple[float, float, float]:
    """a x b of a = (a0, a1, a2), b = (b0, b1, b2): THE cross-product law of the package, scalars in and out (a
    kernel keeps them in registers; inlined, it costs what the three lines written out would).  Every cross product
    (the row helper :func:`cross_row`, the numpy-facing :func:`fawtgym.core.so3.cross`, the kernels of ``envs`` and
    ``observers``) is this function, so each component is ``a_j b_k - a_k b_j`` in this operand order everywhere.
    Plain arithmetic only: it also runs on numpy arrays (componentwise) as :data:`cross_entries_numpy`."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


#: :func:`cross_entries` as plain Python (its ``py_func``; the function itself under ``NUMBA_DISABLE_JIT=1``), for
#: numpy arrays of components: the same operations, elementwise (:func:`fawtgym.core.so3.cross`)
cross_entries_numpy: Callable[..., tuple[Any, Any, Any]] = getattr(cross_entries, "py_func", cross_entries)


@njit(cache=True, inline="always")
def cross_row(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """out = a x b (3-vectors, :func:`cross_entries`); ``out`` may alias ``a`` or ``b``."""
    out[0], out[1], out[2] = cross_entries(a[0], a[1], a[2], b[0], b[1], b[2])


@njit(cache=True, inline="always")
def mat_vec_entries(m: np.ndarray, v0: float, v1: float, v2: float) -> tuple[float, float, float]:
    """M v of a 3 x 3 array M and v = (v0, v1, v2), scalars out (each entry ``m_j0 v0 + m_j1 v1 + m_j2 v2``, summed
    left to right)."""
    return (m[0, 0] * v0 + m[0, 1] * v1 + m[0, 2] * v2,
            m[1, 0] * v0 + m[1, 1] * v1 + m[1, 2] * v2,
            m[2, 0] * v0 + m[2, 1] * v1 + m[2, 2] * v2)


@njit(cache=True, inline="always")
def mat_vec_row(r: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """out = R v (3 x 3 times a 3-vector, :func:`mat_vec_entries`); ``out`` may alias ``v``."""
    out[0], out[1], out[2] = mat_vec_entries(r, v[0], v[1], v[2])


@njit(cache=True, inline="always")
def gyroscopic_entries(inertia: np.ndarray, w0: float, w1: float, w2: float) -> tuple[float, float, float]:
    """(J w) x w, the gyroscopic term of Euler's rigid-body equation J w' = J w x w + tau (body frame; Wang et al.
    (2024) eq. 38), for the inertia J (3 x 3) and the body rate w = (w0, w1, w2).  Its negative w x (J w), the
    feedforward of a rate controller, is ``cross_entries(w, J w)`` (the same products, operands swapped)."""
    jw0, jw1, jw2 = mat_vec_entries(inertia, w0, w1, w2)
    return cross_entries(jw0, jw1, jw2, w0, w1, w2)


@njit(cache=True, inline="always")
def known_angular_acceleration_entries(inertia: np.ndarray, inertia_inv: np.ndarray, w0: float, w1: float, w2: float,
                                       t0: float, t1: float, t2: float) -> tuple[float, float, float]:
    """w' = J^-1 (J w x w + tau): the known part of the body-rate derivative in Wang et al. (2024) eq. 38 (Euler's
    equation; body FRD), from J, J^-1 (3 x 3), the rate w and the torque tau = (t0, t1, t2).  The observers' models
    (``observers._obs_common.known_angular_acceleration_row``, HC-ESO's eq. 30) are this function."""
    g0, g1, g2 = gyroscopic_entries(inertia, w0, w1, w2)
    return mat_vec_entries(inertia_inv, g0 + t0, g1 + t1, g2 + t2)


@njit(cache=True, inline="always")
def mat_t_vec_row(r: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """out = R^T v (world -> body for R body -> world); ``out`` must not alias ``v``."""
    for j in range(3):
        out[j] = r[0, j] * v[0] + r[1, j] * v[1] + r[2, j] * v[2]


@njit(cache=True, inline="always")
def mat_copy_row(a: np.ndarray, out: np.ndarray) -> None:
    """out = A (3 x 3), entry by entry: an array assignment (``out[:, :] = a``) may go through a temporary, which a
    kernel compiled without numba's reference counting (``NO_REFCOUNT``) cannot allocate."""
    for j in range(3):
        for k in range(3):
            out[j, k] = a[j, k]


@njit(cache=True, inline="always")
def mat_mul_row(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """out = A B (3 x 3); ``out`` must not alias ``a`` or ``b``."""
    for j in range(3):
        for k in range(3):
            out[j, k] = a[j, 0] * b[0, k] + a[j, 1] * b[1, k] + a[j, 2] * b[2, k]


@njit(cache=True, inline="always")
def exp_so3_coefficients(t2: float) -> tuple[float, float]:
    """Rodrigues' coefficients (a, b) = (sin t / t, (1 - cos t) / t^2) of exp(w^) from t2 = |w|^2 (Taylor series to
    t^4 below ``SMALL_ANGLE_SQ``; NaN for a non-finite t2).  A function of its own so that a kernel can take those of
    many rows in one loop, where the rows' sin / cos overlap (see :func:`exp_so3_row`)."""
    if not math.isfinite(t2):
        return math.nan, math.nan
    if t2 < SMALL_ANGLE_SQ:
        return 1.0 - t2 / 6.0 + t2 * t2 / 120.0, 0.5 - t2 / 24.0 + t2 * t2 / 720.0
    t = math.sqrt(t2)
    return math.sin(t) / t, (1.0 - math.cos(t)) / t2


@njit(cache=True, inline="always")
def exp_so3_apply(w: np.ndarray, t2: float, a: float, b: float, out: np.ndarray) -> None:
    """out = I + a w^ + b w^ w^ (w^ w^ = w w^T - t2 I written out, no hat matrix formed) with the coefficients of
    :func:`exp_so3_coefficients`; NaN coefficients give an all-NaN ``out``."""
    for j in range(3):
        for k in range(3):
            out[j, k] = b * w[j] * w[k]
        out[j, j] += 1.0 - b * t2
    out[0, 1] -= a * w[2]
    out[0, 2] += a * w[1]
    out[1, 0] += a * w[2]
    out[1, 2] -= a * w[0]
    out[2, 0] -= a * w[1]
    out[2, 1] += a * w[0]


@njit(cache=True, inline="always")
def exp_so3_row(w: np.ndarray, out: np.ndarray) -> None:
    """Rodrigues' formula exp(w^) = I + a w^ + b w^ w^ with a = sin t / t, b = (1 - cos t) / t^2, t = |w|.

    Below ``SMALL_ANGLE_SQ`` a and b are their Taylor series to t^4 (as :func:`fawtgym.core.so3.exp_so3`);
    w^ w^ = w w^T - t^2 I is written out, so no hat matrix is formed.  A non-finite w gives an all-NaN ``out``
    (in compiled and in plain-Python runs alike).  The two parts, :func:`exp_so3_coefficients` and
    :func:`exp_so3_apply`, are the law for kernels that take the coefficients of many rows in a loop of their own.
    """
    t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    a, b = exp_so3_coefficients(t2)
    exp_so3_apply(w, t2, a, b, out)


@njit(cache=True)
def rot_to_euler_row(r: np.ndarray, out: np.ndarray) -> None:
    """Z-Y-X Euler angles (roll, pitch, yaw) of R (FRD -> NED), as :func:`fawtgym.core.frames.rot_to_euler`."""
    out[0] = math.atan2(r[2, 1], r[2, 2])
    out[1] = math.asin(min(max(-r[2, 0], -1.0), 1.0))
    out[2] = math.atan2(r[1, 0], r[0, 0])


@njit(cache=True, inline="always")
def quat_to_rot_entries(qw: float, qx: float, qy: float, qz: float) -> tuple[float, float, float, float, float,
                                                                             float, float, float, float]:
    """The rotation matrix of the quaternion (w, x, y, z), normalized first (the caller refuses a zero one), as its
    nine entries row by row (scalars: a kernel keeps them in registers instead of writing a row view)."""
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    w, x, y, z = qw / norm, qx / norm, qy / norm, qz / norm
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))


@njit(cache=True)
def quat_to_rot_row(q: np.ndarray, out: np.ndarray) -> None:
    """Rotation matrix of the quaternion (w, x, y, z), normalized first (the caller refuses a zero one):
    :func:`quat_to_rot_entries` into ``out`` (3, 3)."""
    (out[0, 0], out[0, 1], out[0, 2], out[1, 0], out[1, 1], out[1, 2], out[2, 0], out[2, 1],
     out[2, 2]) = quat_to_rot_entries(q[0], q[1], q[2], q[3])


@njit(cache=True)
def rot_to_quat_row(r: np.ndarray, out: np.ndarray) -> None:
    """Unit quaternion (w, x, y, z), w >= 0, of R by Shepperd's method (the largest of 1 + trace and the
    diagonal picks the well-conditioned formula), as :func:`fawtgym.core.frames.rot_to_quat`."""
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    if tr >= r[0, 0] and tr >= r[1, 1] and tr >= r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + tr)
        w, x, y, z = 0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s
    elif r[0, 0] >= r[1, 1] and r[0, 0] >= r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        w, x, y, z = (r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s
    elif r[1, 1] >= r[2, 2]:
        s = 2.0 * math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        w, x, y, z = (r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        w, x, y, z = (r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s
    sign = -1.0 if w < 0.0 else 1.0
    norm = sign * math.sqrt(w * w + x * x + y * y + z * z)
    out[0] = w / norm
    out[1] = x / norm
    out[2] = y / norm
    out[3] = z / norm


@njit(cache=True, inline="always")
def rotation_defect_row(r: np.ndarray) -> float:
    """How far R is from a rotation: max |(R^T R - I)_jk| over the entries, or +inf if det R <= 0 or R is
    not finite.  A rotation gives rounding-level values (~1e-16); :func:`first_non_rotation` compares
    against a tolerance."""
    worst = 0.0
    for j in range(3):
        for k in range(3):
            g = r[0, j] * r[0, k] + r[1, j] * r[1, k] + r[2, j] * r[2, k]
            if j == k:
                g -= 1.0
            if not math.isfinite(g):
                return math.inf
            worst = max(worst, abs(g))
    det = (r[0, 0] * (r[1, 1] * r[2, 2] - r[1, 2] * r[2, 1]) - r[0, 1] * (r[1, 0] * r[2, 2] - r[1, 2] * r[2, 0])
           + r[0, 2] * (r[1, 0] * r[2, 1] - r[1, 1] * r[2, 0]))
    if not det > 0.0:
        return math.inf
    return worst


@njit(cache=True)
def first_non_rotation(r: np.ndarray, tol: float) -> int:
    """Index of the first row of ``r`` (N, 3, 3) whose :func:`rotation_defect_row` exceeds ``tol``, or -1."""
    for i in range(r.shape[0]):
        if rotation_defect_row(r[i]) > tol:
            return i
    return -1


# ---- batch loops behind the numpy-facing functions of core.so3 / core.frames (one law each) ----------------
@njit(cache=True)
def exp_so3_rows(w: np.ndarray, out: np.ndarray) -> None:
    """:func:`exp_so3_row` of each row of ``w`` (M, 3) into ``out`` (M, 3, 3)."""
    for i in range(w.shape[0]):
        exp_so3_row(w[i], out[i])


@njit(cache=True)
def rot_to_euler_rows(r: np.ndarray, out: np.ndarray) -> None:
    """:func:`rot_to_euler_row` of each row of ``r`` (M, 3, 3) into ``out`` (M, 3)."""
    for i in range(r.shape[0]):
        rot_to_euler_row(r[i], out[i])


@njit(cache=True)
def quat_to_rot_rows(q: np.ndarray, out: np.ndarray) -> None:
    """:func:`quat_to_rot_row` of each row of ``q`` (M, 4) into ``out`` (M, 3, 3)."""
    for i in range(q.shape[0]):
        quat_to_rot_row(q[i], out[i])


@njit(cache=True)
def rot_to_quat_rows(r: np.ndarray, out: np.ndarray) -> None:
    """:func:`rot_to_quat_row` of each row of ``r`` (M, 3, 3) into ``out`` (M, 4)."""
    for i in range(r.shape[0]):
        rot_to_quat_row(r[i], out[i])
