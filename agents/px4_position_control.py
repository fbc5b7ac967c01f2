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

Each step is written once, as a row function compiled by numba (``*_row``: one vehicle, scalars and
row views, no allocation) called per vehicle by the PX4 cascade kernel (:mod:`fawtgym.agents.px4_cascade`)
and, through batch kernels, by :class:`PositionControl` and the functions below.  The controller state of
a vehicle is one row of :attr:`PositionControl.state` (layout ``VEL_INT`` ... ``HOVER``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.rows import check_dt

from .px4_params import PX4Params
from .shared_params import InPlaceArray

_EPS = 1.1920929e-07  # FLT_EPSILON, as PX4 uses single precision
#: PX4 version -> (hover-thrust bounds, vertical integrator clamped before the velocity step)
PX4_VERSIONS: dict[str, tuple[tuple[float, float], bool]] = {"1.13": ((0.1, 0.9), False), "1.14": ((0.05, 0.9), True)}

#: parameter vector layout (:meth:`PositionControl.parameters`)
KP, KV, KI, KD = 0, 3, 6, 9  # (3,) each: position P, velocity P, I, D gains per axis
VEL_XY_MAX, VEL_UP_MAX, VEL_DN_MAX, TILT_MAX, THR_MIN, THR_MAX, THR_XY_MARGIN = 12, 13, 14, 15, 16, 17, 18
HOVER_MIN, HOVER_MAX, CLAMP_BEFORE = 19, 20, 21
N_PARAMS = 22
#: state row layout (:attr:`PositionControl.state`): integrator, last setpoints, hover thrust
VEL_INT, ACC_SP, VEL_SP, THR_SP, HOVER = 0, 3, 6, 9, 12
N_STATE = 13
_E3 = np.array([0.0, 0.0, 1.0])  # world down: the tilt limit's reference axis


# ---- row laws (one vehicle) --------------------------------------------------------------------------
@njit(cache=True, inline="always")
def limit_tilt_row(b: np.ndarray, w: np.ndarray, max_angle: float, cos_max: float, out: np.ndarray) -> None:
    """PX4 ControlMath::limitTilt: rotate the unit vector ``b`` towards ``w`` so their angle is <= max_angle.

    Keeps the direction of the rejection ``b - (b.w) w`` (x if it vanishes) and clamps the angle.  Within the
    limit (``b.w >= cos(max_angle)``) PX4's formula ``cos(acos(b.w)) w + sin(acos(b.w)) r / |r|`` is ``b`` itself
    (``|r| = sin(angle)`` for unit vectors), which is returned as it is: the same result without its four library
    calls and their rounding.  ``cos_max`` is ``cos(max_angle)`` (taken once by the caller for all rows); ``out``
    may alias ``b``.
    """
    dot = min(max(b[0] * w[0] + b[1] * w[1] + b[2] * w[2], -1.0), 1.0)
    if dot >= cos_max:
        out[0], out[1], out[2] = b[0], b[1], b[2]
        return
    angle = min(math.acos(dot), max_angle)
    rx, ry, rz = b[0] - dot * w[0], b[1] - dot * w[1], b[2] - dot * w[2]
    if rx * rx + ry * ry + rz * rz < _EPS:
        rx, ry, rz = 1.0, 0.0, 0.0
    rn = math.sqrt(rx * rx + ry * ry + rz * rz)
    c, s = math.cos(angle), math.sin(angle)
    out[0] = c * w[0] + s * rx / rn
    out[1] = c * w[1] + s * ry / rn
    out[2] = c * w[2] + s * rz / rn


@njit(cache=True, inline="always")
def constrain_xy_row(v0x: float, v0y: float, v1x: float, v1y: float, max_norm: float) -> tuple[float, float]:
    """PX4 ControlMath::constrainXY: ``v0 + v1`` with ``|.| <= max_norm``, giving priority to ``v0`` (2-vectors)."""
    tx, ty = v0x + v1x, v0y + v1y
    n0 = math.sqrt(v0x * v0x + v0y * v0y)
    if math.sqrt(tx * tx + ty * ty) <= max_norm:
        return tx, ty
    d0 = n0 if n0 > 0.0 else 1.0
    if n0 >= max_norm or math.sqrt((v1x - v0x) ** 2 + (v1y - v0y) ** 2) < 0.001:
        return v0x / d0 * max_norm, v0y / d0 * max_norm
    n1 = math.sqrt(v1x * v1x + v1y * v1y)
    d1 = n1 if n1 > 0.0 else 1.0
    u1x, u1y = v1x / d1, v1y / d1
    if n0 < 0.001:
        return u1x * max_norm, u1y * max_norm
    # the s >= 0 with |v0 + s u1| = max_norm
    m = u1x * v0x + u1y * v0y
    c = n0 * n0 - max_norm * max_norm
    s = -m + math.sqrt(max(m * m - c, 0.0))
    return v0x + u1x * s, v0y + u1y * s


@njit(cache=True, inline="always")
def bodyz_to_attitude_row(zx: float, zy: float, zz: float, sin_yaw: float, cos_yaw: float, r: np.ndarray) -> None:
    """PX4 ControlMath::bodyzToAttitude: R (3, 3) with third column ``z`` (normalized) and heading yaw, given as
    ``sin_yaw``, ``cos_yaw`` (the caller takes them once for every row that shares the heading).

    ``x = y_C x z`` with ``y_C = (-sin yaw, cos yaw, 0)`` (negated when z points up, (0, 0, 1) when z is
    horizontal), ``y = z x x``.
    """
    if zx * zx + zy * zy + zz * zz < _EPS:
        zx, zy, zz = 0.0, 0.0, 1.0
    zn = math.sqrt(zx * zx + zy * zy + zz * zz)
    zx, zy, zz = zx / zn, zy / zn, zz / zn
    ycx, ycy = -sin_yaw, cos_yaw  # y_C, z component 0
    xx, xy, xz = ycy * zz, -ycx * zz, ycx * zy - ycy * zx
    if zz < 0.0:
        xx, xy, xz = -xx, -xy, -xz
    if abs(zz) < 1e-6:
        xx, xy, xz = 0.0, 0.0, 1.0
    xn = math.sqrt(xx * xx + xy * xy + xz * xz)
    xx, xy, xz = xx / xn, xy / xn, xz / xn
    r[0, 0], r[1, 0], r[2, 0] = xx, xy, xz
    r[0, 1], r[1, 1], r[2, 1] = zy * xz - zz * xy, zz * xx - zx * xz, zx * xy - zy * xx
    r[0, 2], r[1, 2], r[2, 2] = zx, zy, zz


@njit(cache=True, inline="always")
def acceleration_control_row(ax: float, ay: float, az: float, hover: float, prm: np.ndarray, cos_tilt: float,
                             thr: np.ndarray) -> None:
    """PositionControl::_accelerationControl: acceleration setpoint -> normalized thrust vector ``thr`` (3,).

    ``body_z = normalize(-a_x, -a_y, g)`` tilt-limited (``cos_tilt = cos(prm[TILT_MAX])``); collective
    ``(a_z Th / g - Th) / body_z_z`` capped at ``-MPC_THR_MIN``; ``thr = body_z collective``.
    """
    bn = math.sqrt(ax * ax + ay * ay + GRAVITY * GRAVITY)
    thr[0], thr[1], thr[2] = -ax / bn, -ay / bn, GRAVITY / bn
    limit_tilt_row(thr, _E3, prm[TILT_MAX], cos_tilt, thr)
    collective = (az * (hover / GRAVITY) - hover) / thr[2]
    collective = min(collective, -prm[THR_MIN])
    thr[0] *= collective
    thr[1] *= collective
    thr[2] *= collective


@njit(cache=True, inline="always")
def position_control_row(p: np.ndarray, v: np.ndarray, v_dot: np.ndarray, p_sp: np.ndarray, v_ff: np.ndarray,
                         a_ff: np.ndarray, dt: float, prm: np.ndarray, cos_tilt: float, s: np.ndarray,
                         advance: bool, thr: np.ndarray) -> None:
    """One position/velocity step of one vehicle (steps 1-5 of the module docstring) into ``thr`` (3,).

    ``s`` is the vehicle's state row (``VEL_INT`` ... ``HOVER``); it advances only if ``advance``; ``cos_tilt`` is
    ``cos(prm[TILT_MAX])``, taken once by the caller for all rows.
    """
    # 1. position P with the horizontal limit (priority to the position part) and the vertical limits
    vpx, vpy, vpz = (p_sp[0] - p[0]) * prm[KP], (p_sp[1] - p[1]) * prm[KP + 1], (p_sp[2] - p[2]) * prm[KP + 2]
    vsx, vsy, vsz = v_ff[0] + vpx, v_ff[1] + vpy, v_ff[2] + vpz
    vsx, vsy = constrain_xy_row(vpx, vpy, vsx - vpx, vsy - vpy, prm[VEL_XY_MAX])
    vsz = min(max(vsz, -prm[VEL_UP_MAX]), prm[VEL_DN_MAX])
    # 2. velocity PID; v1.14 clamps |i_z| <= g before using it
    ix, iy, iz = s[VEL_INT], s[VEL_INT + 1], s[VEL_INT + 2]
    if prm[CLAMP_BEFORE] != 0.0:
        iz = min(max(iz, -GRAVITY), GRAVITY)
    ex, ey, ez = vsx - v[0], vsy - v[1], vsz - v[2]
    accx = a_ff[0] + ex * prm[KV] + ix - v_dot[0] * prm[KD]
    accy = a_ff[1] + ey * prm[KV + 1] + iy - v_dot[1] * prm[KD + 1]
    accz = a_ff[2] + ez * prm[KV + 2] + iz - v_dot[2] * prm[KD + 2]
    hover = s[HOVER]
    # 3. acceleration -> thrust
    acceleration_control_row(accx, accy, accz, hover, prm, cos_tilt, thr)
    # 5a. vertical anti-windup: freeze when saturated in the error's direction
    if (thr[2] >= -prm[THR_MIN] and ez >= 0.0) or (thr[2] <= -prm[THR_MAX] and ez <= 0.0):
        ez = 0.0
    # 4. vertical priority, keeping MPC_THR_XY_MARG of horizontal thrust
    thr_xy = math.sqrt(thr[0] * thr[0] + thr[1] * thr[1])
    thr_max_sq = prm[THR_MAX] * prm[THR_MAX]
    allocated_xy = min(thr_xy, prm[THR_XY_MARGIN])
    thr[2] = max(thr[2], -math.sqrt(max(thr_max_sq - allocated_xy * allocated_xy, 0.0)))
    thr_max_xy = math.sqrt(max(thr_max_sq - thr[2] * thr[2], 0.0))
    if thr_xy > thr_max_xy:
        scale = thr_max_xy / thr_xy
        thr[0] *= scale
        thr[1] *= scale
    # 5b. horizontal tracking anti-windup (Rundqwist 1990), gain 2 / K_vp
    prod_x, prod_y = thr[0] * (GRAVITY / hover), thr[1] * (GRAVITY / hover)
    lim_x, lim_y = accx, accy
    if accx * accx + accy * accy > prod_x * prod_x + prod_y * prod_y:
        lim_x, lim_y = prod_x, prod_y
    arw_gain = 2.0 / prm[KV]
    ex -= arw_gain * (accx - lim_x)
    ey -= arw_gain * (accy - lim_y)
    if not advance:
        return
    errs = (ex, ey, ez)
    ints = (ix, iy, iz)
    for j in range(3):
        e = errs[j] if math.isfinite(errs[j]) else 0.0
        s[VEL_INT + j] = ints[j] + e * prm[KI + j] * dt
    if prm[CLAMP_BEFORE] == 0.0:  # v1.13.2: |i_z| <= g after integrating
        s[VEL_INT + 2] = min(max(s[VEL_INT + 2], -GRAVITY), GRAVITY)
    s[VEL_SP], s[VEL_SP + 1], s[VEL_SP + 2] = vsx, vsy, vsz
    s[ACC_SP], s[ACC_SP + 1], s[ACC_SP + 2] = accx, accy, accz
    s[THR_SP], s[THR_SP + 1], s[THR_SP + 2] = thr[0], thr[1], thr[2]


@njit(cache=True, inline="always")
def update_hover_thrust_row(hover_new: float, prm: np.ndarray, s: np.ndarray) -> None:
    """PositionControl::updateHoverThrust for one vehicle: new hover thrust, z integrator shifted by ``a' - a``
    with ``a' = (a - g) Th / Th' + g``; v1.13 divides by the unconstrained ``Th'``, v1.14 by the constrained one."""
    if not (math.isfinite(hover_new) and hover_new > _EPS):
        return
    stored = min(max(hover_new, prm[HOVER_MIN]), prm[HOVER_MAX])
    divisor = stored if prm[CLAMP_BEFORE] != 0.0 else hover_new
    a_z = s[ACC_SP + 2]
    s[VEL_INT + 2] += (a_z - GRAVITY) * s[HOVER] / divisor + GRAVITY - a_z
    s[HOVER] = stored


@njit(cache=True, inline="always")
def force_feedforward_row(thr: np.ndarray, force_hat: np.ndarray, thrust_scale: float, max_tilt: float,
                          cos_tilt: float, thr_min: float, thr_max: float, out: np.ndarray) -> None:
    """F = F0 - phi_hat (Wang et al. (2024) Sec. 7.2) on one normalized thrust vector, then PX4's limits again.

    ``out = -body_z |F|`` with ``body_z`` tilt-limited to ``max_tilt`` (``cos_tilt = cos(max_tilt)``) and ``|F|``
    kept in ``[thr_min, thr_max]``; ``out`` may alias ``thr``.
    """
    fx = thr[0] - force_hat[0] / thrust_scale
    fy = thr[1] - force_hat[1] / thrust_scale
    fz = thr[2] - force_hat[2] / thrust_scale
    n = math.sqrt(fx * fx + fy * fy + fz * fz)
    if n > 0.0:  # thrust acts along -body_z
        out[0], out[1], out[2] = -fx / n, -fy / n, -fz / n
    else:
        out[0], out[1], out[2] = 0.0, 0.0, 1.0
    limit_tilt_row(out, _E3, max_tilt, cos_tilt, out)
    mag = min(max(n, thr_min), thr_max)
    out[0], out[1], out[2] = -out[0] * mag, -out[1] * mag, -out[2] * mag



# ---- batch kernels (the row laws over N vehicles) ------------------------------------------------------
@njit(cache=True)
def _position_kernel(p: np.ndarray, v: np.ndarray, v_dot: np.ndarray, p_sp: np.ndarray, v_ff: np.ndarray,
                     a_ff: np.ndarray, dt: np.ndarray, prm: np.ndarray, state: np.ndarray, advance: np.ndarray,
                     thr: np.ndarray) -> None:
    cos_tilt = math.cos(prm[TILT_MAX])
    for i in range(p.shape[0]):
        position_control_row(p[i], v[i], v_dot[i], p_sp[i], v_ff[i], a_ff[i], dt[i], prm, cos_tilt, state[i],
                             advance[i], thr[i])


@njit(cache=True)
def _hover_thrust_kernel(hover_new: np.ndarray, prm: np.ndarray, state: np.ndarray, rows: np.ndarray) -> None:
    for i in range(state.shape[0]):
        if rows[i]:
            update_hover_thrust_row(hover_new[i], prm, state[i])


@njit(cache=True)
def _limit_tilt_kernel(b: np.ndarray, w: np.ndarray, max_angle: float, out: np.ndarray) -> None:
    cos_max = math.cos(max_angle)
    for i in range(b.shape[0]):
        limit_tilt_row(b[i], w[i], max_angle, cos_max, out[i])


@njit(cache=True)
def _constrain_xy_kernel(v0: np.ndarray, v1: np.ndarray, max_norm: float, out: np.ndarray) -> None:
    for i in range(v0.shape[0]):
        out[i, 0], out[i, 1] = constrain_xy_row(v0[i, 0], v0[i, 1], v1[i, 0], v1[i, 1], max_norm)


@njit(cache=True)
def _bodyz_kernel(z: np.ndarray, yaw: np.ndarray, r: np.ndarray) -> None:
    for i in range(z.shape[0]):
        bodyz_to_attitude_row(z[i, 0], z[i, 1], z[i, 2], math.sin(yaw[i]), math.cos(yaw[i]), r[i])


@njit(cache=True)
def _feedforward_kernel(thr: np.ndarray, force_hat: np.ndarray, thrust_scale: float, max_tilt: float,
                        thr_min: float, thr_max: float, out: np.ndarray) -> None:
    cos_tilt = math.cos(max_tilt)
    for i in range(thr.shape[0]):
        force_feedforward_row(thr[i], force_hat[i], thrust_scale, max_tilt, cos_tilt, thr_min, thr_max, out[i])


def _rows3(x: ArrayLike, n: int | None = None) -> NDArray[np.float64]:
    """``x`` as a C-contiguous (N, 3) float array (a (3,) vector is broadcast to ``n`` rows)."""
    a = np.asarray(x, dtype=float)
    if a.ndim == 1:
        a = a[None]
    if n is not None and a.shape[0] != n:
        a = np.broadcast_to(a, (n, 3))
    return np.ascontiguousarray(a)


def limit_tilt(body_unit: ArrayLike, world_unit: ArrayLike, max_angle: float) -> NDArray[np.float64]:
    """Rotate unit vectors ``body_unit`` (N, 3) towards ``world_unit`` so the angle between them is <= max_angle
    (PX4 ControlMath::limitTilt, :func:`limit_tilt_row`)."""
    b = _rows3(body_unit)
    out = np.empty_like(b)
    _limit_tilt_kernel(b, _rows3(world_unit, b.shape[0]), float(max_angle), out)
    return out


def constrain_xy(v0: ArrayLike, v1: ArrayLike, max_norm: float) -> NDArray[np.float64]:
    """PX4 ControlMath::constrainXY: limit ``|v0 + v1| <= max`` giving priority to ``v0`` (both (N, 2))."""
    a = np.ascontiguousarray(np.atleast_2d(np.asarray(v0, dtype=float)))
    b = np.ascontiguousarray(np.broadcast_to(np.asarray(v1, dtype=float), a.shape))
    out = np.empty_like(a)
    _constrain_xy_kernel(a, b, float(max_norm), out)
    return out


def bodyz_to_attitude(body_z: ArrayLike, yaw: ArrayLike) -> NDArray[np.float64]:
    """Desired R (N, 3, 3) whose third column is ``body_z`` (N, 3) with heading ``yaw`` (N,) [rad].

    PX4 ControlMath::bodyzToAttitude (:func:`bodyz_to_attitude_row`).
    """
    z = _rows3(body_z)
    yaw_rows = np.ascontiguousarray(np.broadcast_to(np.asarray(yaw, dtype=float), (z.shape[0],)))
    r = np.empty((z.shape[0], 3, 3))
    _bodyz_kernel(z, yaw_rows, r)
    return r


def thrust_to_attitude(thrust_sp: ArrayLike, yaw: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Thrust vector setpoint (N, 3) NED normalized -> (R_sp (N, 3, 3), collective thrust (N,) >= 0)."""
    thr = _rows3(thrust_sp)
    return bodyz_to_attitude(-thr, yaw), np.sqrt(np.einsum("ni,ni->n", thr, thr))


def apply_force_feedforward(thrust_sp: ArrayLike, force_hat: ArrayLike, thrust_scale: float, max_tilt: float,
                            thr_min: float, thr_max: float) -> NDArray[np.float64]:
    """F = F0 - phi_hat (Wang et al. (2024) Sec. 7.2) on PX4's normalized thrust vector, then PX4's limits again.

    ``thrust_sp`` (N, 3) normalized NED thrust vector F0 / thrust_scale, ``force_hat`` (N, 3) the estimated
    disturbance force [N] world NED, ``thrust_scale`` [N per unit] (``4 T_max``).  The result is tilt-limited
    to ``max_tilt`` [rad] and its magnitude kept in ``[thr_min, thr_max]`` (:func:`force_feedforward_row`).
    """
    thr = _rows3(thrust_sp)
    out = np.empty_like(thr)
    _feedforward_kernel(thr, _rows3(force_hat, thr.shape[0]), float(thrust_scale), float(max_tilt), float(thr_min),
                        float(thr_max), out)
    return out


class PositionControl:
    """PX4 PositionControl for N vehicles; holds gains, limits and the velocity integrator.

    ``update`` returns the normalized thrust vector setpoint (N, 3) in NED (``|thr|`` = collective
    thrust as a fraction of the maximum, pointing along -body_z).  The state of the N vehicles is
    :attr:`state` (N, ``N_STATE``); ``vel_int``, ``acc_sp``, ``vel_sp``, ``thr_sp`` (N, 3) and
    ``hover_thrust`` (N,) are views of it.
    """
    params = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place

    def __init__(self, params: PX4Params | None = None, hover_thrust: float | None = None,
                 px4_version: str = "1.13") -> None:
        p = params if params is not None else PX4Params.s500()
        if px4_version not in PX4_VERSIONS:
            raise ValueError(f"px4_version must be one of {sorted(PX4_VERSIONS)}, got {shown(px4_version)}")
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
            raise ValueError(f"hover_thrust must be in (0, 1) (normalized collective thrust), got {shown(ht)}")
        self.initial_hover_thrust = float(np.clip(ht, *self.hover_thrust_bounds))
        self.params = self.parameters()
        self.state: NDArray[np.float64] = np.zeros((0, N_STATE))
        self.reset(1)

    def parameters(self) -> NDArray[np.float64]:
        """The parameter vector of the row law (layout ``KP`` ... ``CLAMP_BEFORE``)."""
        prm = np.empty(N_PARAMS)
        prm[KP:KP + 3], prm[KV:KV + 3] = self.gain_pos_p, self.gain_vel_p
        prm[KI:KI + 3], prm[KD:KD + 3] = self.gain_vel_i, self.gain_vel_d
        prm[VEL_XY_MAX], prm[VEL_UP_MAX], prm[VEL_DN_MAX] = self.lim_vel_horizontal, self.lim_vel_up, self.lim_vel_down
        prm[TILT_MAX], prm[THR_MIN], prm[THR_MAX] = self.lim_tilt, self.lim_thr_min, self.lim_thr_max
        prm[THR_XY_MARGIN] = self.lim_thr_xy_margin
        prm[HOVER_MIN], prm[HOVER_MAX] = self.hover_thrust_bounds
        prm[CLAMP_BEFORE] = float(self.clamp_before)
        return prm

    def fresh_state(self) -> NDArray[np.float64]:
        """The state row of a fresh vehicle: zero integrator and setpoints, the initial hover thrust."""
        row = np.zeros(N_STATE)
        row[HOVER] = self.initial_hover_thrust
        return row

    # views of the state, by name
    vel_int = property(lambda self: self.state[:, VEL_INT:VEL_INT + 3], doc="velocity integrator (N, 3) [m/s^2]")
    acc_sp = property(lambda self: self.state[:, ACC_SP:ACC_SP + 3], doc="last acceleration setpoint (N, 3)")
    vel_sp = property(lambda self: self.state[:, VEL_SP:VEL_SP + 3], doc="last velocity setpoint (N, 3)")
    thr_sp = property(lambda self: self.state[:, THR_SP:THR_SP + 3], doc="last thrust vector setpoint (N, 3)")
    hover_thrust = property(lambda self: self.state[:, HOVER], doc="hover thrust per vehicle (N,)")

    def reset(self, n: int = 1, rows: NDArray[np.bool_] | None = None) -> None:
        """Zero the integrator and restore the initial hover thrust for ``n`` vehicles (only ``rows`` (n,) if given)."""
        if rows is not None and self.state.shape[0] == n:
            self.state[rows] = self.fresh_state()
            return
        self.state = np.tile(self.fresh_state(), (n, 1))

    def update_hover_thrust(self, hover_thrust_new: ArrayLike, rows: NDArray[np.bool_] | None = None) -> None:
        """PositionControl::updateHoverThrust: new hover thrust (N,), integrator shifted so the thrust is continuous.

        From ``T = a Th / g - Th``: ``a' = (a - g) Th / Th' + g``, and ``a' - a`` is added to the z integrator.
        The stored hover thrust is constrained to the version's bounds; v1.13 computes the shift from the
        unconstrained ``Th'``, v1.14 from the constrained one (module docstring).  Only the rows of ``rows`` (N,).
        """
        n = self.state.shape[0]
        new = np.ascontiguousarray(np.broadcast_to(np.asarray(hover_thrust_new, dtype=float), (n,)))
        apply = np.ones(n, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
        _hover_thrust_kernel(new, self.params, self.state, apply)

    def update(self, position: ArrayLike, velocity: ArrayLike, velocity_dot: ArrayLike, position_sp: ArrayLike,
               dt: float | ArrayLike, velocity_ff: ArrayLike | None = None,
               acceleration_ff: ArrayLike | None = None, rows: NDArray[np.bool_] | None = None
               ) -> NDArray[np.float64]:
        """One position/velocity step; all vectors (N, 3) NED; returns the thrust vector setpoint (N, 3).

        ``dt`` [s] scalar or one per row (N,); ``rows`` (N,): only these rows advance their state (the
        returned setpoint is computed for every row).
        """
        dt = check_dt(dt)
        pos = _rows3(position)
        n = pos.shape[0]
        if self.state.shape[0] != n:
            self.reset(n)
        zeros = np.zeros((n, 3))
        v_ff = zeros if velocity_ff is None else _rows3(velocity_ff, n)
        a_ff = zeros if acceleration_ff is None else _rows3(acceleration_ff, n)
        thr = np.empty((n, 3))
        advance = np.ones(n, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
        _position_kernel(pos, _rows3(velocity, n), _rows3(velocity_dot, n), _rows3(position_sp, n), v_ff, a_ff,
                         np.ascontiguousarray(np.broadcast_to(dt, (n,)), dtype=float), self.params, self.state,
                         advance, thr)
        return thr
