"""Quaternion backstepping attitude tracking controller with disturbance feedforward.

Source: Shi, Wu & Chou (2018), IEEE Access, Secs. II-B, III-C and V.

Quaternions are Hamilton, scalar first ``(q0, q_v)`` = (w, x, y, z), body FRD -> world NED, with
``q' = 1/2 q (x) [0, omega]`` (eq. 5).  The controller computes

* the attitude error ``q_e = q_d* (x) q`` (eq. 6) and the rate error ``omega_e = omega - C_d^b omega_d``
  (eq. 14) with ``C_d^b = R^T R_d`` mapping desired-frame vectors to the body frame,
* the virtual rate ``omega_ed = -K1 q_ve`` (eq. 41) and its error ``omega_tilde = omega_e + K1 q_ve`` (eq. 43),
* ``N = J (S(omega_e) C_d^b omega_d - C_d^b omega_d') - S(omega) J omega + J K1 q_ve' + q_ve`` (eq. 45) with
  ``q_ve' = 1/2 (S(q_ve) + q_0e I) omega_e`` (eq. 16),
* ``u = u^N + u^E`` (eq. 17), ``u^N = -N - K2 omega_tilde`` (Sec. V), ``u^E = -d_hat`` (eq. 28).

The class holds only the law and its gains (like PX4's AttitudeControl); batch-first, shapes (N, .).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.frames import quat_to_rot
from fawtgym.core.so3 import cross, hat


def quat_multiply(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``a (x) b`` of (..., 4) quaternions (w, x, y, z), eq. 2."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 0] * b[..., 0] - a[..., 1] * b[..., 1] - a[..., 2] * b[..., 2] - a[..., 3] * b[..., 3]
    out[..., 1:] = a[..., :1] * b[..., 1:] + b[..., :1] * a[..., 1:] + cross(a[..., 1:], b[..., 1:])
    return out


def quat_conjugate(q: ArrayLike) -> NDArray[np.float64]:
    """``q* = (q0, -q_v)``."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., :1], -q[..., 1:]], axis=-1)


def quat_derivative(q: ArrayLike, omega: ArrayLike) -> NDArray[np.float64]:
    """``q' = 1/2 q (x) [0, omega]`` for a body rate omega, eq. 5."""
    q = np.asarray(q, dtype=float)
    w = np.asarray(omega, dtype=float)
    out = np.empty(np.broadcast_shapes(q.shape, w.shape[:-1] + (4,)))
    out[..., 0] = -0.5 * np.sum(q[..., 1:] * w, axis=-1)
    out[..., 1:] = 0.5 * (q[..., :1] * w + cross(q[..., 1:], w))
    return out


def euler_to_quat(euler: ArrayLike) -> NDArray[np.float64]:
    """Z-Y-X Euler angles (roll, pitch, yaw) (..., 3) [rad] -> quaternion (..., 4), w >= 0 not enforced."""
    e = np.asarray(euler, dtype=float)
    cr, sr = np.cos(e[..., 0] / 2), np.sin(e[..., 0] / 2)
    cp, sp = np.cos(e[..., 1] / 2), np.sin(e[..., 1] / 2)
    cy, sy = np.cos(e[..., 2] / 2), np.sin(e[..., 2] / 2)
    return np.stack([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy], axis=-1)


def euler_rates_to_body(euler: ArrayLike, euler_rates: ArrayLike) -> NDArray[np.float64]:
    """Body rate of the Z-Y-X Euler frame: ``p = phi' - psi' s_theta``, ``q = theta' c_phi + psi' s_phi c_theta``,
    ``r = -theta' s_phi + psi' c_phi c_theta``."""
    e = np.asarray(euler, dtype=float)
    d = np.asarray(euler_rates, dtype=float)
    sph, cph, sth, cth = np.sin(e[..., 0]), np.cos(e[..., 0]), np.sin(e[..., 1]), np.cos(e[..., 1])
    return np.stack([d[..., 0] - d[..., 2] * sth, d[..., 1] * cph + d[..., 2] * sph * cth,
                     -d[..., 1] * sph + d[..., 2] * cph * cth], axis=-1)


