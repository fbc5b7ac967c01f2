"""Attitude from vector measurements: the generalized Wahba cost and its Morse-function error terms.

Source: (Wang and Sanyal, IFAC PapersOnLine 55-22, 2022), Secs. 3-5.

k >= 3 known inertial vectors ``E = [e_1 .. e_k]`` (eq. 7, rank 3) are measured in the body frame,
``U^m = R^T E + Xi`` (eq. 9).  With the generalized weight ``W`` of eq. 13 the Wahba cost (eq. 12)
equals the Morse function ``<K, I - Q>`` of the attitude error ``Q = R R_hat^T`` (eq. 14, Lemma 1).
Its gradient terms used by the HC-ESO are ``s_K(Q)`` (eq. 21), ``s_L(R_hat)`` with
``L = E W (U^m)^T`` (eq. 22, Lemma 2), ``z_L`` (eq. 26), ``w_L = d/dt s_L`` (eq. 27) and ``H``
(eq. 28).  Everything is batch-first: rotation matrices (N, 3, 3), vectors (N, 3); ``E`` and
``W`` are shared by the batch.

For a vehicle with an accelerometer and a magnetometer (the env's IMU) :func:`imu_vector_set`
builds three inertial directions: gravity (down, from the specific force, valid when the
vehicle's own acceleration is small compared with g), the Earth field, and their cross product
(:func:`imu_body_vectors_row`, the row function the HC-ESO's kernel calls).

The batch functions of eqs. 21-28 here are the paper's definitions, used by the tests and the reproduction; the
HC-ESO's kernel evaluates s_L, w_L, z_L and H(s_L) w_L in closed form per row
(:func:`fawtgym.observers.hc_eso.hc_eso_rates_row`), and tests/test_hc_eso_observer.py checks its
rates against these definitions through the error dynamics of eq. 31.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.arrays import REAL_KINDS, as_array
from fawtgym.core.checks import shown
from fawtgym.core.measurement import EARTH_FIELD_NED
from fawtgym.core.so3 import cross, hat, vee
from fawtgym.core.so3_kernels import cross_entries

#: floor on s^T s in the Hölder terms (eqs. 26, 28, 30): they are continuous at s = 0 but their
#: formulas divide by powers of |s|; below this the direction is undefined and the term is ~0.
_S2_FLOOR = 1e-24


def check_vector_set(e: ArrayLike) -> NDArray[np.float64]:
    """Validate the inertial vector matrix E (3, k), k >= 3, rank 3 (Assumption 2, eq. 7)."""
    e = np.asarray(e, dtype=float)
    if e.ndim != 2 or e.shape[0] != 3 or e.shape[1] < 3:
        raise ValueError(f"E must have shape (3, k) with k >= 3 inertial vectors as columns, got {e.shape}")
    if not np.all(np.isfinite(e)):
        raise ValueError("E contains non-finite values")
    sv = np.linalg.svd(e, compute_uv=False)
    if sv[-1] <= 1e-9 * max(sv[0], 1e-300):
        raise ValueError(f"E must have rank 3 (at least three non-collinear vectors, Assumption 2); "
                         f"singular values {sv}")
    return e


def check_morse_gains(k: ArrayLike) -> NDArray[np.float64]:
    """Validate K = diag(k1, k2, k3) with k1 > k2 > k3 >= 1 (Lemma 1), real numbers (bool, complex, str refused);
    returns the diagonal (3,)."""
    given = k
    k = as_array(k)
    if k.dtype.kind not in REAL_KINDS:
        raise ValueError(f"K = diag(k1, k2, k3) needs real numbers k1 > k2 > k3 >= 1 (Lemma 1), got {shown(given)}")
    k = k.astype(np.float64)
    if k.shape == (3, 3):
        if np.any(k != np.diag(np.diag(k))):
            raise ValueError(f"K must be diagonal, got {k}")
        k = np.diag(k)
    if k.shape != (3,) or not np.all(np.isfinite(k)) or not (k[0] > k[1] > k[2] >= 1.0):
        raise ValueError(f"K = diag(k1, k2, k3) needs k1 > k2 > k3 >= 1 (Lemma 1), got {k}")
    return k


def wahba_weight(e: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """Generalized Wahba weight, eq. 13: ``W = E^T (E E^T)^-1 K (E E^T)^-1 E`` (k x k); then E W E^T = K."""
    e = check_vector_set(e)
    kd = np.diag(check_morse_gains(k))
    g = np.linalg.inv(e @ e.T)
    return e.T @ g @ kd @ g @ e


def wahba_cost(e: ArrayLike, u_m: ArrayLike, r_hat: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
    """Wahba cost, eq. 12: ``1/2 <E - R_hat U^m, (E - R_hat U^m) W>``; u_m (N, 3, k), r_hat (N, 3, 3) -> (N,)."""
    d = np.asarray(e, float) - np.asarray(r_hat, float) @ np.asarray(u_m, float)
    return 0.5 * np.einsum("...ij,...ij->...", d, d @ np.asarray(w, float))


def gain_matrix(e: ArrayLike, w: ArrayLike, u_m: ArrayLike) -> NDArray[np.float64]:
    """``L = E W (U^m)^T`` (Lemma 2), (N, 3, 3); with exact measurements L = K R."""
    return np.asarray(e, float) @ np.asarray(w, float) @ np.swapaxes(np.asarray(u_m, float), -1, -2)


def s_k(q: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """``s_K(Q) = vex(K Q - Q^T K)``, eq. 21."""
    kd = np.diag(np.asarray(k, float))
    q = np.asarray(q, float)
    return 2.0 * vee(kd @ q)  # vex(A - A^T) = 2 vee(A) (vee takes the skew part)


_EYE = np.eye(3)


def s_l(l: ArrayLike, r_hat: ArrayLike) -> NDArray[np.float64]:
    """``s_L(R_hat) = vex(L^T R_hat - R_hat^T L)``, eq. 22, (N, 3)."""
    return 2.0 * vee(np.swapaxes(np.asarray(l, float), -1, -2) @ np.asarray(r_hat, float))


def _pow_s2(s: NDArray[np.float64], expo: float) -> NDArray[np.float64]:
    s2 = np.maximum(np.sum(s * s, axis=-1), _S2_FLOOR)
    return s2**expo


def z_l(s: ArrayLike, alpha: float, gamma: float) -> NDArray[np.float64]:
    """``z_L = (s_L^T s_L)^((alpha-1)/gamma) s_L``, eq. 26 (Hölder-continuous, 0 at s_L = 0)."""
    s = np.asarray(s, float)
    return _pow_s2(s, (alpha - 1.0) / gamma)[..., None] * s


def w_l(l: ArrayLike, r_hat: ArrayLike, omega_hat: ArrayLike, omega_m: ArrayLike) -> NDArray[np.float64]:
    """``w_L = d/dt s_L(R_hat)``, eq. 27, for R_hat' = R_hat Omega_hat^x and L' = L (Omega^m)^x.

    ``vex(L^T R_hat W_hat + W_hat R_hat^T L) - vex(R_hat^T L W_m + W_m L^T R_hat)`` with W = Omega^x.
    """
    l = np.asarray(l, float)
    r = np.asarray(r_hat, float)
    wh, wm = hat(omega_hat), hat(omega_m)
    lt_r = np.swapaxes(l, -1, -2) @ r
    rt_l = np.swapaxes(lt_r, -1, -2)
    return vee(lt_r @ wh + wh @ rt_l) - vee(rt_l @ wm + wm @ lt_r)


def h_matrix(x: ArrayLike, alpha: float, gamma: float) -> NDArray[np.float64]:
    """``H(x) = I - 2 (1 - alpha)/gamma x x^T / (x^T x)``, eq. 28, (N, 3, 3); H(0) := I."""
    x = np.asarray(x, float)
    x2 = np.maximum(np.sum(x * x, axis=-1), _S2_FLOOR)[..., None, None]
    return _EYE - 2.0 * (1.0 - alpha) / gamma * (x[..., :, None] * x[..., None, :]) / x2


def solve_wahba(l: ArrayLike) -> NDArray[np.float64]:
    """Static attitude: the R_hat in SO(3) maximizing tr(L^T R_hat) (i.e. minimizing eq. 12), by SVD."""
    from fawtgym.core.so3 import project_so3

    return project_so3(l)


def imu_inertial_vectors(field_ned: ArrayLike = EARTH_FIELD_NED) -> NDArray[np.float64]:
    """Inertial unit vectors (3, 3) used by :func:`imu_vector_set`: down e3, field direction, e3 x field."""
    field = np.asarray(field_ned, float)
    if field.shape != (3,) or not np.all(np.isfinite(field)) or np.linalg.norm(field) == 0:
        raise ValueError(f"field_ned must be a finite non-zero 3-vector, got {shown(field_ned)}")
    g_i = np.array([0.0, 0.0, 1.0])
    m_i = field / np.linalg.norm(field)
    c_i = cross(g_i, m_i)
    if np.linalg.norm(c_i) < 1e-6:
        raise ValueError(f"the Earth field {field} is parallel to gravity; no attitude from these vectors")
    return np.stack([g_i, m_i, c_i / np.linalg.norm(c_i)], axis=1)


def imu_vector_set(specific_force: ArrayLike, magnetometer: ArrayLike,
                   field_ned: ArrayLike = EARTH_FIELD_NED) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Inertial/body unit-vector sets ``(E (3, 3), U^m (N, 3, 3))`` from an accelerometer and a magnetometer.

    Columns: gravity direction (NED down e3; body ``-f / |f|`` since the specific force is
    ``R^T (a - g e3)``), the Earth field direction, and their normalized cross product.  A column
    whose body vector has (near) zero length (free fall, missing magnetometer) raises ValueError.
    """
    f = np.atleast_2d(np.asarray(specific_force, float))
    m = np.atleast_2d(np.asarray(magnetometer, float))
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(m))):
        raise ValueError("specific_force / magnetometer contain non-finite values")
    e = imu_inertial_vectors(field_ned)
    return e, imu_body_vectors(f, m)


