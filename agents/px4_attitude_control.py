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
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.frames import rot_to_quat

from .px4_params import PX4Params


def quat_mul(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hamilton product of (..., 4) quaternions (w, x, y, z)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def quat_inv(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Inverse of unit quaternions (the conjugate)."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_canonical(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """The representative with w >= 0."""
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_between(src: NDArray[np.float64], dst: NDArray[np.float64]) -> NDArray[np.float64]:
    """Shortest rotation (..., 4) taking unit vectors ``src`` to ``dst`` (PX4 ``Quaternion(src, dst)``)."""
    cr = np.cross(src, dst)
    dt = np.einsum("...i,...i->...", src, dst)
    opposite = (np.einsum("...i,...i->...", cr, cr) < 1e-12) & (dt < 0)
    w = dt + np.sqrt(np.einsum("...i,...i->...", src, src) * np.einsum("...i,...i->...", dst, dst))
    if np.any(opposite):
        a = np.abs(src[opposite])
        axis = np.zeros_like(a)
        idx = np.argmin(a, axis=1)
        axis[np.arange(a.shape[0]), idx] = 1.0
        cr = cr.copy()
        w = w.copy()
        cr[opposite] = np.cross(src[opposite], axis)
        w[opposite] = 0.0
    q = np.concatenate([w[..., None], cr], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row-wise cross product of (N, 3) arrays (cheaper than np.cross for small N)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _skew(v: NDArray[np.float64]) -> NDArray[np.float64]:
    k = np.zeros(v.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2] = -v[..., 2], v[..., 1]
    k[..., 1, 0], k[..., 1, 2] = v[..., 2], -v[..., 0]
    k[..., 2, 0], k[..., 2, 1] = -v[..., 1], v[..., 0]
    return k


def attitude_error_vector(r_e: NDArray[np.float64]) -> NDArray[np.float64]:
    """``2 Im(q)`` of the canonical (w >= 0) quaternion of rotations R_e (N, 3, 3): ``2 sin(angle/2) axis``.

    Uses ``R - R^T = 4 q_w [q_v]^x``; near a half turn (q_w < 1e-3) falls back to Shepperd's method.
    """
    tr = r_e[:, 0, 0] + r_e[:, 1, 1] + r_e[:, 2, 2]
    qw = 0.5 * np.sqrt(np.maximum(1.0 + tr, 0.0))
    vee = np.stack([r_e[:, 2, 1] - r_e[:, 1, 2], r_e[:, 0, 2] - r_e[:, 2, 0], r_e[:, 1, 0] - r_e[:, 0, 1]], axis=1)
    small = qw < 1e-3
    out = vee / (2.0 * np.where(small, 1.0, qw))[:, None]
    if np.any(small):
        out[small] = 2.0 * rot_to_quat(r_e[small])[:, 1:]
    return out


class AttitudeControl:
    """PX4 AttitudeControl for N vehicles: attitude setpoint -> body rate setpoint (N, 3) [rad/s].

    Computed with rotation matrices, which is algebraically the same as PX4's quaternion law: the
    reduced rotation ``q(e_z -> e_z,d)`` is Rodrigues' ``I + [c]^x + [c]^x^2 / (1 + d)`` (c = e_z x e_z,d,
    d = e_z . e_z,d); ``qd_dyaw`` is the rotation about z by ``psi`` with ``|psi| <= pi`` (canonical
    quaternion), and PX4's ``(cos(w acos(qw)), 0, 0, sin(w asin(qz)))`` is the rotation by ``w psi``.
    """

    def __init__(self, params: PX4Params | None = None) -> None:
        p = params if params is not None else PX4Params.s500()
        self.yaw_weight = min(max(p["MC_YAW_WEIGHT"], 0.0), 1.0)
        gain = np.array([p["MC_ROLL_P"], p["MC_PITCH_P"], p["MC_YAW_P"]])
        if self.yaw_weight > 1e-4:
            gain[2] /= self.yaw_weight
        self.gain = gain
        self.rate_limit = np.radians([p["MC_ROLLRATE_MAX"], p["MC_PITCHRATE_MAX"], p["MC_YAWRATE_MAX"]])

    def update(self, attitude: ArrayLike, attitude_sp: ArrayLike,
               yawspeed_sp: ArrayLike | None = None) -> NDArray[np.float64]:
        """Rate setpoint (N, 3) FRD [rad/s] from R (N, 3, 3), R_sp (N, 3, 3) and yaw-rate setpoint (N,) [rad/s]."""
        r = np.asarray(attitude, dtype=float)
        if r.ndim == 2:
            r = r[None]
        r_sp = np.asarray(attitude_sp, dtype=float)
        if r_sp.shape != r.shape:
            r_sp = np.broadcast_to(r_sp, r.shape)
        e_z = r[:, :, 2]
        e_z_d = r_sp[:, :, 2]
        c = _cross(e_z, e_z_d)
        d = np.einsum("ni,ni->n", e_z, e_z_d)
        degenerate = d < -1.0 + 1e-9  # thrust axes opposite: PX4 takes the full attitude setpoint
        k = _skew(c)
        r_red = np.eye(3) + k + (k @ k) / np.where(degenerate, 1.0, 1.0 + d)[:, None, None]
        qd_red = np.where(degenerate[:, None, None], r_sp, r_red @ r)
        m = np.swapaxes(qd_red, 1, 2) @ r_sp  # rotation about body z by psi
        psi = self.yaw_weight * np.arctan2(m[:, 1, 0], m[:, 0, 0])
        cy, sy = np.cos(psi), np.sin(psi)
        rz = np.zeros((psi.shape[0], 3, 3))
        rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = cy, -sy, sy, cy, 1.0
        r_e = np.swapaxes(r, 1, 2) @ (qd_red @ rz)
        rate_sp = attitude_error_vector(r_e) * self.gain
        if yawspeed_sp is not None:
            ys = np.broadcast_to(np.asarray(yawspeed_sp, dtype=float), (r.shape[0],))
            rate_sp = rate_sp + r[:, 2, :] * ys[:, None]  # R^T e3: world z in body axes
        return np.clip(rate_sp, -self.rate_limit, self.rate_limit)


def principal_angle(attitude: ArrayLike, attitude_sp: ArrayLike) -> NDArray[np.float64]:
    """Attitude error principal angle Phi = arccos((tr(R_e) - 1)/2), R_e = R_d^T R (Wang et al. 2024, eq. 88)."""
    r = np.asarray(attitude, dtype=float)
    rd = np.asarray(attitude_sp, dtype=float)
    tr = np.einsum("...ji,...ji->...", rd, r)
    return np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))