def _gain(value: ArrayLike, name: str) -> NDArray[np.float64]:
    g = np.asarray(value, dtype=float)
    g = np.full(3, float(g)) if g.ndim == 0 else (np.diag(g) if g.shape == (3, 3) else g)
    if g.shape != (3,) or not np.all(np.isfinite(g)) or np.any(g <= 0):
        raise ValueError(f"{name} must be a positive scalar, 3 diagonal entries or a diagonal 3x3 matrix, "
                         f"got {shown(value)}")
    return g


class QuaternionBackstepping:
    """Backstepping attitude tracking law of Shi et al. 2018, Sec. V (default gains: Sec. VI-A, K1 = 11.5 I,
    K2 = 16.2 I)."""

    def __init__(self, inertia: ArrayLike, k1: ArrayLike = 11.5, k2: ArrayLike = 16.2) -> None:
        j = np.asarray(inertia, dtype=float)
        j = np.diag(j) if j.shape == (3,) else j
        if j.shape != (3, 3) or not np.all(np.isfinite(j)) or np.linalg.eigvalsh((j + j.T) / 2).min() <= 0:
            raise ValueError(f"inertia must be positive definite (3 diagonal entries or 3x3), got {shown(inertia)}")
        self.inertia = j
        self.k1 = _gain(k1, "K1")
        self.k2 = _gain(k2, "K2")

    def errors(self, q: ArrayLike, omega: ArrayLike, q_d: ArrayLike,
               omega_d: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(q_e (N, 4), omega_e (N, 3), C_d^b (N, 3, 3))`` of eqs. 6 and 14."""
        q_e = quat_multiply(quat_conjugate(q_d), q)
        c_db = np.swapaxes(quat_to_rot(q_e), -1, -2)  # R_e = R_d^T R (body -> desired); C_d^b = R_e^T
        omega_e = np.asarray(omega, float) - np.einsum("...ij,...j->...i", c_db, np.asarray(omega_d, float))
        return q_e, omega_e, c_db

    def torque(self, q: ArrayLike, omega: ArrayLike, q_d: ArrayLike, omega_d: ArrayLike,
               omega_d_dot: ArrayLike, disturbance: ArrayLike | None = None) -> NDArray[np.float64]:
        """Control torque u (N, 3) [N m, body] for attitude q, body rate omega and the desired (q_d, omega_d,
        omega_d') given in the desired frame; ``disturbance`` is the estimate d_hat fed forward (eq. 28)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        omega = np.atleast_2d(np.asarray(omega, dtype=float))
        arrays = (q, omega, q_d, omega_d, omega_d_dot) + (() if disturbance is None else (disturbance,))
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise ValueError("backstepping controller inputs contain non-finite values")
        q_e, omega_e, c_db = self.errors(q, omega, q_d, omega_d)
        q0e, qve = q_e[..., :1], q_e[..., 1:]
        j = self.inertia
        c_wd = np.einsum("...ij,...j->...i", c_db, np.asarray(omega_d, float))
        c_wd_dot = np.einsum("...ij,...j->...i", c_db, np.asarray(omega_d_dot, float))
        qve_dot = 0.5 * (np.einsum("...ij,...j->...i", hat(qve), omega_e) + q0e * omega_e)  # eq. 16
        jw = omega @ j.T
        n_term = ((cross(omega_e, c_wd) - c_wd_dot) @ j.T - cross(omega, jw)
                  + (self.k1 * qve_dot) @ j.T + qve)  # eq. 45
        omega_tilde = omega_e + self.k1 * qve  # eq. 43
        u = -n_term - self.k2 * omega_tilde
        if disturbance is not None:
            u = u - np.asarray(disturbance, dtype=float)
        return u
