"""PX4's multicopter attitude controller (``mc_att_control`` AttitudeControl, v1.13), batch-first.

The law (re-derived; quaternions (w, x, y, z), body FRD -> world NED):

1. reduced attitude: the shortest rotation ``q_red`` taking the current thrust axis ``e_z = R e3`` to
   the desired ``e_z,d``, applied to the current attitude: ``qd_red = q(e_z -> e_z,d) * q``;
2. yaw mixing: ``qd_dyaw = qd_red^-1 qd`` (a pure rotation about z), scaled by the yaw weight
   ``w = MC_YAW_WEIGHT``: ``qd = qd_red * (cos(w acos(qd_dyaw_w)), 0, 0, sin(w asin(qd_dyaw_z)))``;
3. error ``qe = q^-1 qd`` (canonical, w >= 0), ``e = 2 Im(qe)``; rates ``omega_sp = K e`` with
   ``K = (MC_ROLL_P, MC_PITCH_P, MC_YAW_P / w)`` (PX4 compensates the yaw weight in the gain);
4. yaw-rate feedforward ``omega_sp += (R^T e3) yawspeed_sp``;
5. limit each axis to ``MC_ROLLRATE_MAX / MC_PITCHRATE_MAX / MC_YAWRATE_MAX``.

The law is written once, as the row function :func:`attitude_control_row` compiled by numba, which the PX4
cascade kernel (:mod:`fawtgym.agents.px4_cascade`) calls per vehicle and :class:`AttitudeControl` through a
batch kernel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.so3_kernels import mat_copy_row, mat_mul_row, rot_to_quat_row

from .px4_params import PX4Params
from .shared_params import InPlaceArray

#: parameter vector layout (:attr:`AttitudeControl.params`)
GAIN, YAW_WEIGHT, RATE_MAX = 0, 3, 4  # gain (3,), yaw weight, rate limits (3,) [rad/s]
N_PARAMS = 7


@njit(cache=True, inline="always")
def attitude_error_vector_row(r_e: np.ndarray, q: np.ndarray, out: np.ndarray) -> None:
    """``2 Im(q)`` (3,) of the canonical (w >= 0) quaternion of the rotation R_e: ``2 sin(angle/2) axis``.

    Uses ``R - R^T = 4 q_w [q_v]^x``; near a half turn (q_w < 1e-3) falls back to Shepperd's method (``q`` (4,)
    is scratch).
    """
    qw = 0.5 * math.sqrt(max(1.0 + r_e[0, 0] + r_e[1, 1] + r_e[2, 2], 0.0))
    if qw < 1e-3:
        rot_to_quat_row(r_e, q)
        out[0], out[1], out[2] = 2.0 * q[1], 2.0 * q[2], 2.0 * q[3]
        return
    out[0] = (r_e[2, 1] - r_e[1, 2]) / (2.0 * qw)
    out[1] = (r_e[0, 2] - r_e[2, 0]) / (2.0 * qw)
    out[2] = (r_e[1, 0] - r_e[0, 1]) / (2.0 * qw)


@njit(cache=True, inline="always")
def attitude_control_row(r: np.ndarray, r_sp: np.ndarray, yawspeed_sp: float, prm: np.ndarray, qd: np.ndarray,
                         r_e: np.ndarray, red: np.ndarray, q: np.ndarray, rate_sp: np.ndarray) -> None:
    """One vehicle's rate setpoint ``rate_sp`` (3,) [rad/s] from R, R_sp (3, 3) (steps 1-5 of the module docstring).

    ``qd``, ``r_e``, ``red`` (3, 3) and ``q`` (4,) are scratch (given by the caller: views made here, per row,
    would cost an atomic reference count each).  Matrix form of PX4's quaternion law: the reduced rotation
    q(e_z -> e_z,d) is Rodrigues' ``I + [c]^x + [c]^x^2 / (1 + d)`` with ``c = e_z x e_z,d``, ``d = e_z . e_z,d``.
    """
    # 1. reduced attitude qd_red = q(e_z -> e_z,d) q
    cx = r[1, 2] * r_sp[2, 2] - r[2, 2] * r_sp[1, 2]
    cy = r[2, 2] * r_sp[0, 2] - r[0, 2] * r_sp[2, 2]
    cz = r[0, 2] * r_sp[1, 2] - r[1, 2] * r_sp[0, 2]
    d = r[0, 2] * r_sp[0, 2] + r[1, 2] * r_sp[1, 2] + r[2, 2] * r_sp[2, 2]
    if d < -1.0 + 1e-9:  # thrust axes opposite: PX4 takes the full attitude setpoint
        mat_copy_row(r_sp, qd)
    else:
        cc = cx * cx + cy * cy + cz * cz
        # red = I + [c]^x + (c c^T - |c|^2 I) / (1 + d)
        red[0, 0], red[0, 1], red[0, 2] = 1.0 + (cx * cx - cc) / (1.0 + d), -cz + cx * cy / (1.0 + d), \
            cy + cx * cz / (1.0 + d)
        red[1, 0], red[1, 1], red[1, 2] = cz + cy * cx / (1.0 + d), 1.0 + (cy * cy - cc) / (1.0 + d), \
            -cx + cy * cz / (1.0 + d)
        red[2, 0], red[2, 1], red[2, 2] = -cy + cz * cx / (1.0 + d), cx + cz * cy / (1.0 + d), \
            1.0 + (cz * cz - cc) / (1.0 + d)
        mat_mul_row(red, r, qd)
    # 2. yaw mixing: qd_red^T R_sp is a rotation about z by psi; keep w psi of it
    m00 = qd[0, 0] * r_sp[0, 0] + qd[1, 0] * r_sp[1, 0] + qd[2, 0] * r_sp[2, 0]
    m10 = qd[0, 1] * r_sp[0, 0] + qd[1, 1] * r_sp[1, 0] + qd[2, 1] * r_sp[2, 0]
    psi = prm[YAW_WEIGHT] * math.atan2(m10, m00)
    cps, sps = math.cos(psi), math.sin(psi)
    for j in range(3):  # qd <- qd_red R_z(w psi)
        a0, a1 = qd[j, 0], qd[j, 1]
        qd[j, 0] = a0 * cps + a1 * sps
        qd[j, 1] = -a0 * sps + a1 * cps
    # 3. error R_e = R^T qd, e = 2 Im(q_e), rates K e; 4. yaw-rate feedforward (R^T e3) yawspeed; 5. limits
    for j in range(3):
        for m in range(3):
            r_e[j, m] = r[0, j] * qd[0, m] + r[1, j] * qd[1, m] + r[2, j] * qd[2, m]  # R^T qd
    attitude_error_vector_row(r_e, q, rate_sp)
    for j in range(3):
        w = rate_sp[j] * prm[GAIN + j] + r[2, j] * yawspeed_sp
        rate_sp[j] = min(max(w, -prm[RATE_MAX + j]), prm[RATE_MAX + j])


@njit(cache=True)
def _attitude_kernel(r: np.ndarray, r_sp: np.ndarray, yawspeed_sp: np.ndarray, prm: np.ndarray,
                     rate_sp: np.ndarray) -> None:
    work, q = np.empty((3, 3, 3)), np.empty(4)
    qd, r_e, red = work[0], work[1], work[2]
    for i in range(r.shape[0]):
        attitude_control_row(r[i], r_sp[i], yawspeed_sp[i], prm, qd, r_e, red, q, rate_sp[i])


@njit(cache=True)
def _error_vector_kernel(r_e: np.ndarray, out: np.ndarray) -> None:
    q = np.empty(4)
    for i in range(r_e.shape[0]):
        attitude_error_vector_row(r_e[i], q, out[i])


def _rots(x: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(x, dtype=float)
    return np.ascontiguousarray(a[None] if a.ndim == 2 else a)


def attitude_error_vector(r_e: ArrayLike) -> NDArray[np.float64]:
    """``2 Im(q)`` of the canonical (w >= 0) quaternion of rotations R_e (N, 3, 3) (the row law
    :func:`attitude_error_vector_row`)."""
    r = _rots(r_e)
    out = np.empty((r.shape[0], 3))
    _error_vector_kernel(r, out)
    return out


class AttitudeControl:
    """PX4 AttitudeControl for N vehicles: attitude setpoint -> body rate setpoint (N, 3) [rad/s].

    Computed with rotation matrices, which is algebraically the same as PX4's quaternion law: the
    reduced rotation ``q(e_z -> e_z,d)`` is Rodrigues' ``I + [c]^x + [c]^x^2 / (1 + d)`` (c = e_z x e_z,d,
    d = e_z . e_z,d); ``qd_dyaw`` is the rotation about z by ``psi`` with ``|psi| <= pi`` (canonical
    quaternion), and PX4's ``(cos(w acos(qw)), 0, 0, sin(w asin(qz)))`` is the rotation by ``w psi``.
    """
    params = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place

    def __init__(self, params: PX4Params | None = None) -> None:
        p = params if params is not None else PX4Params.s500()
        self.yaw_weight = min(max(p["MC_YAW_WEIGHT"], 0.0), 1.0)
        gain = np.array([p["MC_ROLL_P"], p["MC_PITCH_P"], p["MC_YAW_P"]])
        if self.yaw_weight > 1e-4:
            gain[2] /= self.yaw_weight
        self.gain = gain
        self.rate_limit = np.radians([p["MC_ROLLRATE_MAX"], p["MC_PITCHRATE_MAX"], p["MC_YAWRATE_MAX"]])
        self.params = np.concatenate([self.gain, [self.yaw_weight], self.rate_limit])

    def update(self, attitude: ArrayLike, attitude_sp: ArrayLike,
               yawspeed_sp: ArrayLike | None = None) -> NDArray[np.float64]:
        """Rate setpoint (N, 3) FRD [rad/s] from R (N, 3, 3), R_sp (N, 3, 3) and yaw-rate setpoint (N,) [rad/s]."""
        r = _rots(attitude)
        n = r.shape[0]
        r_sp = np.ascontiguousarray(np.broadcast_to(np.asarray(attitude_sp, dtype=float), r.shape))
        ys = np.zeros(n) if yawspeed_sp is None else np.ascontiguousarray(
            np.broadcast_to(np.asarray(yawspeed_sp, dtype=float), (n,)))
        out = np.empty((n, 3))
        _attitude_kernel(r, r_sp, ys, self.params, out)
        return out


def principal_angle(attitude: ArrayLike, attitude_sp: ArrayLike) -> NDArray[np.float64]:
    """Attitude error principal angle Phi = arccos((tr(R_e) - 1)/2), R_e = R_d^T R (Wang et al. 2024, eq. 88)."""
    r = np.asarray(attitude, dtype=float)
    rd = np.asarray(attitude_sp, dtype=float)
    tr = np.einsum("...ji,...ji->...", rd, r)
    return np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))