#: the messages of :func:`imu_body_vectors_row`'s status codes 1, 2, 3
IMU_VECTOR_ERRORS = ("specific force has (near) zero length; cannot use it as a direction (free fall?)",
                     "magnetometer has (near) zero length; cannot use it as a direction",
                     "gravity x field has (near) zero length; cannot use it as a direction (vectors collinear)")


@njit(cache=True)
def imu_body_vectors_row(f, m, U):
    """U^m (3, 3) of one row into ``U``: columns -f/|f| (the gravity direction), m/|m| and their normalized cross
    product.  Returns 0, or 1, 2, 3 (:data:`IMU_VECTOR_ERRORS`) where a direction has length < 1e-9."""
    n = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    if n < 1e-9:
        return 1
    g0, g1, g2 = -f[0] / n, -f[1] / n, -f[2] / n
    n = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
    if n < 1e-9:
        return 2
    m0, m1, m2 = m[0] / n, m[1] / n, m[2] / n
    c0, c1, c2 = cross_entries(g0, g1, g2, m0, m1, m2)  # g_b x m_b
    n = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if n < 1e-9:
        return 3
    U[0, 0], U[0, 1], U[0, 2] = g0, m0, c0 / n
    U[1, 0], U[1, 1], U[1, 2] = g1, m1, c1 / n
    U[2, 0], U[2, 1], U[2, 2] = g2, m2, c2 / n
    return 0


@njit(cache=True)
def _imu_body_vectors_rows(f, m, U):
    for i in range(f.shape[0]):
        code = imu_body_vectors_row(f[i], m[i], U[i])
        if code:
            return code
    return 0


def imu_body_vectors(f: NDArray[np.float64], m: NDArray[np.float64]) -> NDArray[np.float64]:
    """U^m (N, 3, 3) of :func:`imu_vector_set` for finite (N, 3) arrays (columns -f/|f|, m/|m|, their
    normalized cross product, :func:`imu_body_vectors_row`); ValueError where a direction has (near) zero length."""
    f = np.ascontiguousarray(f, dtype=float)
    m = np.ascontiguousarray(np.broadcast_to(np.asarray(m, dtype=float), f.shape))
    U = np.empty(f.shape + (3,))
    code = _imu_body_vectors_rows(f, m, U)
    if code:
        raise ValueError(IMU_VECTOR_ERRORS[code - 1])
    return U
