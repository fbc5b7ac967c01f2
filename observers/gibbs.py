"""Gibbs-vector (Rodrigues parameter) attitude kinematics and dynamics, batch-first.

Source: Silva and Santos (2023), Sec. 4, eqs. 45-55 and 80: the attitude matrix D(g) (45), Gamma(g) (48),
g' = 1/2 Gamma(g) omega (47), the rigid body omega' = J^-1 (J omega x omega + u + d) (49), g'' (52) =
1/2 [Gamma'(g) omega + Gamma(g) omega'] with Gamma' = g g'^T + g' g^T + [g' x], and omega = 2 Gamma(g)^-1 g'
(80) with Gamma(g)^-1 = (I - [g x]) / (1 + g^T g).

Frames.  The paper's S^g and S^b are world NED and body FRD; its D^{b/g} maps world to body components, so
D = R^T with the project's R (body -> world): :func:`gibbs_to_rot` returns R = D(g)^T and :func:`rot_to_gibbs`
the g of D = R^T.

The maps the observers use in their kernels (R = D(g)^T, omega of eq. 80, g of a rotation) are row functions
(``*_row``, numba) and the batch functions here call them, so each exists once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.kernel_types import NO_REFCOUNT
from fawtgym.core.so3 import cross, hat
from fawtgym.core.so3_kernels import cross_entries

_EYE = np.eye(3)


# --------------------------------------------------------------------------------------------------
# row functions (used inside the observer kernels)
# --------------------------------------------------------------------------------------------------
@njit(cache=True, **NO_REFCOUNT)
def gibbs_to_rot_row(g0, g1, g2, R):
    """R = D(g)^T = ((1 - g.g) I + 2 g g^T + 2 [g x]) / (1 + g.g) (eq. 45, transposed) into R (3, 3)."""
    gg = g0 * g0 + g1 * g1 + g2 * g2
    d, m = 1.0 - gg, 1.0 + gg
    R[0, 0], R[0, 1], R[0, 2] = (d + 2.0 * g0 * g0) / m, 2.0 * (g0 * g1 - g2) / m, 2.0 * (g0 * g2 + g1) / m
    R[1, 0], R[1, 1], R[1, 2] = 2.0 * (g1 * g0 + g2) / m, (d + 2.0 * g1 * g1) / m, 2.0 * (g1 * g2 - g0) / m
    R[2, 0], R[2, 1], R[2, 2] = 2.0 * (g2 * g0 - g1) / m, 2.0 * (g2 * g1 + g0) / m, (d + 2.0 * g2 * g2) / m


@njit(cache=True, **NO_REFCOUNT)
def omega_row(g0, g1, g2, d0, d1, d2):
    """omega = 2 Gamma(g)^-1 g' = 2 (g' - g x g') / (1 + g.g) (eq. 80) of one row."""
    m = 1.0 + (g0 * g0 + g1 * g1 + g2 * g2)
    x0, x1, x2 = cross_entries(g0, g1, g2, d0, d1, d2)  # g x g'
    return 2.0 * (d0 - x0) / m, 2.0 * (d1 - x1) / m, 2.0 * (d2 - x2) / m


@njit(cache=True, **NO_REFCOUNT)
def rot_to_gibbs_row(R, den_floor, max_norm):
    """g of D = R^T: 2 vee(R) / (1 + tr R) = tan(theta/2) axis, with 1 + tr R floored at ``den_floor`` and the
    result clipped to norm ``max_norm`` (a half turn has no Gibbs vector)."""
    den = 1.0 + (R[0, 0] + R[1, 1] + R[2, 2])
    den = den if den > den_floor else den_floor
    g0, g1, g2 = (R[2, 1] - R[1, 2]) / den, (R[0, 2] - R[2, 0]) / den, (R[1, 0] - R[0, 1]) / den
    n = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    if n > max_norm:
        g0, g1, g2 = g0 * max_norm / n, g1 * max_norm / n, g2 * max_norm / n
    return g0, g1, g2


@njit(cache=True)
def _gibbs_to_rot_rows(g, R):
    for i in range(g.shape[0]):
        gibbs_to_rot_row(g[i, 0], g[i, 1], g[i, 2], R[i])


@njit(cache=True)
def _omega_rows(g, gd, w):
    for i in range(g.shape[0]):
        w[i, 0], w[i, 1], w[i, 2] = omega_row(g[i, 0], g[i, 1], g[i, 2], gd[i, 0], gd[i, 1], gd[i, 2])


@njit(cache=True)
def _rot_to_gibbs_rows(R, g):
    for i in range(R.shape[0]):
        g[i, 0], g[i, 1], g[i, 2] = rot_to_gibbs_row(R[i], 0.0, np.inf)


def _rows(x: ArrayLike, trailing: tuple[int, ...]) -> tuple[NDArray[np.float64], tuple[int, ...]]:
    """(x as C-contiguous float rows (M, *trailing), the leading shape)."""
    a = np.asarray(x, dtype=float)
    lead = a.shape[:a.ndim - len(trailing)]
    return np.ascontiguousarray(a.reshape((-1,) + trailing)), lead


