"""PX4's multicopter position controller (``mc_pos_control`` PositionControl + ControlMath), batch-first.

The law, as PX4 v1.13 implements it (re-derived, world NED, normalized thrust):

1. position P:  ``v_sp = v_ff + K_p (p_sp - p)``; horizontal magnitude limited by ``MPC_XY_VEL_MAX``
   with priority for the position part (``constrain_xy``), vertical to ``[-MPC_Z_VEL_MAX_UP, MPC_Z_VEL_MAX_DN]``.
2. velocity PID: ``a_sp = a_ff + K_vp (v_sp - v) + i - K_vd v_dot`` (D on the low-passed derivative of the
   measured velocity, not of the error).
3. acceleration -> thrust: ``body_z = normalize(-a_x, -a_y, g)`` tilt-limited to ``MPC_TILTMAX_AIR``;
   collective ``c = (a_z Th/g - Th) / body_z_z`` capped at ``-MPC_THR_MIN``; ``thr = body_z c``.
4. thrust limits with vertical priority keeping ``MPC_THR_XY_MARG`` of horizontal thrust; ``|thr| <= MPC_THR_MAX``.
5. anti-windup: vertical integrator frozen when the thrust is saturated in the error's direction;
   horizontal tracking anti-windup (Rundqwist 1990) with gain ``2 / K_vp``; ``|i_z| <= g``.
6. hover thrust: ``updateHoverThrust`` shifts the z integrator so the thrust stays continuous.

Version (``px4_version``).  The paper flew PX4 v1.13.2 (seed-000 Sec. 7.2), so ``"1.13"`` is the default:
its ``|i_z| <= g`` clamp is applied *after* the integration step and the hover thrust is stored in
``[0.1, 0.9]`` while ``updateHoverThrust`` computes the integrator shift from the unclamped new value
(``PositionControl.cpp/.hpp`` of the release/1.13 branch, as quoted in PX4 PR #21372).  PX4 v1.14 (after its
issue #20275, PR #21380) clamps ``i_z`` at the *start* of the velocity step, i.e. after a hover-thrust shift,
and constrains the hover thrust to ``[0.05, 0.9]`` before computing the shift: ``"1.14"``.  The two differ
only while the integrator sits at ``+-g`` or the hover thrust leaves ``[0.1, 0.9]``; neither happens in the
FAWT study (|i_z| stays below 2 m/s^2, the estimate within ``MPC_THR_HOVER +- HTE_THR_RANGE``), which a test checks.
6. thrust vector + yaw -> attitude setpoint (``bodyz_to_attitude``).

The observer feedforward of Wang et al. (2024) Sec. 7.2 (F = F0 - phi_hat) is applied to this law's output
thrust vector by the agent (:func:`apply_force_feedforward`), so the baseline law, its anti-windup and
the hover-thrust estimator see exactly PX4's own F0.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.rows import check_dt, masked, per_row
from fawtgym.envs.vehicles import GRAVITY

from .px4_attitude_control import _cross
from .px4_params import PX4Params

_EPS = 1.1920929e-07  # FLT_EPSILON, as PX4 uses single precision
#: PX4 version -> (hover-thrust bounds, vertical integrator clamped before the velocity step)
PX4_VERSIONS: dict[str, tuple[tuple[float, float], bool]] = {"1.13": ((0.1, 0.9), False), "1.14": ((0.05, 0.9), True)}


def _norm(v: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def limit_tilt(body_unit: ArrayLike, world_unit: ArrayLike, max_angle: float) -> NDArray[np.float64]:
    """Rotate unit vectors ``body_unit`` (N, 3) towards ``world_unit`` so the angle between them is <= max_angle.

    PX4 ControlMath::limitTilt: keep the direction of the rejection, clamp the angle.
    """
    b = np.asarray(body_unit, dtype=float)
    w = np.broadcast_to(np.asarray(world_unit, dtype=float), b.shape)
    dot = np.clip(np.einsum("...i,...i->...", b, w), -1.0, 1.0)
    angle = np.minimum(np.arccos(dot), max_angle)
    rej = b - dot[..., None] * w
    small = np.einsum("...i,...i->...", rej, rej) < _EPS
    rej = np.where(small[..., None], np.array([1.0, 0.0, 0.0]), rej)
    rej = rej / _norm(rej)[..., None]
    return np.cos(angle)[..., None] * w + np.sin(angle)[..., None] * rej


def constrain_xy(v0: ArrayLike, v1: ArrayLike, max_norm: float) -> NDArray[np.float64]:
    """PX4 ControlMath::constrainXY: limit ``|v0 + v1| <= max`` giving priority to ``v0`` (both (N, 2))."""
    v0 = np.asarray(v0, dtype=float)
    v1 = np.broadcast_to(np.asarray(v1, dtype=float), v0.shape)
    total = v0 + v1
    n_total, n0, n1 = _norm(total), _norm(v0), _norm(v1)
    with np.errstate(invalid="ignore", divide="ignore"):
        u0 = v0 / np.where(n0 > 0, n0, 1.0)[..., None]
        u1 = v1 / np.where(n1 > 0, n1, 1.0)[..., None]
        m = np.einsum("...i,...i->...", u1, v0)
        c = n0**2 - max_norm**2
        s = -m + np.sqrt(np.maximum(m * m - c, 0.0))
    out = v0 + u1 * s[..., None]
    out = np.where((n0 < 0.001)[..., None], u1 * max_norm, out)
    out = np.where((_norm(v1 - v0) < 0.001)[..., None], u0 * max_norm, out)
    out = np.where((n0 >= max_norm)[..., None], u0 * max_norm, out)
    return np.where((n_total <= max_norm)[..., None], total, out)


def bodyz_to_attitude(body_z: ArrayLike, yaw: ArrayLike) -> NDArray[np.float64]:
    """Desired R (N, 3, 3) whose third column is ``body_z`` (N, 3) with heading ``yaw`` (N,) [rad].

    PX4 ControlMath::bodyzToAttitude: ``x = y_C x z`` with ``y_C = (-sin yaw, cos yaw, 0)``.
    """
    z = np.array(body_z, dtype=float)
    yaw = np.broadcast_to(np.asarray(yaw, dtype=float), z.shape[:-1])
    zero = np.einsum("...i,...i->...", z, z) < _EPS
    z[zero] = np.array([0.0, 0.0, 1.0])
    z = z / _norm(z)[..., None]
    y_c = np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], axis=-1)
    x = _cross(y_c, z)
    x = np.where((z[..., 2] < 0.0)[..., None], -x, x)
    x = np.where((np.abs(z[..., 2]) < 1e-6)[..., None], np.array([0.0, 0.0, 1.0]), x)
    x = x / _norm(x)[..., None]
    y = _cross(z, x)
    return np.stack([x, y, z], axis=-1)


def thrust_to_attitude(thrust_sp: ArrayLike, yaw: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Thrust vector setpoint (N, 3) NED normalized -> (R_sp (N, 3, 3), collective thrust (N,) >= 0)."""
    thr = np.asarray(thrust_sp, dtype=float)
    return bodyz_to_attitude(-thr, yaw), _norm(thr)


