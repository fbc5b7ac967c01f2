"""The hover env's step law as compiled row kernels (one implementation for N = 1 and N = 1024).

Each kernel loops ``for i in range(n)`` over the rows of C-contiguous float64 arrays with a leading row axis
and writes into the arrays it is given (numba ``@njit(cache=True)``; ``NUMBA_DISABLE_JIT=1`` runs them as plain
Python).  The env validates its inputs in Python once, in front of them (:mod:`fawtgym.envs.options`).

* :func:`motor_controls`: the exact first-order rotor lag over a control step (speeds at the mid-substep times ->
  rotor thrusts per physics substep, the speeds at the end of the step, the mean thrusts) and the held
  disturbance wrench, written as ``mujoco.rollout`` controls;
* :func:`read_states`: MuJoCo FULLPHYSICS states -> the NED/FRD state, the divergence test and the termination
  rules (ground contact, position box);
* :func:`hover_reward`: the dense reward and its terms (the table of :mod:`fawtgym.envs.hover_env`);
* :func:`act_rows`, :func:`observe_rows`, :func:`step_rows`, :func:`disturbance_rows`: the laws above, the sensors
  and the aero wrench composed into the few calls of one control step (a numba call costs ~0.2 us + ~0.05 us per
  argument, so the env's constants travel in one float64 array, :func:`step_params`), writing ``info``'s numbers
  into one fresh float64 buffer per step (:data:`INFO_FIELDS`, handed out as views by :func:`info_views`).

Frames: MuJoCo is z-up with an FLU body, so NED = diag(1, -1, -1) MuJoCo for vectors and
R_NED = S R_MuJoCo S with S = diag(1, -1, -1) (:mod:`fawtgym.core.frames`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.checks import shown
from fawtgym.core.so3_kernels import quat_to_rot_entries

from .aero import aero_wrench_rows
from .ctbr import rate_loop_rows
from .motors import lag_thrusts
from .observation import OBS_SIZE, observation_rows
from .sensors_batch import measure_rows

#: failure codes of :func:`read_states` -> ``info["failure"]`` names (index = code)
FAILURES = np.array(["", "diverged", "ground_contact", "out_of_bounds"], dtype="<U14")
DIVERGED, GROUND_CONTACT, OUT_OF_BOUNDS = 1, 2, 3
#: the reward's terms, in the order of :func:`hover_reward`'s ``weights`` and ``terms``
REWARD_TERMS = ("pos", "vel", "att", "rate", "action", "failure")


@njit(cache=True, inline="always")
def rot_ned_row(states: NDArray[np.float64], i: int, rot: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """Row ``i`` of FULLPHYSICS states (k, 14): its MuJoCo unit quaternion (w, x, y, z) (columns 4-7) -> R (3, 3) body
    FRD -> world NED into ``rot[i]``.

    R_MuJoCo from :func:`fawtgym.core.so3_kernels.quat_to_rot_entries`, then R_NED = S R_MuJoCo S
    (S = diag(1, -1, -1)): the signs of entries (0, 1), (0, 2), (1, 0), (2, 0) flip.
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rot_entries(states[i, 4], states[i, 5], states[i, 6],
                                                                      states[i, 7])
    rot[i, 0, 0], rot[i, 0, 1], rot[i, 0, 2] = r00, -r01, -r02
    rot[i, 1, 0], rot[i, 1, 1], rot[i, 1, 2] = -r10, r11, r12
    rot[i, 2, 0], rot[i, 2, 1], rot[i, 2, 2] = -r20, r21, r22