# --------------------------------------------------------------------------------------------------
# batch functions (leading axes allowed)
# --------------------------------------------------------------------------------------------------
def gibbs_to_rot(g: ArrayLike) -> NDArray[np.float64]:
    """R = D(g)^T (eq. 45), body -> world (NED/FRD), (..., 3) -> (..., 3, 3)."""
    rows, lead = _rows(g, (3,))
    R = np.empty((rows.shape[0], 3, 3))
    _gibbs_to_rot_rows(rows, R)
    return R.reshape(lead + (3, 3))


def gibbs_matrix(g: ArrayLike) -> NDArray[np.float64]:
    """D(g) of eq. 45 (world -> body components) = R^T, (..., 3) -> (..., 3, 3)."""
    return np.swapaxes(gibbs_to_rot(g), -1, -2)


def rot_to_gibbs(R: ArrayLike) -> NDArray[np.float64]:
    """Gibbs vector g of D = R^T: g = tan(theta/2) a for R = exp(theta a^); raises at a half turn."""
    rows, lead = _rows(R, (3, 3))
    if np.any(1.0 + np.trace(rows, axis1=-2, axis2=-1) <= 1e-9):
        raise ValueError("rotation is (near) a half turn: its Gibbs vector is infinite")
    g = np.empty((rows.shape[0], 3))
    _rot_to_gibbs_rows(rows, g)
    return g.reshape(lead + (3,))


def gamma(g: ArrayLike) -> NDArray[np.float64]:
    """Gamma(g) = g g^T + [g x] + I (eq. 48)."""
    g = np.asarray(g, dtype=float)
    return g[..., :, None] * g[..., None, :] + hat(g) + _EYE


def gamma_inv(g: ArrayLike) -> NDArray[np.float64]:
    """Gamma(g)^-1 = (I - [g x]) / (1 + g^T g) (Gamma is invertible for every finite g)."""
    g = np.asarray(g, dtype=float)
    return (_EYE - hat(g)) / (1.0 + np.sum(g * g, axis=-1))[..., None, None]


def gibbs_rate(g: ArrayLike, omega: ArrayLike) -> NDArray[np.float64]:
    """g' = 1/2 Gamma(g) omega (eq. 47), omega body FRD [rad/s]."""
    return 0.5 * np.einsum("...ij,...j->...i", gamma(g), np.asarray(omega, dtype=float))


def omega_from_gibbs(g: ArrayLike, g_dot: ArrayLike) -> NDArray[np.float64]:
    """omega = 2 Gamma(g)^-1 g' (eq. 80), (..., 3)."""
    g_arr, gd_arr = np.broadcast_arrays(np.asarray(g, dtype=float), np.asarray(g_dot, dtype=float))
    rows, lead = _rows(g_arr, (3,))
    drows, _ = _rows(gd_arr, (3,))
    w = np.empty_like(rows)
    _omega_rows(rows, drows, w)
    return w.reshape(lead + (3,))


def rigid_body_rhs(omega: ArrayLike, inertia: ArrayLike, torque: ArrayLike) -> NDArray[np.float64]:
    """omega' = J^-1 (J omega x omega + tau) (eq. 49; Wang et al. (2024) eq. 38 in FRD), numpy (..., 3) arrays: a
    reference for tests and the paper reproductions (the kernels use
    :func:`fawtgym.core.so3_kernels.known_angular_acceleration_entries`)."""
    J = np.asarray(inertia, dtype=float)
    w = np.asarray(omega, dtype=float)
    return np.einsum("ij,...j->...i", np.linalg.inv(J), cross(np.einsum("ij,...j->...i", J, w), w)
                     + np.asarray(torque, dtype=float))


def gibbs_accel(g: ArrayLike, g_dot: ArrayLike, omega: ArrayLike, inertia: ArrayLike, torque: ArrayLike,
                disturbance: ArrayLike | None = None) -> NDArray[np.float64]:
    """g'' of eq. 52 / 54: 1/2 [Gamma'(g) omega + Gamma(g) J^-1 (J omega x omega + u + d)]."""
    g = np.asarray(g, dtype=float)
    g_dot = np.asarray(g_dot, dtype=float)
    omega = np.asarray(omega, dtype=float)
    tau = np.asarray(torque, dtype=float) + (0.0 if disturbance is None else np.asarray(disturbance, dtype=float))
    gamma_dot = g[..., :, None] * g_dot[..., None, :] + g_dot[..., :, None] * g[..., None, :] + hat(g_dot)
    omega_dot = rigid_body_rhs(omega, inertia, tau)
    return 0.5 * (np.einsum("...ij,...j->...i", gamma_dot, omega) + np.einsum("...ij,...j->...i", gamma(g), omega_dot))