class PositionControl:
    """PX4 PositionControl for N vehicles; holds gains, limits and the velocity integrator.

    ``update`` returns the normalized thrust vector setpoint (N, 3) in NED (``|thr|`` = collective
    thrust as a fraction of the maximum, pointing along -body_z).
    """

    def __init__(self, params: PX4Params | None = None, hover_thrust: float | None = None,
                 px4_version: str = "1.13") -> None:
        p = params if params is not None else PX4Params.s500()
        if px4_version not in PX4_VERSIONS:
            raise ValueError(f"px4_version must be one of {sorted(PX4_VERSIONS)}, got {px4_version!r}")
        self.px4_version = px4_version
        self.hover_thrust_bounds, self.clamp_before = PX4_VERSIONS[px4_version]
        self.gain_pos_p = np.array([p["MPC_XY_P"], p["MPC_XY_P"], p["MPC_Z_P"]])
        self.gain_vel_p = np.array([p["MPC_XY_VEL_P_ACC"], p["MPC_XY_VEL_P_ACC"], p["MPC_Z_VEL_P_ACC"]])
        self.gain_vel_i = np.array([p["MPC_XY_VEL_I_ACC"], p["MPC_XY_VEL_I_ACC"], p["MPC_Z_VEL_I_ACC"]])
        self.gain_vel_d = np.array([p["MPC_XY_VEL_D_ACC"], p["MPC_XY_VEL_D_ACC"], p["MPC_Z_VEL_D_ACC"]])
        self.lim_vel_horizontal = p["MPC_XY_VEL_MAX"]
        self.lim_vel_up = p["MPC_Z_VEL_MAX_UP"]
        self.lim_vel_down = p["MPC_Z_VEL_MAX_DN"]
        self.lim_tilt = math.radians(p["MPC_TILTMAX_AIR"])
        self.lim_thr_min = max(p["MPC_THR_MIN"], 10e-4)
        self.lim_thr_max = p["MPC_THR_MAX"]
        self.lim_thr_xy_margin = p["MPC_THR_XY_MARG"]
        ht = p["MPC_THR_HOVER"] if hover_thrust is None else hover_thrust
        if not (math.isfinite(ht) and 0.0 < ht < 1.0):
            raise ValueError(f"hover_thrust must be in (0, 1) (normalized collective thrust), got {ht!r}")
        self.initial_hover_thrust = float(np.clip(ht, *self.hover_thrust_bounds))
        #: hover thrust per vehicle (N,)
        self.hover_thrust = np.full(1, self.initial_hover_thrust)
        self.vel_int = np.zeros((1, 3))
        # last outputs, for logging and tests
        self.vel_sp = np.zeros((1, 3))
        self.acc_sp = np.zeros((1, 3))
        self.thr_sp = np.zeros((1, 3))

    def reset(self, n: int = 1, rows: NDArray[np.bool_] | None = None) -> None:
        """Zero the integrator and restore the initial hover thrust for ``n`` vehicles (only ``rows`` (n,) if given)."""
        if rows is not None and self.vel_int.shape[0] == n:
            self.vel_int = masked(self.vel_int, 0.0 * self.vel_int, rows)
            self.hover_thrust = masked(self.hover_thrust, np.full(n, self.initial_hover_thrust), rows)
            self.acc_sp = masked(self.acc_sp, 0.0 * self.acc_sp, rows)
            return
        self.vel_int = np.zeros((n, 3))
        self.hover_thrust = np.full(n, self.initial_hover_thrust)
        self.acc_sp = np.zeros((n, 3))

    def update_hover_thrust(self, hover_thrust_new: ArrayLike, rows: NDArray[np.bool_] | None = None) -> None:
        """PositionControl::updateHoverThrust: new hover thrust (N,), integrator shifted so the thrust is continuous.

        From ``T = a Th / g - Th``: ``a' = (a - g) Th / Th' + g``, and ``a' - a`` is added to the z integrator.
        The stored hover thrust is constrained to the version's bounds; v1.13 computes the shift from the
        unconstrained ``Th'``, v1.14 from the constrained one (module docstring).  Only the rows of ``rows`` (N,).
        """
        new = np.broadcast_to(np.asarray(hover_thrust_new, dtype=float), self.hover_thrust.shape)
        ok = np.isfinite(new) & (new > _EPS)
        if rows is not None:
            ok &= rows
        stored = np.clip(new, *self.hover_thrust_bounds)
        divisor = stored if self.clamp_before else new
        a_z = self.acc_sp[:, 2]
        shift = (a_z - GRAVITY) * self.hover_thrust / np.where(ok, divisor, 1.0) + GRAVITY - a_z
        self.vel_int[:, 2] += np.where(ok, shift, 0.0)
        self.hover_thrust = np.where(ok, stored, self.hover_thrust)

    def update(self, position: ArrayLike, velocity: ArrayLike, velocity_dot: ArrayLike, position_sp: ArrayLike,
               dt: float | ArrayLike, velocity_ff: ArrayLike | None = None,
               acceleration_ff: ArrayLike | None = None, rows: NDArray[np.bool_] | None = None
               ) -> NDArray[np.float64]:
        """One position/velocity step; all vectors (N, 3) NED; returns the thrust vector setpoint (N, 3).

        ``dt`` [s] scalar or one per row (N,); ``rows`` (N,): only these rows advance their state (the
        returned setpoint is computed for every row).
        """
        dt = check_dt(dt)
        pos = np.atleast_2d(np.asarray(position, dtype=float))
        vel = np.atleast_2d(np.asarray(velocity, dtype=float))
        vel_dot = np.atleast_2d(np.asarray(velocity_dot, dtype=float))
        n = pos.shape[0]
        if self.vel_int.shape[0] != n:
            self.reset(n)
        pos_sp = np.broadcast_to(np.asarray(position_sp, dtype=float), pos.shape)
        v_ff = np.zeros_like(pos) if velocity_ff is None else np.broadcast_to(velocity_ff, pos.shape)
        a_ff = np.zeros_like(pos) if acceleration_ff is None else np.broadcast_to(acceleration_ff, pos.shape)

        # ---- position P (PositionControl::_positionControl)
        vel_sp_pos = (pos_sp - pos) * self.gain_pos_p
        vel_sp = v_ff + vel_sp_pos
        vel_sp_xy = constrain_xy(vel_sp_pos[:, :2], (vel_sp - vel_sp_pos)[:, :2], self.lim_vel_horizontal)
        vel_sp = np.concatenate([vel_sp_xy, np.clip(vel_sp[:, 2:], -self.lim_vel_up, self.lim_vel_down)], axis=1)

        # ---- velocity PID (PositionControl::_velocityControl); v1.14 clamps |i_z| <= g here, before use
        vel_int_now = self.vel_int
        if self.clamp_before:
            vel_int_now = self.vel_int.copy()
            vel_int_now[:, 2] = np.clip(vel_int_now[:, 2], -GRAVITY, GRAVITY)
        vel_err = vel_sp - vel
        acc_sp = a_ff + vel_err * self.gain_vel_p + vel_int_now - vel_dot * self.gain_vel_d
        thr_sp = self._acceleration_control(acc_sp)

        # vertical anti-windup: freeze when saturated in the error's direction
        freeze_z = ((thr_sp[:, 2] >= -self.lim_thr_min) & (vel_err[:, 2] >= 0.0)) | \
                   ((thr_sp[:, 2] <= -self.lim_thr_max) & (vel_err[:, 2] <= 0.0))
        vel_err[:, 2] = np.where(freeze_z, 0.0, vel_err[:, 2])

        # vertical priority with a horizontal margin
        thr_xy = thr_sp[:, :2]
        thr_xy_norm = _norm(thr_xy)
        thr_max_sq = self.lim_thr_max**2
        allocated_xy = np.minimum(thr_xy_norm, self.lim_thr_xy_margin)
        thr_z_max_sq = thr_max_sq - allocated_xy**2
        thr_z = np.maximum(thr_sp[:, 2], -np.sqrt(np.maximum(thr_z_max_sq, 0.0)))
        thr_max_xy = np.sqrt(np.maximum(thr_max_sq - thr_z**2, 0.0))
        scale = np.where(thr_xy_norm > thr_max_xy, thr_max_xy / np.where(thr_xy_norm > 0, thr_xy_norm, 1.0), 1.0)
        thr_sp = np.concatenate([thr_xy * scale[:, None], thr_z[:, None]], axis=1)

        # horizontal tracking anti-windup (Rundqwist 1990), gain 2 / K_vp
        acc_xy_produced = thr_sp[:, :2] * (GRAVITY / self.hover_thrust)[:, None]
        arw_gain = 2.0 / self.gain_vel_p[0]
        acc_xy = acc_sp[:, :2]
        acc_limited_xy = np.where((_norm(acc_xy) ** 2 > _norm(acc_xy_produced) ** 2)[:, None], acc_xy_produced, acc_xy)
        vel_err[:, :2] = vel_err[:, :2] - arw_gain * (acc_xy - acc_limited_xy)

        vel_err = np.where(np.isfinite(vel_err), vel_err, 0.0)
        vel_int = vel_int_now + vel_err * self.gain_vel_i * per_row(dt, 2)
        if not self.clamp_before:  # v1.13.2: |i_z| <= g after integrating
            vel_int[:, 2] = np.clip(vel_int[:, 2], -GRAVITY, GRAVITY)

        self.vel_int = masked(self.vel_int, vel_int, rows)
        self.vel_sp = masked(self.vel_sp, vel_sp, rows) if self.vel_sp.shape == vel_sp.shape else vel_sp
        self.acc_sp = masked(self.acc_sp, acc_sp, rows)
        self.thr_sp = masked(self.thr_sp, thr_sp, rows) if self.thr_sp.shape == thr_sp.shape else thr_sp
        return thr_sp

    def _acceleration_control(self, acc_sp: NDArray[np.float64]) -> NDArray[np.float64]:
        """PositionControl::_accelerationControl: acceleration (N, 3) -> thrust vector (N, 3)."""
        body_z = np.stack([-acc_sp[:, 0], -acc_sp[:, 1], np.full(acc_sp.shape[0], GRAVITY)], axis=1)
        body_z = body_z / _norm(body_z)[:, None]
        body_z = limit_tilt(body_z, np.array([0.0, 0.0, 1.0]), self.lim_tilt)
        collective = acc_sp[:, 2] * (self.hover_thrust / GRAVITY) - self.hover_thrust
        collective = collective / body_z[:, 2]
        collective = np.minimum(collective, -self.lim_thr_min)
        return body_z * collective[:, None]


