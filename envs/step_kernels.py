"""The hover env's step law as compiled row kernels (one implementation for N = 1 and N = 1024).

Each kernel loops ``for i in range(n)`` over the rows of C-contiguous float64 arrays with a leading row axis
and writes into the arrays it is given (numba ``@njit(cache=True)``; ``NUMBA_DISABLE_JIT=1`` runs them as plain
Python).  The env validates its inputs in Python once, in front of them (:mod:`fawtgym.envs.options`).

* :func:`motor_controls`: the exact first-order rotor lag over a control step (speeds at the mid-substep times ->
  rotor thrusts per physics substep, the speeds at the end of the step, the mean thrusts) and the held
  disturbance wrench, written as ``mujoco.rollout`` controls;
* :func:`read_states`: MuJoCo FULLPHYSICS states -> the NED/FRD state, the divergence test and the termination
  rules (ground contact, position box);
* :func:`hover_reward`: the dense reward and its terms (the table of :mod:`fawtgym.envs.hover_env`).

Frames: MuJoCo is z-up with an FLU body, so NED = diag(1, -1, -1) MuJoCo for vectors and
R_NED = S R_MuJoCo S with S = diag(1, -1, -1) (:mod:`fawtgym.core.frames`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.so3_kernels import quat_to_rot_row

from .ctbr import rate_loop_rows
from .motors import lag_thrusts
from .observation import observation_rows

#: failure codes of :func:`read_states` -> ``info["failure"]`` names (index = code)
FAILURES = np.array(["", "diverged", "ground_contact", "out_of_bounds"], dtype="<U14")
DIVERGED, GROUND_CONTACT, OUT_OF_BOUNDS = 1, 2, 3
#: the reward's terms, in the order of :func:`hover_reward`'s ``weights`` and ``terms``
REWARD_TERMS = ("pos", "vel", "att", "rate", "action", "failure")


@njit(cache=True)
def quat_mj_to_rot_ned(q: NDArray[np.float64], r: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """One MuJoCo unit quaternion (w, x, y, z) (4,) -> R (3, 3) body FRD -> world NED into ``r``.

    R_MuJoCo from :func:`fawtgym.core.so3_kernels.quat_to_rot_row`, then R_NED = S R_MuJoCo S
    (S = diag(1, -1, -1)): the signs of entries (0, 1), (0, 2), (1, 0), (2, 0) flip.
    """
    quat_to_rot_row(q, r)
    r[0, 1], r[0, 2], r[1, 0], r[2, 0] = -r[0, 1], -r[0, 2], -r[1, 0], -r[2, 0]


@njit(cache=True)
def states_to_ned(states: NDArray[np.float64], pos: NDArray[np.float64], vel: NDArray[np.float64],
                  rot: NDArray[np.float64], omega: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """FULLPHYSICS states (k, 14) = [time, qpos 7, qvel 6] -> position, velocity (k, 3) NED, R (k, 3, 3), Omega FRD."""
    for i in range(states.shape[0]):
        s = states[i]
        pos[i, 0], pos[i, 1], pos[i, 2] = s[1], -s[2], -s[3]
        quat_mj_to_rot_ned(s[4:8], rot[i])
        vel[i, 0], vel[i, 1], vel[i, 2] = s[8], -s[9], -s[10]
        omega[i, 0], omega[i, 1], omega[i, 2] = s[11], -s[12], -s[13]


@njit(cache=True)
def clip_actions(a: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64],
                 stepping: NDArray[np.bool_], hover: NDArray[np.float32], clipped: NDArray[np.float64],
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
    for i in range(final.shape[0]):
        failure[i] = 0
        if not stepping[i]:
            continue
        s = final[i]
        finite = True
        for c in range(s.shape[0]):
            if not math.isfinite(s[c]):
                finite = False
        if diverged_before[i] or not finite or abs(s[0] - t_end) > 0.5 * physics_dt:
            failure[i] = DIVERGED
            continue
        v0, v1, v2 = vel[i, 0], vel[i, 1], vel[i, 2]
        for c in range(s.shape[0]):
            mj_state[i, c] = s[c]
        pos[i, 0], pos[i, 1], pos[i, 2] = s[1], -s[2], -s[3]
        quat_mj_to_rot_ned(s[4:8], rot[i])
        vel[i, 0], vel[i, 1], vel[i, 2] = s[8], -s[9], -s[10]
        omega[i, 0], omega[i, 1], omega[i, 2] = s[11], -s[12], -s[13]
        accel[i, 0], accel[i, 1], accel[i, 2] = (vel[i, 0] - v0) / dt, (vel[i, 1] - v1) / dt, (vel[i, 2] - v2) / dt
        lowest = -math.inf  # the lowest hull point: the largest z_NED
        for h in range(hull.shape[0]):
            z = pos[i, 2] + rot[i, 2, 0] * hull[h, 0] + rot[i, 2, 1] * hull[h, 1] + rot[i, 2, 2] * hull[h, 2]
            if z > lowest:
                lowest = z
        if lowest >= 0.0:
            failure[i] = GROUND_CONTACT
            continue
        err = max(abs(pos[i, 0] - setpoint[i, 0]), abs(pos[i, 1] - setpoint[i, 1]), abs(pos[i, 2] - setpoint[i, 2]))
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
