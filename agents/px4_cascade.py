"""One control step of the PX4 cascade for N vehicles, as one compiled kernel over rows.

:class:`fawtgym.agents.px4_agent.PX4Agent` calls :func:`cascade_step` once per ``act``.  Per vehicle
(row) it runs, in PX4's order and with each law's row function from its own module (written once there):

1. gyro filters (``VehicleAngularVelocity``): the gyro through the ``IMU_GYRO_CUTOFF`` Butterworth, the
   backward-difference angular acceleration through the ``IMU_DGYRO_CUTOFF`` one
   (:func:`~fawtgym.agents.px4_filters.butterworth_row`); a row that was just reset starts both from its
   sample (rate = gyro, angular acceleration 0);
2. the three loop clocks: a loop runs when its period has elapsed, with the elapsed time as its dt;
3. position loop: hover-thrust EKF (:func:`~fawtgym.agents.px4_hover_thrust.hover_thrust_row`, applied to
   the position law only once valid), the filtered velocity derivative, the position/velocity law
   (:func:`~fawtgym.agents.px4_position_control.position_control_row`), the observer feedforward
   F = F0 - phi_hat (Wang et al. (2024) Sec. 7.2), and the attitude setpoint (``bodyzToAttitude``);
4. attitude loop (:func:`~fawtgym.agents.px4_attitude_control.attitude_control_row`);
5. rate loop (:func:`~fawtgym.agents.px4_rate_control.rate_control_row`) and tau = tau0 - tau_hat;
6. allocation with desaturation (:func:`~fawtgym.agents.px4_allocation.allocate_row`), the rate loop's
   saturation flags from the unallocated torque, and the motor commands.

State.  Everything the cascade itself keeps is one row of the agent state (layout below); the laws' own
state rows are those of :class:`PositionControl`, :class:`HoverThrustEstimator` and :class:`RateControl`.
A per-row reset writes a fresh row (:func:`fresh_state`): a masked write.

Status.  The kernel returns ``(code, row)``: ``OK``, ``BAD_MEASUREMENT`` (a non-finite position, velocity, gyro
or specific force, or an attitude that is not a rotation: :func:`~fawtgym.core.so3_kernels.first_non_rotation`
within :data:`~fawtgym.core.so3_kernels.ROTATION_TOL`), ``BAD_SETPOINT`` (a position setpoint not finite or beyond
the env's bound), ``BAD_ESTIMATE`` (a non-finite disturbance estimate), all found before any state changes, or
``BAD_ACTION`` (a non-finite motor command); the agent raises (it words a bad measurement with the observers'
check, :func:`fawtgym.agents.base.refuse_measurement`).  :func:`first_bad_input` is the kernel's own check of the
measurement and the setpoint, callable alone: an agent that changes state before the kernel runs (an observer's
update, a pose delay line) calls it first, so a refused ``act`` changes nothing.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.constants import GRAVITY
from fawtgym.core.kernel_types import NO_REFCOUNT
from fawtgym.core.so3_kernels import ROTATION_TOL, first_non_rotation
from fawtgym.envs.options import MAX_SETPOINT

from .px4_allocation import allocate_row, rotor_command_row
from .px4_attitude_control import N_PARAMS as N_ATT_PARAMS
from .px4_attitude_control import attitude_control_row
from .px4_filters import N_BIQUAD, butterworth_reset_row, butterworth_row, filtered_derivative_row
from .px4_hover_thrust import HOVER as HTE_HOVER
from .px4_hover_thrust import N_PARAMS as N_HTE_PARAMS
from .px4_hover_thrust import N_STATE as N_HTE_STATE
from .px4_hover_thrust import VALID, hover_thrust_row
from .px4_position_control import N_PARAMS as N_POS_PARAMS
from .px4_position_control import N_STATE as N_POS_STATE
from .px4_position_control import (
    THR_MAX,
    THR_MIN,
    TILT_MAX,
    bodyz_to_attitude_row,
    force_feedforward_row,
    position_control_row,
    update_hover_thrust_row,
)
from .px4_rate_control import N_PARAMS as N_RATE_PARAMS
from .px4_rate_control import N_STATE as N_RATE_STATE
from .px4_rate_control import SAT_NEG, SAT_POS, rate_control_row

#: kernel status codes
OK, BAD_ESTIMATE, BAD_ACTION, BAD_MEASUREMENT, BAD_SETPOINT = 0, 1, 2, 3, 4
#: |unallocated roll/pitch/yaw|^2 above which the allocation reports saturation to the rate loop
SAT_EPS = 1e-6

#: configuration vector layout (:func:`configuration`)
GYRO_COEF, DGYRO_COEF = 0, N_BIQUAD  # the two Butterworth coefficient vectors
VELD_CUTOFF = 2 * N_BIQUAD  # Hz, MPC_VELD_LP
PERIOD = VELD_CUTOFF + 1  # (3,) loop periods [s]: position, attitude, rate
POS_LOOP, ATT_LOOP, RATE_LOOP = 0, 1, 2
USE_HTE = PERIOD + 3  # 1: the hover-thrust estimator runs (MPC_USE_HTE)
THRUST_SCALE = USE_HTE + 1  # N per unit normalized collective thrust
TORQUE_SCALE = THRUST_SCALE + 1  # (3,) N m per unit normalized torque
N_CONFIG = TORQUE_SCALE + 3

#: constants vector layout (:func:`pack_constants`): the configuration, each law's parameter vector, the
#: allocation's mix (4, 4, row-major), effectiveness (4, 4), scale (4,) and rotor map (4,)
K_CONFIG = 0
K_POS = K_CONFIG + N_CONFIG
K_HTE = K_POS + N_POS_PARAMS
K_ATT = K_HTE + N_HTE_PARAMS
K_RATE = K_ATT + N_ATT_PARAMS
K_MIX_T = K_RATE + N_RATE_PARAMS
K_EFFECTIVENESS = K_MIX_T + 16
K_ALLOC_SCALE = K_EFFECTIVENESS + 16
K_ROTOR_MAP = K_ALLOC_SCALE + 4
N_CONSTANTS = K_ROTOR_MAP + 4

#: agent state row layout (:func:`fresh_state`)
GYRO_Z = 0  # (6,) gyro Butterworth registers
DGYRO_Z = 6  # (6,) angular-acceleration Butterworth registers
GYRO_PREV = 12  # (3,) previous gyro sample
FRESH = 15  # 1: the row was reset; its filters start from its next sample
ELAPSED = 16  # (3,) time since each loop last ran (inf: run at the next step)
VEL_DERIV = 19  # (7,) filtered velocity derivative: previous velocity, low-pass state, first-sample flag
THR0 = 26  # (3,) PX4's own thrust vector setpoint F0 (what the hover-thrust EKF sees)
HAS_THR0 = 29  # 1 once F0 exists
THR_SP = 30  # (3,) thrust vector setpoint after the feedforward
RATE_SP = 33  # (3,) body rate setpoint [rad/s]
TORQUE = 36  # (3,) normalized torque setpoint
ROTOR = 39  # (4,) rotor normalized thrusts sent to the motors
N_STATE = 43

#: work buffer layout of :func:`cascade_step` (one buffer of ``N_WORK`` floats, the caller's): five (3, 3) scratch
#: matrices, then one row of every array the row loop works on
W_MATS = 0
W_ROW = W_MATS + 45
N_WORK = W_ROW + 7 * 3 + 2 * 4 + N_STATE + N_POS_STATE + N_HTE_STATE + N_RATE_STATE + 4 * 3 + 4


def configuration(gyro_coef: NDArray[np.float64], dgyro_coef: NDArray[np.float64], veld_cutoff: float,
                  periods: tuple[float, float, float], use_hte: bool, thrust_scale: float,
                  torque_scale: NDArray[np.float64]) -> NDArray[np.float64]:
    """The configuration vector of :func:`cascade_step` (layout ``GYRO_COEF`` ... ``TORQUE_SCALE``)."""
    cfg = np.zeros(N_CONFIG)
    cfg[GYRO_COEF:GYRO_COEF + N_BIQUAD] = gyro_coef
    cfg[DGYRO_COEF:DGYRO_COEF + N_BIQUAD] = dgyro_coef
    cfg[VELD_CUTOFF] = veld_cutoff
    cfg[PERIOD:PERIOD + 3] = periods
    cfg[USE_HTE] = float(use_hte)
    cfg[THRUST_SCALE] = thrust_scale
    cfg[TORQUE_SCALE:TORQUE_SCALE + 3] = torque_scale
    return cfg


def pack_constants(config: NDArray[np.float64], pos_prm: NDArray[np.float64], hte_prm: NDArray[np.float64],
                   att_prm: NDArray[np.float64], rate_prm: NDArray[np.float64], mix_t: NDArray[np.float64],
                   effectiveness: NDArray[np.float64], alloc_scale: NDArray[np.float64],
                   rotor_map: NDArray[np.float64]) -> tuple[NDArray[np.float64], tuple[NDArray[np.float64], ...]]:
    """The constants vector of :func:`cascade_step` (layout ``K_CONFIG`` ... ``K_ROTOR_MAP``) and its views in the
    order and shapes of the arguments: the caller keeps the views as the laws' parameter arrays, so one copy of the
    parameters exists (a parameter changed in place, e.g. the hover-thrust EKF's variance bump, is what the kernel
    reads).  One argument instead of nine: each argument of a compiled call costs ~0.06 us at N = 1."""
    parts = (config, pos_prm, hte_prm, att_prm, rate_prm, mix_t, effectiveness, alloc_scale, rotor_map)
    sizes = (N_CONFIG, N_POS_PARAMS, N_HTE_PARAMS, N_ATT_PARAMS, N_RATE_PARAMS, 16, 16, 4, 4)
    constants = np.empty(N_CONSTANTS)
    views = []
    start = 0
    for part, size in zip(parts, sizes, strict=True):
        part = np.asarray(part, dtype=float)
        if part.size != size:
            raise ValueError(f"pack_constants: a part of {part.size} values where the layout has {size}")
        view = constants[start:start + size]
        view[:] = part.ravel()
        views.append(view.reshape(part.shape))
        start += size
    return constants, tuple(views)


def fresh_state(hover_thrust: float) -> NDArray[np.float64]:
    """The agent state row of a vehicle starting an episode: filters fresh, every loop due, hover thrust set point."""
    row = np.zeros(N_STATE)
    row[FRESH] = 1.0
    row[ELAPSED:ELAPSED + 3] = math.inf
    row[VEL_DERIV + 6] = 1.0  # the next velocity is a first sample
    row[THR_SP + 2] = -hover_thrust
    row[ROTOR:ROTOR + 4] = hover_thrust
    return row


@njit(cache=True, inline="always")
def _tick(s: np.ndarray, loop: int, period: float, dt: float) -> float:
    """Advance a loop clock by ``dt``; returns the loop's dt if it runs now (elapsed time, the period after a
    reset), else 0."""
    elapsed = s[ELAPSED + loop] + dt
    if elapsed < period - 1e-9:
        s[ELAPSED + loop] = elapsed
        return 0.0
    s[ELAPSED + loop] = 0.0
    return elapsed if math.isfinite(elapsed) else period


@njit(cache=True, nogil=True)
def first_bad_input(pos: np.ndarray, vel: np.ndarray, att: np.ndarray, gyro: np.ndarray, specific_force: np.ndarray,
                    setpoint: np.ndarray) -> tuple[int, int]:
    """``(BAD_MEASUREMENT, row)`` for the first row with a non-finite position, velocity, gyro or specific force or
    an attitude that is not a rotation (row -1: the arrays have different numbers of rows), else
    ``(BAD_SETPOINT, row)`` for the first setpoint row ((1, 3) or (N, 3)) with a coordinate not finite or beyond the
    env's :data:`~fawtgym.envs.options.MAX_SETPOINT`, else ``(OK, -1)``: what :func:`cascade_step` refuses before
    anything changes."""
    n = pos.shape[0]
    if vel.shape[0] != n or att.shape[0] != n or gyro.shape[0] != n or specific_force.shape[0] != n:
        return BAD_MEASUREMENT, -1
    for i in range(n):
        for j in range(3):
            if not (math.isfinite(pos[i, j]) and math.isfinite(vel[i, j]) and math.isfinite(gyro[i, j])
                    and math.isfinite(specific_force[i, j])):
                return BAD_MEASUREMENT, i
    row = first_non_rotation(att, ROTATION_TOL)  # NaN entries fail it too
    if row >= 0:
        return BAD_MEASUREMENT, row
    for i in range(setpoint.shape[0]):
        for j in range(3):
            if not abs(setpoint[i, j]) <= MAX_SETPOINT:  # NaN fails too
                return BAD_SETPOINT, i
    return OK, -1


@njit(cache=True, nogil=True, **NO_REFCOUNT)
def cascade_step(pos: np.ndarray, vel: np.ndarray, att: np.ndarray, gyro: np.ndarray, specific_force: np.ndarray,
                 has_specific_force: bool, setpoint: np.ndarray, yaw: float, force_hat: np.ndarray, use_force: bool,
                 torque_hat: np.ndarray, use_torque: bool, dt: float, constants: np.ndarray, state: np.ndarray,
                 pos_state: np.ndarray, hte_state: np.ndarray, rate_state: np.ndarray, att_sp: np.ndarray,
                 action: np.ndarray, work: np.ndarray) -> tuple[int, int]:
    """One ``act`` of the cascade for every row (module docstring); writes ``action`` (N, 4) motor commands.

    Inputs (N, 3) / (N, 3, 3) are the measurement (pose possibly delayed; checked finite, the attitude a rotation:
    ``BAD_MEASUREMENT``), the position setpoint ((1, 3): the same for every row; checked finite: ``BAD_SETPOINT``)
    and the disturbance estimates
    (zeros without an observer; C-contiguous or strided, e.g. the columns of an observer's estimate buffer; both
    checked finite, fed forward if ``use_force`` / ``use_torque``); the state arrays are updated in place.
    ``work`` (:data:`N_WORK`,) is the caller's scratch: the kernel allocates nothing, so it is compiled without
    numba's reference counting (:data:`~fawtgym.core.kernel_types.NO_REFCOUNT`).
    """
    cfg = constants[K_CONFIG:K_POS]
    pos_prm = constants[K_POS:K_HTE]
    hte_prm = constants[K_HTE:K_ATT]
    att_prm = constants[K_ATT:K_RATE]
    rate_prm = constants[K_RATE:K_MIX_T]
    mix_t = constants[K_MIX_T:K_EFFECTIVENESS].reshape((4, 4))
    effectiveness = constants[K_EFFECTIVENESS:K_ALLOC_SCALE].reshape((4, 4))
    alloc_scale = constants[K_ALLOC_SCALE:K_ROTOR_MAP]
    rotor_map = constants[K_ROTOR_MAP:N_CONSTANTS]
    n = pos.shape[0]
    # a bad measurement or setpoint or a diverging observer stops the step before anything changes
    code, row = first_bad_input(pos, vel, att, gyro, specific_force, setpoint)
    if code != OK:
        return code, row
    for i in range(n):
        for j in range(3):
            if not (math.isfinite(force_hat[i, j]) and math.isfinite(torque_hat[i, j])):
                return BAD_ESTIMATE, i
    gyro_coef = cfg[GYRO_COEF:GYRO_COEF + N_BIQUAD]
    dgyro_coef = cfg[DGYRO_COEF:DGYRO_COEF + N_BIQUAD]
    # One row of every array, in the work buffer: the row loop copies a row in, runs the laws on the views made
    # here and copies the row out (no view is made inside the loop).
    scratch = work[W_ROW:N_WORK]
    zeros = scratch[0:3]
    zeros[:] = 0.0
    rate, ang_acc, raw, vel_dot = scratch[3:6], scratch[6:9], scratch[9:12], scratch[12:15]
    thr, torque = scratch[15:18], scratch[18:21]
    unallocated, q = scratch[21:25], scratch[25:29]
    mats = work[W_MATS:W_ROW].reshape((5, 3, 3))
    qd, r_e, red, att_i, att_sp_i = mats[0], mats[1], mats[2], mats[3], mats[4]
    k = 29
    s = scratch[k:k + N_STATE]  # the row of the agent state
    k += N_STATE
    pos_s = scratch[k:k + N_POS_STATE]  # ... of the position law's state
    k += N_POS_STATE
    hte_s = scratch[k:k + N_HTE_STATE]  # ... of the hover-thrust EKF's state
    k += N_HTE_STATE
    rate_s = scratch[k:k + N_RATE_STATE]  # ... of the rate law's state
    k += N_RATE_STATE
    gyro_i, pos_i, vel_i, sp_i = scratch[k:k + 3], scratch[k + 3:k + 6], scratch[k + 6:k + 9], scratch[k + 9:k + 12]
    k += 12
    action_i = scratch[k:k + 4]
    gyro_z, dgyro_z = s[GYRO_Z:GYRO_Z + 6], s[DGYRO_Z:DGYRO_Z + 6]
    vel_deriv, rate_sp = s[VEL_DERIV:VEL_DERIV + 7], s[RATE_SP:RATE_SP + 3]
    torque_sp, rotor = s[TORQUE:TORQUE + 3], s[ROTOR:ROTOR + 4]
    last_sp = setpoint.shape[0] - 1
    sin_yaw, cos_yaw = math.sin(yaw), math.cos(yaw)  # the heading setpoint, the same for every row
    cos_tilt = math.cos(pos_prm[TILT_MAX])  # the tilt limit's cosine, the same for every row
    for i in range(n):
        for j in range(N_STATE):
            s[j] = state[i, j]
        for j in range(N_RATE_STATE):
            rate_s[j] = rate_state[i, j]
        for j in range(3):
            gyro_i[j] = gyro[i, j]
            for m in range(3):
                att_i[j, m] = att[i, j, m]
                att_sp_i[j, m] = att_sp[i, j, m]
        # 1. gyro filters
        if s[FRESH] != 0.0:
            butterworth_reset_row(gyro_i, gyro_z, gyro_coef)
            dgyro_z[:] = 0.0
            for j in range(3):
                rate[j] = gyro_i[j]
            ang_acc[:] = 0.0
            s[FRESH] = 0.0
        else:
            butterworth_row(gyro_i, gyro_z, gyro_coef, rate)
            for j in range(3):
                raw[j] = (gyro_i[j] - s[GYRO_PREV + j]) / dt
            butterworth_row(raw, dgyro_z, dgyro_coef, ang_acc)
        for j in range(3):
            s[GYRO_PREV + j] = gyro_i[j]
        # 2.-3. position loop
        pos_dt = _tick(s, POS_LOOP, cfg[PERIOD + POS_LOOP], dt)
        if pos_dt > 0.0:
            for j in range(N_POS_STATE):
                pos_s[j] = pos_state[i, j]
            for j in range(N_HTE_STATE):
                hte_s[j] = hte_state[i, j]
            row_sp = min(i, last_sp)
            for j in range(3):
                pos_i[j] = pos[i, j]
                vel_i[j] = vel[i, j]
                sp_i[j] = setpoint[row_sp, j]
            if cfg[USE_HTE] != 0.0 and has_specific_force and s[HAS_THR0] != 0.0:
                # vertical acceleration (up positive) from the accelerometer: a = R f + g e3
                acc_up = -(att_i[2, 0] * specific_force[i, 0] + att_i[2, 1] * specific_force[i, 1]
                           + att_i[2, 2] * specific_force[i, 2] + GRAVITY)
                hover_thrust_row(acc_up, -s[THR0 + 2], vel_i, pos_dt, hte_prm, hte_s)
                if hte_s[VALID] != 0.0:  # PX4 applies only valid estimates
                    update_hover_thrust_row(hte_s[HTE_HOVER], pos_prm, pos_s)
            filtered_derivative_row(vel_i, vel_deriv, cfg[VELD_CUTOFF], pos_dt, vel_dot)
            position_control_row(pos_i, vel_i, vel_dot, sp_i, zeros, zeros, pos_dt, pos_prm, cos_tilt, pos_s, True, thr)
            for j in range(3):
                s[THR0 + j] = thr[j]
            s[HAS_THR0] = 1.0
            if use_force:  # F = F0 - phi_hat, limited as PX4's own
                for j in range(3):
                    raw[j] = force_hat[i, j]
                force_feedforward_row(thr, raw, cfg[THRUST_SCALE], pos_prm[TILT_MAX], cos_tilt, pos_prm[THR_MIN],
                                      pos_prm[THR_MAX], thr)
            for j in range(3):
                s[THR_SP + j] = thr[j]
            bodyz_to_attitude_row(-thr[0], -thr[1], -thr[2], sin_yaw, cos_yaw, att_sp_i)
            for j in range(N_POS_STATE):
                pos_state[i, j] = pos_s[j]
            for j in range(N_HTE_STATE):
                hte_state[i, j] = hte_s[j]
            for j in range(3):
                for m in range(3):
                    att_sp[i, j, m] = att_sp_i[j, m]
        # 4. attitude loop
        if _tick(s, ATT_LOOP, cfg[PERIOD + ATT_LOOP], dt) > 0.0:
            attitude_control_row(att_i, att_sp_i, 0.0, att_prm, qd, r_e, red, q, rate_sp)
        # 5. rate loop, tau = tau0 - tau_hat in normalized units
        rate_dt = _tick(s, RATE_LOOP, cfg[PERIOD + RATE_LOOP], dt)
        if rate_dt > 0.0:
            rate_control_row(rate, rate_sp, ang_acc, rate_dt, rate_prm, rate_s, True, torque)
            for j in range(3):
                s[TORQUE + j] = torque[j] - torque_hat[i, j] / cfg[TORQUE_SCALE + j] if use_torque else torque[j]
        # 6. allocation, saturation flags for the rate integrator, motor commands
        collective = math.sqrt(s[THR_SP] * s[THR_SP] + s[THR_SP + 1] * s[THR_SP + 1] + s[THR_SP + 2] * s[THR_SP + 2])
        allocate_row(torque_sp, collective, mix_t, effectiveness, alloc_scale, rotor, unallocated)
        missed = unallocated[0] ** 2 + unallocated[1] ** 2 + unallocated[2] ** 2 >= SAT_EPS
        for j in range(3):
            rate_s[SAT_POS + j] = 1.0 if missed and unallocated[j] > SAT_EPS else 0.0
            rate_s[SAT_NEG + j] = 1.0 if missed and unallocated[j] < -SAT_EPS else 0.0
        rotor_command_row(rotor, rotor_map, action_i)
        for j in range(4):
            action[i, j] = action_i[j]
        for j in range(N_STATE):
            state[i, j] = s[j]
        for j in range(N_RATE_STATE):
            rate_state[i, j] = rate_s[j]
    for i in range(n):
        for j in range(4):
            if not math.isfinite(action[i, j]):
                return BAD_ACTION, i
    return OK, -1