def apply_force_feedforward(thrust_sp: ArrayLike, force_hat: ArrayLike, thrust_scale: float, max_tilt: float,
                            thr_min: float, thr_max: float) -> NDArray[np.float64]:
    """F = F0 - phi_hat (Wang et al. (2024) Sec. 7.2) on PX4's normalized thrust vector, then PX4's limits again.

    ``thrust_sp`` (N, 3) normalized NED thrust vector F0 / thrust_scale, ``force_hat`` (N, 3) the estimated
    disturbance force [N] world NED, ``thrust_scale`` [N per unit] (``4 T_max``).  The result is tilt-limited
    to ``max_tilt`` [rad] and its magnitude kept in ``[thr_min, thr_max]``.
    """
    thr = np.asarray(thrust_sp, dtype=float) - np.asarray(force_hat, dtype=float) / thrust_scale
    n = _norm(thr)
    body_z = -thr / np.where(n > 0, n, 1.0)[:, None]  # thrust acts along -body_z
    body_z = np.where((n > 0)[:, None], body_z, np.array([0.0, 0.0, 1.0]))
    body_z = limit_tilt(body_z, np.array([0.0, 0.0, 1.0]), max_tilt)
    mag = np.clip(n, thr_min, thr_max)
    return -body_z * mag[:, None]