@njit(cache=True, inline="always")
def state_row_to_ned(states: NDArray[np.float64], i: int, pos: NDArray[np.float64], vel: NDArray[np.float64],
                     rot: NDArray[np.float64], omega: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """Row ``i`` of FULLPHYSICS states (k, 14) = [time, qpos 7, qvel 6] -> ``pos[i]``, ``vel[i]`` NED, ``rot[i]``,
    ``omega[i]`` FRD (S = diag(1, -1, -1) on MuJoCo's world and body axes)."""
    pos[i, 0], pos[i, 1], pos[i, 2] = states[i, 1], -states[i, 2], -states[i, 3]
    rot_ned_row(states, i, rot)
    vel[i, 0], vel[i, 1], vel[i, 2] = states[i, 8], -states[i, 9], -states[i, 10]
    omega[i, 0], omega[i, 1], omega[i, 2] = states[i, 11], -states[i, 12], -states[i, 13]


@njit(cache=True)
def states_to_ned(states: NDArray[np.float64], pos: NDArray[np.float64], vel: NDArray[np.float64],
                  rot: NDArray[np.float64], omega: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """FULLPHYSICS states (k, 14) = [time, qpos 7, qvel 6] -> position, velocity (k, 3) NED, R (k, 3, 3), Omega FRD."""
    for i in range(states.shape[0]):
        state_row_to_ned(states, i, pos, vel, rot, omega)


@njit(cache=True)
def clip_actions(a: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64],
                 stepping: NDArray[np.bool_], hover: NDArray[np.float64], clipped: NDArray[np.float64],
                 flagged: NDArray[np.bool_]) -> int:  # pragma: no cover - jitted
    """The applied actions: finite actions (N, 4) clipped to [low, high] (``flagged`` rows where that changed an
    entry); a row not stepping (it autoresets) applies the hover action and is not flagged.

    Returns -1; or, before writing anything, ``4 * row + entry`` of the first non-finite action of a stepping row
    (the caller raises, :func:`fawtgym.envs.options.raise_action_not_finite`).
    """
    for i in range(a.shape[0]):
        if stepping[i]:
            for j in range(4):
                if not math.isfinite(a[i, j]):
                    return 4 * i + j
    for i in range(a.shape[0]):
        flagged[i] = False
        for j in range(4):
            if not stepping[i]:
                clipped[i, j] = hover[j]
                continue
            x = min(max(a[i, j], low[j]), high[j])
            clipped[i, j] = x
            if x != a[i, j]:
                flagged[i] = True
    return -1


@njit(cache=True)
def advance_clock(stepping: NDArray[np.bool_], dt: float, max_steps: int, failure: NDArray[np.int8],
                  time: NDArray[np.float64], steps: NDArray[np.int64], terminated: NDArray[np.bool_],
                  truncated: NDArray[np.bool_]) -> int:  # pragma: no cover - jitted
    """Episode time and step count of the stepping rows; ``terminated`` (a failure code) and ``truncated`` (a
    stepping row's step count reached ``max_steps`` without a failure) of every row (a row that autoresets: neither).
    Returns the number of rows that ended (terminated or truncated)."""
    ended = 0
    for i in range(time.shape[0]):
        if stepping[i]:
            time[i] += dt
            steps[i] += 1
        terminated[i] = failure[i] != 0
        truncated[i] = stepping[i] and failure[i] == 0 and steps[i] >= max_steps
        if terminated[i] or truncated[i]:
            ended += 1
    return ended


@njit(cache=True)
def wind_points(pos: NDArray[np.float64], rot: NDArray[np.float64], rotor_pos: NDArray[np.float64],
                points: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """The wind sample points (N, 5, 3) world NED of every row: the CoM ``b`` and the rotor hubs ``b + R r_j``
    (``rotor_pos`` (4, 3) body FRD)."""
    for i in range(pos.shape[0]):
        for c in range(3):
            points[i, 0, c] = pos[i, c]
        for j in range(4):
            for c in range(3):
                points[i, j + 1, c] = pos[i, c] + (rot[i, c, 0] * rotor_pos[j, 0] + rot[i, c, 1] * rotor_pos[j, 1]
                                                   + rot[i, c, 2] * rotor_pos[j, 2])


@njit(cache=True)
def motor_controls(ref: NDArray[np.float64], speeds: NDArray[np.float64], k_thrust: float,
                   decay_up: NDArray[np.float64], decay_down: NDArray[np.float64], force: NDArray[np.float64],
                   torque: NDArray[np.float64], ctrl: NDArray[np.float64],
                   applied: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """Rotor lag and rollout controls of one control step for every row.

    With the speed reference ``c`` (``ref`` (N, 4) [rad/s]) held, a rotor's speed is exactly
    ``w(t) = c + (w0 - c) exp(-t / tau)`` (tau_up if ``c > w0`` else tau_down: the speed approaches ``c``
    monotonically).  ``decay_*`` (K + 1,) hold ``exp(-t / tau)`` at the K mid-substep times and at the end of
    the step.  Writes ``ctrl`` (N, K, 10): the rotor thrusts ``k_T w(t_k)^2`` of substep k, then the held
    wrench (force world NED (N, 3), torque body FRD (N, 3)) in MuJoCo's frames as the free joint's generalized
    force; ``speeds`` (N, 4) becomes the end-of-step speeds and ``applied`` (N, 4) the mean rotor thrusts.
    """
    # the rotor lag: the one law of envs/motors.py (speeds updated in place: each entry is read before written)
    lag_thrusts(ref, speeds, decay_up, decay_down, k_thrust, ctrl, speeds, applied)
    n, k = ctrl.shape[0], ctrl.shape[1]
    for i in range(n):
        for s in range(k):  # NED/FRD -> MuJoCo world z-up / body FLU
            ctrl[i, s, 4], ctrl[i, s, 5], ctrl[i, s, 6] = force[i, 0], -force[i, 1], -force[i, 2]
            ctrl[i, s, 7], ctrl[i, s, 8], ctrl[i, s, 9] = torque[i, 0], -torque[i, 1], -torque[i, 2]


@njit(cache=True)
def action_motor_controls(clipped: NDArray[np.float64], omega_min: float, omega_span: float,
                          speeds: NDArray[np.float64], k_thrust: float, decay_up: NDArray[np.float64],
                          decay_down: NDArray[np.float64], force: NDArray[np.float64],
                          external_force: NDArray[np.float64], torque: NDArray[np.float64],
                          external_torque: NDArray[np.float64], ctrl: NDArray[np.float64],
                          applied: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """``action_type="motors"``: clipped actions (N, 4) in [0, 1] -> speed references
    ``omega_min + u (omega_max - omega_min)``, then :func:`motor_controls` with the held wrench = aero + external
    (force world NED, torque body FRD)."""
    n = clipped.shape[0]
    ref = np.empty((n, 4))
    held_force, held_torque = np.empty((n, 3)), np.empty((n, 3))
    for i in range(n):
        for r in range(4):
            ref[i, r] = clipped[i, r] * omega_span + omega_min
        for c in range(3):
            held_force[i, c] = force[i, c] + external_force[i, c]
            held_torque[i, c] = torque[i, c] + external_torque[i, c]
    motor_controls(ref, speeds, k_thrust, decay_up, decay_down, held_force, held_torque, ctrl, applied)


@njit(cache=True)
def ctbr_substep(collective: NDArray[np.float64], rate_sp: NDArray[np.float64], state: NDArray[np.float64],
                 final: NDArray[np.float64], first: bool, t_end: float, physics_dt: float,
                 loop: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                             NDArray[np.float64], float, float, float, float],
                 loop_state: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]],
                 speeds: NDArray[np.float64], k_thrust: float, decay_up: NDArray[np.float64],
                 decay_down: NDArray[np.float64], force: NDArray[np.float64], torque: NDArray[np.float64],
                 ctrl: NDArray[np.float64], applied: NDArray[np.float64], total: NDArray[np.float64],
                 diverged: NDArray[np.bool_]) -> None:  # pragma: no cover - jitted
    """One physics substep of ``action_type="ctbr"`` for every row, up to the rollout.

    Unless ``first``, the previous one-substep rollout's ``final`` states become ``state`` (a row whose MuJoCo
    time is not ``t_end`` or whose state is not finite is flagged in ``diverged``).  Then the rate loop
    (:func:`fawtgym.envs.ctbr.rate_loop_rows`, gains ``loop``, state ``loop_state``) on the true body rates
    (FRD) gives rotor thrusts, i.e. speed references ``sqrt(T / k_T)``, and :func:`motor_controls` the lagged
    thrusts of the substep (``decay_*`` (2,): mid-substep, end) into ``ctrl`` (N, 1, 10); ``total`` (N, 4)
    accumulates them.
    """
    n = state.shape[0]
    if not first:
        for i in range(n):
            ok = abs(final[i, 0] - t_end) <= 0.5 * physics_dt
            for c in range(state.shape[1]):
                ok = ok and math.isfinite(final[i, c])
                state[i, c] = final[i, c]
            if not ok:
                diverged[i] = True
    rate = np.empty((n, 3))
    for i in range(n):
        rate[i, 0], rate[i, 1], rate[i, 2] = state[i, 11], -state[i, 12], -state[i, 13]
    thrusts = np.empty((n, 4))
    kp, ki, kd, j, b_inv, t_min, t_max, i_lim, dt = loop
    integral, prev_rate, has_prev = loop_state
    rate_loop_rows(collective, rate_sp, rate, kp, ki, kd, j, b_inv, t_min, t_max, i_lim, dt, integral, prev_rate,
                   has_prev, thrusts)
    for i in range(n):
        for r in range(4):
            thrusts[i, r] = math.sqrt(thrusts[i, r] / k_thrust)  # the speed references
    motor_controls(thrusts, speeds, k_thrust, decay_up, decay_down, force, torque, ctrl, applied)
    for i in range(n):
        for r in range(4):
            total[i, r] += applied[i, r]


@njit(cache=True)
def read_states(final: NDArray[np.float64], t_end: float, physics_dt: float, dt: float,
                stepping: NDArray[np.bool_], diverged_before: NDArray[np.bool_], mj_state: NDArray[np.float64],
                pos: NDArray[np.float64], vel: NDArray[np.float64], rot: NDArray[np.float64],
                omega: NDArray[np.float64], accel: NDArray[np.float64], hull: NDArray[np.float64],
                setpoint: NDArray[np.float64], max_position_error: float,
                failure: NDArray[np.int8]) -> None:  # pragma: no cover - jitted
    """The rows' states after a rollout of one control step ``dt``, and the episode-end rules, written in place. A
    stepping row whose final MuJoCo time is not ``t_end`` (MuJoCo reset it: NaN/inf/huge state), whose state is
    not finite, or that diverged in an earlier rollout of the step (``diverged_before``) has diverged: it keeps
    its last finite state (``mj_state``, ``pos`` ...) and gets ``failure = DIVERGED``. Every other stepping row
    takes its final state (``accel`` = the velocity change over the step / dt) and is tested for a ground contact
    (a hull point ``b + R p`` at or below the floor, z_NED >= 0) then the position box (``|b - b_sp|_inf >
    max_position_error``). Rows not stepping are left alone (``failure`` 0).
    """
    n_state = final.shape[1]
    limit = 0.5 * physics_dt
    for i in range(final.shape[0]):
        failure[i] = 0
        if not stepping[i]:
            continue
        zero = 0.0  # sum of x * 0: +-0 if every x is finite, NaN if any is NaN/inf (no overflow, no branch per entry)
        for c in range(n_state):
            zero += float(final[i, c]) * 0.0  # float(): plain Python (no numba) multiplies silently
        if diverged_before[i] or not math.isfinite(zero) or abs(final[i, 0] - t_end) > limit:
            failure[i] = DIVERGED
            continue
        for c in range(n_state):
            mj_state[i, c] = final[i, c]
        v0, v1, v2 = vel[i, 0], vel[i, 1], vel[i, 2]  # the step's start velocity
        state_row_to_ned(final, i, pos, vel, rot, omega)
        accel[i, 0], accel[i, 1], accel[i, 2] = (vel[i, 0] - v0) / dt, (vel[i, 1] - v1) / dt, (vel[i, 2] - v2) / dt
        b0, b1, b2 = pos[i, 0], pos[i, 1], pos[i, 2]
        r20, r21, r22 = rot[i, 2, 0], rot[i, 2, 1], rot[i, 2, 2]
        lowest = -math.inf  # the lowest hull point: the largest z_NED of b + R p
        for h in range(hull.shape[0]):
            z = b2 + r20 * hull[h, 0] + r21 * hull[h, 1] + r22 * hull[h, 2]
            if z > lowest:
                lowest = z
        if lowest >= 0.0:
            failure[i] = GROUND_CONTACT
            continue
        err = max(abs(b0 - setpoint[i, 0]), abs(b1 - setpoint[i, 1]), abs(b2 - setpoint[i, 2]))
        if err > max_position_error:
            failure[i] = OUT_OF_BOUNDS


@njit(cache=True)
def hover_reward(pos: NDArray[np.float64], vel: NDArray[np.float64], att: NDArray[np.float64],
                 rate: NDArray[np.float64], setpoint: NDArray[np.float64], action: NDArray[np.float64],
                 prev_action: NDArray[np.float64], weights: NDArray[np.float64], failed: NDArray[np.bool_],
                 reward: NDArray[np.float64], terms: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """Reward (N,) and its terms (6, N) = (pos, vel, att, rate, action, failure) from measurements.

    ``weights`` (6,) in that order.  pos = w e.e (e = b^m - b_sp), vel = w v.v, att = w Phi^2 with
    Phi = arccos((tr R^m - 1) / 2) the angle from the hover attitude, rate = w Omega.Omega,
    action = w (u - u_prev).(u - u_prev); reward = exp(-(pos + vel + att + rate + action)) in (0, 1], or
    -w_failure on a failure step (failure term w_failure, else 0).
    """
    for i in range(pos.shape[0]):
        e0, e1, e2 = pos[i, 0] - setpoint[i, 0], pos[i, 1] - setpoint[i, 1], pos[i, 2] - setpoint[i, 2]
        t_pos = weights[0] * (e0 * e0 + e1 * e1 + e2 * e2)
        t_vel = weights[1] * (vel[i, 0] * vel[i, 0] + vel[i, 1] * vel[i, 1] + vel[i, 2] * vel[i, 2])
        cos_phi = 0.5 * (att[i, 0, 0] + att[i, 1, 1] + att[i, 2, 2] - 1.0)
        phi = math.acos(min(max(cos_phi, -1.0), 1.0))
        t_att = weights[2] * phi * phi
        t_rate = weights[3] * (rate[i, 0] * rate[i, 0] + rate[i, 1] * rate[i, 1] + rate[i, 2] * rate[i, 2])
        da = 0.0
        for j in range(4):
            d = action[i, j] - prev_action[i, j]
            da += d * d
        t_action = weights[4] * da
        terms[0, i], terms[1, i], terms[2, i], terms[3, i], terms[4, i] = t_pos, t_vel, t_att, t_rate, t_action
        if failed[i]:
            terms[5, i] = weights[5]
            reward[i] = -weights[5]
        else:
            terms[5, i] = 0.0
            reward[i] = math.exp(-(t_pos + t_vel + t_rate + t_action + t_att))


@njit(cache=True)
def finish_step(final: NDArray[np.float64], t_end: float, physics_dt: float, dt: float,
                stepping: NDArray[np.bool_], diverged_before: NDArray[np.bool_], mj_state: NDArray[np.float64],
                pos: NDArray[np.float64], vel: NDArray[np.float64], rot: NDArray[np.float64],
                omega: NDArray[np.float64], accel: NDArray[np.float64], hull: NDArray[np.float64],
                setpoint: NDArray[np.float64], max_position_error: float, failure: NDArray[np.int8],
                max_steps: int, time: NDArray[np.float64], steps: NDArray[np.int64], terminated: NDArray[np.bool_],
                truncated: NDArray[np.bool_], rotor_pos: NDArray[np.float64],
                points: NDArray[np.float64]) -> int:  # pragma: no cover - jitted
    """After a control step's rollout: :func:`read_states`, :func:`advance_clock` and the next wind sample points
    (:func:`wind_points`), in one call.  Returns the number of rows that ended."""
    read_states(final, t_end, physics_dt, dt, stepping, diverged_before, mj_state, pos, vel, rot, omega, accel, hull,
                setpoint, max_position_error, failure)
    ended = advance_clock(stepping, dt, max_steps, failure, time, steps, terminated, truncated)
    wind_points(pos, rot, rotor_pos, points)
    return ended


@njit(cache=True)
def observe_and_reward(pos: NDArray[np.float64], vel: NDArray[np.float64], att: NDArray[np.float64],
                       rate: NDArray[np.float64], setpoint: NDArray[np.float64], action: NDArray[np.float64],
                       prev_action: NDArray[np.float64], obs_low: NDArray[np.float64], obs_high: NDArray[np.float64],
                       weights: NDArray[np.float64], failure: NDArray[np.int8], obs: NDArray[np.float32],
                       reward: NDArray[np.float64], terms: NDArray[np.float64]) -> int:  # pragma: no cover - jitted
    """The observation (:func:`fawtgym.envs.observation.observation_rows`) and the reward with its terms
    (:func:`hover_reward`; a row fails where ``failure`` != 0) from measurements, in one call.  Returns -1, or
    ``19 * row + entry`` of the first non-finite observation entry (nothing else is computed; the caller raises)."""
    bad = observation_rows(pos, vel, att, rate, setpoint, action, obs_low, obs_high, obs)
    if bad >= 0:
        return bad
    failed = np.empty(pos.shape[0], dtype=np.bool_)
    for i in range(pos.shape[0]):
        failed[i] = failure[i] != 0
    hover_reward(pos, vel, att, rate, setpoint, action, prev_action, weights, failed, reward, terms)
    return -1


# ---- one control step in a few calls ---------------------------------------------------------------------------

#: ``info``'s numbers: (group, key, shape per row), in buffer order ("" = a top-level key).  The buffer of N rows
#: is field-major: a field of width w starting at column ``s`` (:data:`INFO_START`) is the C-contiguous (N, w) block
#: ``buf[s N:(s + w) N]``, so every array handed out is a view of the step's own fresh buffer (:func:`info_views`).
INFO_FIELDS = (
    ("measurement", "position", (3,)), ("measurement", "velocity", (3,)), ("measurement", "attitude", (3, 3)),
    ("measurement", "angular_velocity", (3,)), ("measurement", "specific_force", (3,)),
    ("measurement", "gyro", (3,)), ("measurement", "magnetometer", (3,)), ("measurement", "time", ()),
    ("applied", "thrust", ()), ("applied", "torque", (3,)), ("applied", "rotor_thrusts", (4,)),
    ("applied", "motor_speeds", (4,)),
    ("truth", "position", (3,)), ("truth", "velocity", (3,)), ("truth", "attitude", (3, 3)),
    ("truth", "angular_velocity", (3,)), ("truth", "wind", (3,)), ("truth", "force", (3,)), ("truth", "torque", (3,)),
    *(("reward_terms", key, ()) for key in REWARD_TERMS),
    ("", "setpoint", (3,)), ("", "time", ()),
)
INFO_START: dict[tuple[str, str], int] = {}
_col = 0
for _group, _key, _shape in INFO_FIELDS:
    INFO_START[_group, _key] = _col
    _col += int(np.prod(_shape, dtype=int))
INFO_WIDTH = _col  #: numbers per row
_I_MEAS, _I_MEAS_TIME = INFO_START["measurement", "position"], INFO_START["measurement", "time"]
_I_THRUST, _I_ROTORS = INFO_START["applied", "thrust"], INFO_START["applied", "rotor_thrusts"]
_I_TRUTH, _I_WIND = INFO_START["truth", "position"], INFO_START["truth", "wind"]
_I_TERMS, _I_SETPOINT, _I_TIME = INFO_START["reward_terms", "pos"], INFO_START["", "setpoint"], INFO_START["", "time"]

#: the env's constant step parameters, one float64 array (:func:`step_params`): (name, size), in order
STEP_PARAMS = (("t0", 1), ("t_end", 1), ("physics_dt", 1), ("dt", 1), ("max_position_error", 1), ("max_steps", 1),
               ("pose_every", 1), ("sigma", 7), ("field", 3), ("act_low", 4), ("act_high", 4), ("hover", 4),
               ("omega_min", 1), ("omega_span", 1), ("k_thrust", 1), ("obs_low", OBS_SIZE),
               ("obs_high", OBS_SIZE), ("reward_weights", 6), ("alloc_t", 16), ("rotor_pos", 12), ("hull", 36),
               ("cop", 3), ("body_drag", 3), ("k_d", 1), ("k_r", 1))
_P: dict[str, int] = {}
_col = 0
for _name, _size in STEP_PARAMS:
    _P[_name] = _col
    _col += _size
STEP_PARAMS_SIZE = _col
STEP_PARAM_START = dict(_P)  #: where each of :data:`STEP_PARAMS` starts in the array
(_P_T0, _P_T_END, _P_PHYSICS_DT, _P_DT, _P_MAX_ERR, _P_MAX_STEPS, _P_POSE_EVERY, _P_SIGMA, _P_FIELD, _P_ACT_LOW,
 _P_ACT_HIGH, _P_HOVER, _P_OMEGA_MIN, _P_OMEGA_SPAN, _P_K_THRUST, _P_OBS_LOW, _P_OBS_HIGH, _P_REWARD_W, _P_ALLOC_T,
 _P_ROTOR_POS, _P_HULL, _P_COP, _P_BODY_DRAG, _P_K_D, _P_K_R) = (_P[k] for k, _ in STEP_PARAMS)


def step_params(**values: object) -> NDArray[np.float64]:
    """The constant step parameters (every name of :data:`STEP_PARAMS`, each a number or an array of its size) as
    the one float64 array the kernels unpack."""
    out = np.empty(STEP_PARAMS_SIZE)
    if set(values) != set(_P):
        raise ValueError(f"step_params needs exactly {sorted(_P)}, got {sorted(values)}")
    for name, size in STEP_PARAMS:
        v = np.asarray(values[name], dtype=float).ravel()
        if v.size != size:
            raise ValueError(f"step parameter {shown(name)} must have {size} numbers, got {v.size}")
        out[_P[name]:_P[name] + size] = v
    return out


def _row_slices(group: str) -> tuple[slice, ...]:
    """The single env's slices (N = 1) of ``group``'s array fields, in :data:`INFO_FIELDS` order."""
    return tuple(slice(INFO_START[g, key], INFO_START[g, key] + int(np.prod(shape, dtype=int)))
                 for g, key, shape in INFO_FIELDS if g == group and shape)


_MEAS_ROW, _APPLIED_ROW, _TRUTH_ROW = _row_slices("measurement"), _row_slices("applied"), _row_slices("truth")
_TERMS_ROW, _SETPOINT_ROW = slice(_I_TERMS, _I_TERMS + 6), slice(_I_SETPOINT, _I_SETPOINT + 3)


def info_views(buf: NDArray[np.float64], n: int, single: bool) -> dict[str, Any]:
    """``info``'s arrays as views of one step's buffer ``buf`` (:data:`INFO_FIELDS`, N = ``n`` rows): (N, ...) arrays,
    or for ``single`` (N = 1, Gymnasium's single-env form) the row's arrays ((3,), (3, 3), ...), the applied thrust,
    the reward terms and the time as Python floats and the measurement time a numpy float64.  The caller adds
    ``action_clipped`` and ``failure``.  Written out field by field (the hot path of the single env; a test checks
    it against :data:`INFO_FIELDS`)."""
    if single:  # precomputed slices (~0.08 us a view instead of ~0.12)
        mp, mv, ma, mr, mf, mg, mm = _MEAS_ROW
        at, ar, asp = _APPLIED_ROW
        tp, tv, ta, t_rate, tw, tf, tt = _TRUTH_ROW
        terms = buf[_TERMS_ROW].tolist()
        return {
            "measurement": {"position": buf[mp], "velocity": buf[mv], "attitude": buf[ma].reshape(3, 3),
                            "angular_velocity": buf[mr], "specific_force": buf[mf], "gyro": buf[mg],
                            "magnetometer": buf[mm], "time": buf[_I_MEAS_TIME]},
            "applied": {"thrust": float(buf[_I_THRUST]), "torque": buf[at], "rotor_thrusts": buf[ar],
                        "motor_speeds": buf[asp]},
            "truth": {"position": buf[tp], "velocity": buf[tv], "attitude": buf[ta].reshape(3, 3),
                      "angular_velocity": buf[t_rate], "wind": buf[tw], "force": buf[tf], "torque": buf[tt]},
            "reward_terms": {"pos": terms[0], "vel": terms[1], "att": terms[2], "rate": terms[3], "action": terms[4],
                             "failure": terms[5]},
            "setpoint": buf[_SETPOINT_ROW], "time": float(buf[_I_TIME])}
    m, ap, tr, te, sp, t = _I_MEAS, _I_THRUST, _I_TRUTH, _I_TERMS, _I_SETPOINT, _I_TIME

    def vec(start: int, width: int = 3) -> NDArray[np.float64]:
        return buf[start * n:(start + width) * n].reshape(n, width)

    def mat(start: int) -> NDArray[np.float64]:
        return buf[start * n:(start + 9) * n].reshape(n, 3, 3)

    def col(start: int) -> NDArray[np.float64]:
        return buf[start * n:(start + 1) * n]

    return {
        "measurement": {"position": vec(m), "velocity": vec(m + 3), "attitude": mat(m + 6),
                        "angular_velocity": vec(m + 15), "specific_force": vec(m + 18), "gyro": vec(m + 21),
                        "magnetometer": vec(m + 24), "time": col(m + 27)},
        "applied": {"thrust": col(ap), "torque": vec(ap + 1), "rotor_thrusts": vec(ap + 4, 4),
                    "motor_speeds": vec(ap + 8, 4)},
        "truth": {"position": vec(tr), "velocity": vec(tr + 3), "attitude": mat(tr + 6),
                  "angular_velocity": vec(tr + 15), "wind": vec(tr + 18), "force": vec(tr + 21),
                  "torque": vec(tr + 24)},
        "reward_terms": {"pos": col(te), "vel": col(te + 1), "att": col(te + 2), "rate": col(te + 3),
                         "action": col(te + 4), "failure": col(te + 5)},
        "setpoint": vec(sp), "time": col(t)}


@njit(cache=True)
def _block(buf: NDArray[np.float64], start: int, width: int, n: int) -> NDArray[np.float64]:  # pragma: no cover
    """The (n, width) field block of an info buffer starting at column ``start`` (:data:`INFO_FIELDS`)."""
    return buf[start * n:(start + width) * n].reshape((n, width))


@njit(cache=True, nogil=True)
def act_rows(a: NDArray[np.float64], params: NDArray[np.float64], stepping: NDArray[np.bool_], motors: bool,
             decay_up: NDArray[np.float64], decay_down: NDArray[np.float64], speeds: NDArray[np.float64],
             wrench: NDArray[np.float64], clipped: NDArray[np.float64], flagged: NDArray[np.bool_],
             ctrl: NDArray[np.float64], applied: NDArray[np.float64]) -> int:  # pragma: no cover - jitted
    """:func:`clip_actions` (to the action space's bounds in ``params``; a row not stepping: its hover action), then
    for ``motors`` :func:`action_motor_controls` (speed map and thrust coefficient in ``params``; the held wrench:
    ``wrench`` (N, 15), :func:`disturbance_rows`' layout).  Returns -1, or :func:`clip_actions`' code of the first
    non-finite action of a stepping row (nothing written)."""
    bad = clip_actions(a, params[_P_ACT_LOW:_P_ACT_LOW + 4], params[_P_ACT_HIGH:_P_ACT_HIGH + 4], stepping,
                       params[_P_HOVER:_P_HOVER + 4], clipped, flagged)
    if bad >= 0 or not motors:
        return bad
    action_motor_controls(clipped, params[_P_OMEGA_MIN], params[_P_OMEGA_SPAN], speeds, params[_P_K_THRUST], decay_up,
                          decay_down, wrench[:, 0:3], wrench[:, 9:12], wrench[:, 3:6], wrench[:, 12:15], ctrl, applied)
    return -1


@njit(cache=True, nogil=True)
def observe_rows(params: NDArray[np.float64], z: NDArray[np.float64], measure: bool, pos: NDArray[np.float64],
                 vel: NDArray[np.float64], rot: NDArray[np.float64], omega: NDArray[np.float64],
                 accel: NDArray[np.float64], time: NDArray[np.float64], setpoint: NDArray[np.float64],
                 failure: NDArray[np.int8], sensor_count: NDArray[np.int64], sensor_state: NDArray[np.float64],
                 action: NDArray[np.float64], prev_action: NDArray[np.float64],
                 applied: NDArray[np.float64], speeds: NDArray[np.float64], buf: NDArray[np.float64],
                 obs: NDArray[np.float32], reward: NDArray[np.float64]) -> int:  # pragma: no cover - jitted
    """Every row's info numbers but the held disturbance (:func:`disturbance_rows` writes those), observation and
    reward after a step (or a reset).

    If ``measure``, the sensors (:func:`fawtgym.envs.sensors_batch.measure_rows`, normals ``z`` (N, 21), the sensor
    state ``sensor_count``, ``sensor_state`` updated in place) write the measurement into ``buf``; else the caller
    wrote it there.  Then the applied rotor thrusts (collective thrust and torque through the allocation), the rotor
    speeds, the true state, set point and time, and :func:`observe_and_reward` of the measurement with the applied
    ``action`` and the previous one (its terms into ``buf``).  Returns -1; or ``OBS_SIZE N + row`` of the first row
    whose measurement is not finite; or :func:`observe_and_reward`'s code (the caller raises).
    """
    n = pos.shape[0]
    m_pos, m_vel = _block(buf, _I_MEAS, 3, n), _block(buf, _I_MEAS + 3, 3, n)
    m_att = buf[(_I_MEAS + 6) * n:(_I_MEAS + 15) * n].reshape((n, 3, 3))
    m_rate = _block(buf, _I_MEAS + 15, 3, n)
    if measure:
        bad = measure_rows(pos, vel, rot, omega, accel, z, params[_P_SIGMA:_P_SIGMA + 7],
                           params[_P_FIELD:_P_FIELD + 3], sensor_state, sensor_count, int(params[_P_POSE_EVERY]),
                           m_pos, m_vel, m_att, m_rate,
                           _block(buf, _I_MEAS + 18, 3, n), _block(buf, _I_MEAS + 21, 3, n),
                           _block(buf, _I_MEAS + 24, 3, n))
        if bad >= 0:
            return OBS_SIZE * n + bad
        buf[_I_MEAS_TIME * n:(_I_MEAS_TIME + 1) * n] = time
    alloc_t = params[_P_ALLOC_T:_P_ALLOC_T + 16].reshape((4, 4))
    torque = _block(buf, _I_THRUST + 1, 3, n)
    rotors, motor_speeds = _block(buf, _I_ROTORS, 4, n), _block(buf, _I_ROTORS + 4, 4, n)
    t_pos, t_vel = _block(buf, _I_TRUTH, 3, n), _block(buf, _I_TRUTH + 3, 3, n)
    t_att = buf[(_I_TRUTH + 6) * n:(_I_TRUTH + 15) * n].reshape((n, 3, 3))
    t_rate = _block(buf, _I_TRUTH + 15, 3, n)
    sp = _block(buf, _I_SETPOINT, 3, n)
    for i in range(n):
        for c in range(4):  # [f, tau] = B T: collective thrust and body torque (envs/motors.allocation_matrix)
            total = 0.0
            for r in range(4):
                total += applied[i, r] * alloc_t[r, c]
            if c == 0:
                buf[_I_THRUST * n + i] = total
            else:
                torque[i, c - 1] = total
            rotors[i, c] = applied[i, c]
            motor_speeds[i, c] = speeds[i, c]
        for c in range(3):
            t_pos[i, c], t_vel[i, c], t_rate[i, c], sp[i, c] = pos[i, c], vel[i, c], omega[i, c], setpoint[i, c]
            for k in range(3):
                t_att[i, c, k] = rot[i, c, k]
        buf[_I_TIME * n + i] = time[i]
    terms = _block(buf, _I_TERMS, 6, n).reshape((6, n))
    return observe_and_reward(m_pos, m_vel, m_att, m_rate, setpoint, action, prev_action,
                              params[_P_OBS_LOW:_P_OBS_LOW + OBS_SIZE], params[_P_OBS_HIGH:_P_OBS_HIGH + OBS_SIZE],
                              params[_P_REWARD_W:_P_REWARD_W + 6], failure, obs, reward, terms)


@njit(cache=True, nogil=True)
def step_rows(params: NDArray[np.float64], states: NDArray[np.float64], stepping: NDArray[np.bool_],
              diverged_before: NDArray[np.bool_], mj_state: NDArray[np.float64], pos: NDArray[np.float64],
              vel: NDArray[np.float64], rot: NDArray[np.float64], omega: NDArray[np.float64],
              accel: NDArray[np.float64], setpoint: NDArray[np.float64], failure: NDArray[np.int8],
              time: NDArray[np.float64], steps: NDArray[np.int64], ended_flags: NDArray[np.bool_],
              points: NDArray[np.float64], observe: bool, z: NDArray[np.float64],
              sensor_count: NDArray[np.int64], sensor_state: NDArray[np.float64], action: NDArray[np.float64],
              prev_action: NDArray[np.float64], applied: NDArray[np.float64],
              speeds: NDArray[np.float64], buf: NDArray[np.float64], obs: NDArray[np.float32],
              reward: NDArray[np.float64]) -> tuple[int, int]:  # pragma: no cover - jitted
    """After a control step's rollout (``states`` (N, K, 14): the rollout's states; the last substep's are the
    final ones): :func:`finish_step` (state readout, termination, clock, wind sample points; the kept MuJoCo states
    set back to the rollouts' start time ``t0``), then, if ``observe`` (no row restarts in this step, else the caller
    resets those rows first), :func:`observe_rows` with the sensors' normals ``z``; ``ended_flags`` (2, N):
    terminated, truncated.  Returns (rows ended, :func:`observe_rows`' status; -1 when not observed)."""
    hull = params[_P_HULL:_P_HULL + 36].reshape((12, 3))
    rotor_pos = params[_P_ROTOR_POS:_P_ROTOR_POS + 12].reshape((4, 3))
    final = states[:, states.shape[1] - 1]
    ended = finish_step(final, params[_P_T_END], params[_P_PHYSICS_DT], params[_P_DT], stepping, diverged_before,
                        mj_state, pos, vel, rot, omega, accel, hull, setpoint, params[_P_MAX_ERR], failure,
                        int(params[_P_MAX_STEPS]), time, steps, ended_flags[0], ended_flags[1], rotor_pos, points)
    for i in range(mj_state.shape[0]):
        mj_state[i, 0] = params[_P_T0]  # the next rollout starts at t0 (its end time is the divergence test)
    if not observe:
        return ended, -1
    status = observe_rows(params, z, True, pos, vel, rot, omega, accel, time, setpoint, failure, sensor_count,
                          sensor_state, action, prev_action, applied, speeds, buf, obs, reward)
    return ended, status


@njit(cache=True, nogil=True)
def disturbance_rows(params: NDArray[np.float64], rot: NDArray[np.float64], vel: NDArray[np.float64],
                     omega: NDArray[np.float64], speeds: NDArray[np.float64], wind: NDArray[np.float64],
                     drag_scale: NDArray[np.float64], keep: NDArray[np.bool_], wrench: NDArray[np.float64],
                     buf: NDArray[np.float64]) -> int:  # pragma: no cover - jitted
    """The held disturbance for the next step: the aero wrench (:func:`fawtgym.envs.aero.aero_wrench_rows`) of every
    row in ``wind`` (N, 5, 3) at [CoM, hubs], scaled by the rows' ``drag_scale`` (the wrench is linear in the drag
    coefficients), kept with the CoM wind for the rows of ``keep`` in ``wrench`` (N, 15): per row aero force NED
    0-2, aero torque FRD 3-5, CoM wind 6-8, external force 9-11 and torque 12-14; then the truth's wind, force and
    torque (aero + external) of every row into the info buffer ``buf``.  Returns -1, or the
    first row whose wrench is not finite (nothing written; the caller raises)."""
    n = rot.shape[0]
    new_force, new_torque = np.empty((n, 3)), np.empty((n, 3))
    bad = aero_wrench_rows(rot, vel, omega, speeds, wind, params[_P_ROTOR_POS:_P_ROTOR_POS + 12].reshape((4, 3)),
                           params[_P_COP:_P_COP + 3], params[_P_BODY_DRAG:_P_BODY_DRAG + 3], params[_P_K_D],
                           params[_P_K_R], new_force, new_torque)
    if bad >= 0:
        return bad
    t_wind, t_force, t_torque = _block(buf, _I_WIND, 3, n), _block(buf, _I_WIND + 3, 3, n), _block(buf, _I_WIND + 6,
                                                                                                   3, n)
    for i in range(n):
        if keep[i]:
            scale = drag_scale[i]
            for c in range(3):
                wrench[i, c] = new_force[i, c] * scale
                wrench[i, 3 + c] = new_torque[i, c] * scale
                wrench[i, 6 + c] = wind[i, 0, c]
    for i in range(n):  # row-major over each info block
        for c in range(3):
            t_wind[i, c] = wrench[i, 6 + c]
    for i in range(n):
        for c in range(3):
            t_force[i, c] = wrench[i, c] + wrench[i, 9 + c]
    for i in range(n):
        for c in range(3):
            t_torque[i, c] = wrench[i, 3 + c] + wrench[i, 12 + c]
    return -1
