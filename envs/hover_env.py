"""``fawtgym/Hover-v0``: a quad X hovering at a set point (by default in front of the fan array).

Physics: MuJoCo, one free body (:mod:`fawtgym.envs.mjcf`), default step 1 ms with MuJoCo's
semi-implicit ``Euler`` integrator.  Why Euler: the vehicle is a single free rigid body whose only
stiff part (the rotor lag) is integrated exactly outside MuJoCo, so RK4's accuracy buys nothing
measurable at 1 ms while costing ~4x per step (raw ``mj_step`` here: ~350k steps/s Euler vs ~87k
RK4); ``integrator="RK4"`` is available.

One control step (period ``1 / control_rate``, which must divide the physics rate):

1. the action is checked (NaN/inf -> ValueError naming the index; finite values outside the
   action space are clipped and flagged in ``info["action_clipped"]``);
2. the wind model gives the wind at the CoM and the four rotor hubs, the aerodynamic model turns
   it into a disturbance force (world NED) and torque (body FRD); both, plus any user external
   wrench, are held over the control step and reported exactly in ``info["truth"]``;
3. the motors: ``"motors"`` actions set rotor speed references (see :mod:`.motors`), the rotor
   speeds follow the exact first-order lag; ``"ctbr"`` actions (collective thrust, body rates)
   go through an inner rate loop (:mod:`.ctbr`) at the physics rate;
4. MuJoCo steps ``physics_rate / control_rate`` times; a non-finite state ends the episode with
   ``info["failure"] = "diverged"`` (the last finite state is returned);
5. sensors (:mod:`.sensors`) produce ``info["measurement"]``; the observation is built from it.

``info`` also carries ``"applied"`` (the known inputs: mean collective rotor thrust [N] and rotor
torque [N m] over the step just taken, rotor thrusts and speeds), ``"truth"`` (true state, wind at the
CoM, disturbance force NED and torque FRD exactly as applied; for metrics only), ``"setpoint"``
(the NED position set point, a command), ``"action_clipped"``, ``"failure"`` and ``"time"``.

Observation (float32, shape (19,)), from *measurements*, never the truth:
``[b^m - b_sp (3, NED m), v^m (3, NED m/s), R^m[:, 0], R^m[:, 1] (6, the continuous 6-D attitude
representation of Zhou et al. 2019), Omega^m (3, FRD rad/s), the action just applied (4; at reset
the hover action)]``, clipped to the box bounds.

Reward (dense, bounded in [-1, 1]): ``exp(-(w_pos |e_b|^2 + w_vel |v|^2 + w_att Phi^2 +
w_rate |Omega|^2 + w_action |u - u_prev|^2))`` with Phi the attitude error angle (tilt + yaw) from
the hover attitude (computed on measurements), and ``-w_failure`` (default 1) on a failure step.

Termination: ground contact (a hull corner or rotor hub at or below the floor, z_NED >= 0), leaving
the box ``|b_i - b_sp,i| <= max_position_error`` (default 2 m per NED axis), or divergence.  Truncation at
``episode_seconds``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from fawtgym.observers.lie import exp_so3

from . import measurement as M
from .aero import AeroModel
from .ctbr import MAX_RATES, RateLoop
from .frames import FAWT_HOVER_POINT_NED, SIGN2_MJ_NED, SIGN_MJ_NED, rot_ned_to_quat_mj, vec_ned_to_mj
from .mjcf import INTEGRATORS, hull_points, vehicle_mjcf
from .motors import allocation_matrix, hover_command
from .sensors import SensorModel, make_sensor_spec
from .vehicles import GRAVITY, VehiclePreset, make_vehicle
from .wind import WindModel, make_wind

ACTION_TYPES = ("motors", "ctbr")
RENDER_MODES = ("rgb_array",)
DEFAULT_REWARD_WEIGHTS: dict[str, float] = {
    "pos": 2.0, "vel": 0.2, "att": 1.0, "rate": 0.05, "action": 0.5, "failure": 1.0,
}
#: initial-state perturbation at init_noise = 1: uniform in +- these (position m, velocity m/s, tilt rad, rate rad/s)
INIT_SPREAD = {"position": 0.1, "velocity": 0.1, "attitude": math.radians(3.0), "angular_velocity": 0.1}
_BADQPOS, _BADQVEL, _BADQACC = (int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                                                 mujoco.mjtWarning.mjWARN_BADQACC))
_SIGN, _SIGN2 = SIGN_MJ_NED, SIGN2_MJ_NED  # MuJoCo z-up/FLU <-> NED/FRD, inlined in the hot path


def _positive(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a positive number, got {value!r}") from exc
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    return v


class HoverEnv(gym.Env):
    """Quadrotor hover in (optionally turbulent) wind.  See the module docstring for the details.

    Args:
        vehicle: preset name, :class:`VehiclePreset`, mapping or YAML/JSON path.
        wind: wind preset name, :class:`WindModel` or ``{"name": ..., **options}``.
        action_type: ``"motors"`` (4 normalized commands in [0, 1]) or ``"ctbr"`` (collective
            thrust in [0, 1] of the maximum, body rates in [-1, 1] of (220, 220, 200) deg/s).
        sensors: ``"none"``, ``"seed000"``, ``"mocap_imu"``, a SensorSpec or a mapping.
        control_rate, physics_rate: Hz; ``physics_rate / control_rate`` must be an integer.
        episode_seconds: truncation time.
        setpoint: hover set point, world NED (default: the seed-000 FAWT point).
        init_noise: scale of the random initial perturbation (0: start exactly hovering at the set point).
        reward_weights: overrides of :data:`DEFAULT_REWARD_WEIGHTS`.
        max_position_error: half-size of the termination box [m].
        integrator: MuJoCo integrator name.
        render_mode: ``None`` or ``"rgb_array"`` (headless via MUJOCO_GL=egl, set by default).
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 50}

    def __init__(self, vehicle: str | VehiclePreset | Mapping[str, Any] = "s500",
                 wind: str | WindModel | Mapping[str, Any] | None = "calm", action_type: str = "motors",
                 sensors: Any = "none", control_rate: float = 100.0, physics_rate: float = 1000.0,
                 episode_seconds: float = 10.0, setpoint: ArrayLike | None = None, init_noise: float = 1.0,
                 reward_weights: Mapping[str, float] | None = None, max_position_error: float = 2.0,
                 integrator: str = "Euler", render_mode: str | None = None, render_width: int = 480,
                 render_height: int = 480) -> None:
        super().__init__()
        self.preset = make_vehicle(vehicle)
        if action_type not in ACTION_TYPES:
            raise ValueError(f"unknown action_type {action_type!r}; valid: {list(ACTION_TYPES)}")
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"unknown render_mode {render_mode!r}; valid: {[None, *RENDER_MODES]}")
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {integrator!r}; valid: {list(INTEGRATORS)}")
        control_rate = _positive("control_rate", control_rate)
        physics_rate = _positive("physics_rate", physics_rate)
        ratio = physics_rate / control_rate
        if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(f"control_rate {control_rate:g} Hz must divide physics_rate {physics_rate:g} Hz "
                             f"(their ratio {ratio:g} must be a whole number)")
        self.n_substeps = int(round(ratio))
        self.physics_dt = 1.0 / physics_rate
        self.dt = self.n_substeps * self.physics_dt
        self.episode_seconds = _positive("episode_seconds", episode_seconds)
        self.max_steps = int(math.ceil(self.episode_seconds / self.dt - 1e-9))
        self.max_position_error = _positive("max_position_error", max_position_error)
        self.init_noise = float(init_noise)
        if not (math.isfinite(self.init_noise) and self.init_noise >= 0):
            raise ValueError(f"init_noise must be a finite number >= 0, got {init_noise!r}")
        sp = FAWT_HOVER_POINT_NED if setpoint is None else np.asarray(setpoint, dtype=float)
        if sp.shape != (3,) or not np.all(np.isfinite(sp)):
            raise ValueError(f"setpoint must be 3 finite NED coordinates, got {setpoint!r}")
        self.setpoint = sp.copy()
        self.reward_weights = dict(DEFAULT_REWARD_WEIGHTS)
        for key, value in (reward_weights or {}).items():
            if key not in DEFAULT_REWARD_WEIGHTS:
                raise ValueError(f"unknown reward weight {key!r}; valid: {list(DEFAULT_REWARD_WEIGHTS)}")
            if not (math.isfinite(float(value)) and float(value) >= 0):
                raise ValueError(f"reward weight {key!r} must be finite and >= 0, got {value!r}")
            self.reward_weights[key] = float(value)
        w = self.reward_weights
        # weights over the observation layout [e_b, v, R[:, 0], R[:, 1], Omega, action]; attitude enters via Phi
        self._reward_w = np.repeat([w["pos"], w["vel"], 0.0, w["rate"], w["action"]], [3, 3, 6, 3, 4])
        self._w_att = w["att"]
        self.action_type = action_type
        self.wind = make_wind(wind)
        self.aero = AeroModel(self.preset)
        self.sensor = SensorModel(make_sensor_spec(sensors), self.dt)
        self.render_mode = render_mode
        self._render_size = (int(render_height), int(render_width))
        self._renderer: mujoco.Renderer | None = None

        self.model = mujoco.MjModel.from_xml_string(vehicle_mjcf(self.preset, self.physics_dt, integrator,
                                                                 render_width, render_height))
        self.data = mujoco.MjData(self.model)
        self._body = self.model.body("vehicle").id
        self._hull_points_t = hull_points(self.preset).T  # (3, 12) body FRD
        self._alloc = allocation_matrix(self.preset)
        self._rotor_pos = self.preset.rotor_positions
        self._rate_loop = RateLoop(self.preset, self.physics_dt) if action_type == "ctbr" else None

        if action_type == "motors":
            self.action_space = spaces.Box(0.0, 1.0, shape=(4,), dtype=np.float32)
        else:
            self.action_space = spaces.Box(np.array([0, -1, -1, -1], dtype=np.float32),
                                           np.array([1, 1, 1, 1], dtype=np.float32), dtype=np.float32)
        lim = self.max_position_error + 1.0
        high = np.array([lim] * 3 + [30.0] * 3 + [1.0] * 6 + [40.0] * 3 + [1.0] * 4, dtype=np.float32)
        low = -high
        low[-4:] = self.action_space.low
        high[-4:] = self.action_space.high
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._external_force = np.zeros(3)
        self._external_torque = np.zeros(3)
        self._mat9 = np.zeros(9)
        self._obs_low = self.observation_space.low.astype(float)
        self._obs_high = self.observation_space.high.astype(float)
        self._act_low = self.action_space.low.astype(float)
        self._act_high = self.action_space.high.astype(float)
        self._act_low_list, self._act_high_list = self._act_low.tolist(), self._act_high.tolist()
        # exact motor lag sample times: mid-substep (thrust) and end of step (speed), negated for exp()
        step_times = np.append((np.arange(self.n_substeps) + 0.5) * self.physics_dt, self.dt)[:, None]
        sub_times = np.array([[0.5 * self.physics_dt], [self.physics_dt]])
        tau_up, tau_down = self.preset.tau_up, self.preset.tau_down
        self._step_decay = (np.exp(-step_times / tau_up), np.exp(-step_times / tau_down))
        self._substep_decay = (np.exp(-sub_times / tau_up), np.exp(-sub_times / tau_down))
        self._omega_min = self.preset.omega_min
        self._inv_substeps = 1.0 / self.n_substeps
        self._omega_span = self.preset.omega_max - self.preset.omega_min
        # views into MuJoCo's buffers (stable for the life of self.data)
        self._ctrl = self.data.ctrl
        self._ctrl4 = self.data.ctrl[0:4]
        self._xfrc = self.data.xfrc_applied[self._body]
        self.time = 0.0

    # ---- public helpers -------------------------------------------------------------------
    def set_external_wrench(self, force_ned: ArrayLike = (0.0, 0.0, 0.0),
                            torque_frd: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """A constant extra disturbance (force world NED [N], torque body FRD [N m]), added to the aero wrench."""
        f, t = np.asarray(force_ned, dtype=float), np.asarray(torque_frd, dtype=float)
        if f.shape != (3,) or t.shape != (3,) or not (np.all(np.isfinite(f)) and np.all(np.isfinite(t))):
            raise ValueError(f"external wrench must be two finite 3-vectors, got {force_ned!r}, {torque_frd!r}")
        self._external_force, self._external_torque = f.copy(), t.copy()

    def hover_action(self) -> NDArray[np.float32]:
        """The action that holds the weight at rest (equal rotors / level, zero rates)."""
        if self.action_type == "motors":
            return np.full(4, hover_command(self.preset), dtype=np.float32)
        return np.array([self.preset.mass * GRAVITY / (4 * self.preset.max_thrust_per_rotor), 0, 0, 0],
                        dtype=np.float32)

    # ---- state access ---------------------------------------------------------------------
    def _read_state(self) -> None:
        """Cache the true state (NED/FRD) from MuJoCo once per step (the one hot conversion)."""
        q, v = self.data.qpos, self.data.qvel
        mujoco.mju_quat2Mat(self._mat9, q[3:7])
        self._state = (q[0:3] * _SIGN, v[0:3] * _SIGN, self._mat9.reshape(3, 3) * _SIGN2, v[3:6] * _SIGN)

    def _set_state(self, position: NDArray, velocity: NDArray, rotation: NDArray, omega: NDArray) -> None:
        self.data.qpos[0:3] = vec_ned_to_mj(position)
        self.data.qpos[3:7] = rot_ned_to_quat_mj(rotation)
        self.data.qvel[0:3] = vec_ned_to_mj(velocity)
        self.data.qvel[3:6] = vec_ned_to_mj(omega)

    # ---- gym API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32], dict]:
        super().reset(seed=seed)
        if options:
            unknown = set(options) - {"setpoint", "init_noise"}
            if unknown:
                raise ValueError(f"unknown reset option(s) {sorted(unknown)}; valid: ['init_noise', 'setpoint']")
            if "setpoint" in options:
                sp = np.asarray(options["setpoint"], dtype=float)
                if sp.shape != (3,) or not np.all(np.isfinite(sp)):
                    raise ValueError(f"setpoint must be 3 finite NED coordinates, got {options['setpoint']!r}")
                self.setpoint = sp
            if "init_noise" in options:
                self.init_noise = float(options["init_noise"])
        rng = self.np_random
        mujoco.mj_resetData(self.model, self.data)
        s = self.init_noise
        u = lambda key, n=3: rng.uniform(-1.0, 1.0, n) * INIT_SPREAD[key] * s
        self._set_state(self.setpoint + u("position"), u("velocity"), exp_so3(u("attitude")), u("angular_velocity"))
        mujoco.mj_forward(self.model, self.data)
        self._read_state()
        self.rotor_speeds = np.full(4, self.preset.hover_omega)
        self._last_action = self.hover_action()
        self._step_count = 0
        self.time = 0.0
        self._wind_seed, self._sensor_seed = np.random.SeedSequence(int(rng.integers(2**63))).spawn(2)
        self.wind.reset(1, seed=self._wind_seed)
        self.sensor.reset(np.random.default_rng(self._sensor_seed))
        if self._rate_loop is not None:
            self._rate_loop.reset()
        self._applied_thrusts = self.preset.k_thrust * self.rotor_speeds**2
        self._accel = np.zeros(3)
        self._disturbance = self._compute_disturbance()
        self._failure = ""
        info = self._info(action_clipped=False)
        return self._observation_and_reward(info["measurement"], self._last_action)[0], info

    def _compute_disturbance(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        b, v, r, w = self._state
        points = np.empty((1, 5, 3))
        points[0, 0] = b
        points[0, 1:] = b + self._rotor_pos @ r.T
        wind = self.wind.step(self.time, self.dt, points, v[None])
        force, torque = self.aero.wrench(r[None], v[None], w[None], self.rotor_speeds[None], wind)
        return force[0] + self._external_force, torque[0] + self._external_torque, wind[0, 0]

    def step(self, action: ArrayLike) -> tuple[NDArray[np.float32], float, bool, bool, dict]:
        a = np.asarray(action, dtype=float).reshape(-1)
        if a.shape != (4,):
            raise ValueError(f"action must have 4 entries, got shape {np.shape(action)}")
        values = a.tolist()
        clipped_list = []
        for i, (x, lo, hi) in enumerate(zip(values, self._act_low_list, self._act_high_list, strict=True)):
            if not math.isfinite(x):
                raise ValueError(f"action[{i}] is {x}; every action entry must be finite "
                                 f"(bounds {self._act_low_list} .. {self._act_high_list})")
            clipped_list.append(lo if x < lo else hi if x > hi else x)
        action_clipped = clipped_list != values
        clipped = np.array(clipped_list)

        force, torque, _ = self._disturbance
        self._xfrc[0:3] = force * _SIGN
        self._ctrl[4:7] = torque * _SIGN
        if self.action_type == "motors":
            self._applied_thrusts = self._run_motors(clipped)
        else:
            self._applied_thrusts = self._run_ctbr(clipped)
        self.time += self.dt
        self._step_count += 1

        d = self.data
        warnings = d.warning.number
        if warnings[_BADQPOS] or warnings[_BADQVEL] or warnings[_BADQACC]:
            # MuJoCo found NaN/inf/huge values in qpos/qvel/qacc and reset its data (mj_checkPos/Vel/Acc):
            # keep the last finite state (self._state) for the observation; the episode ends here
            self._failure = "diverged"
        else:
            v_before = self._state[1]
            self._read_state()
            self._accel = (self._state[1] - v_before) / self.dt
            self._disturbance = self._compute_disturbance()
            b, _, r, _ = self._state
            if b[2] + (r[2] @ self._hull_points_t).max() >= 0.0:  # a hull/rotor point at or below the floor (z = 0)
                self._failure = "ground_contact"
            elif np.abs(self._state[0] - self.setpoint).max() > self.max_position_error:
                self._failure = "out_of_bounds"
        info = self._info(action_clipped)
        obs, reward = self._observation_and_reward(info["measurement"], clipped)
        self._last_action = clipped
        terminated = bool(self._failure)
        truncated = (not terminated) and self._step_count >= self.max_steps
        return obs, reward, terminated, truncated, info

    def _motor_lag(self, omega_ref: NDArray[np.float64], decay_up: NDArray[np.float64],
                   decay_down: NDArray[np.float64]) -> NDArray[np.float64]:
        """Exact speeds (K, 4) at K fixed times from the current speeds (see :mod:`.motors`).

        ``decay_up/down`` (K, 1) hold ``exp(-t_k / tau_up/down)``, precomputed: the time constant of each
        rotor is fixed over the interval because the speed approaches its held reference monotonically.
        """
        w0 = self.rotor_speeds
        decay = np.where(omega_ref > w0, decay_up, decay_down)
        return omega_ref + (w0 - omega_ref) * decay

    def _run_motors(self, u: NDArray[np.float64]) -> NDArray[np.float64]:
        """Exact motor lag over the control step; rotor thrust per substep from the mid-substep speed."""
        speeds = self._motor_lag(u * self._omega_span + self._omega_min, *self._step_decay)
        thrusts = speeds[:-1] ** 2 * self.preset.k_thrust
        ctrl4, m, d, step = self._ctrl4, self.model, self.data, mujoco.mj_step
        for row in thrusts:
            ctrl4[:] = row
            step(m, d)
        self.rotor_speeds = speeds[-1]
        return thrusts.sum(axis=0) * self._inv_substeps  # (np.mean costs ~10 us here)

    def _run_ctbr(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        p = self.preset
        collective = a[0] * 4.0 * p.max_thrust_per_rotor
        rate_sp = a[1:] * MAX_RATES
        total = np.zeros(4)
        for _ in range(self.n_substeps):
            omega = self.data.qvel[3:6] * _SIGN
            t_cmd = self._rate_loop.rotor_thrusts(collective, rate_sp, omega)
            omega_ref = np.sqrt(t_cmd / p.k_thrust)
            mid, end = self._motor_lag(omega_ref, *self._substep_decay)
            thrust = p.k_thrust * mid**2
            self.data.ctrl[0:4] = thrust
            mujoco.mj_step(self.model, self.data)
            self.rotor_speeds = end
            total += thrust
        return total / self.n_substeps

    def _info(self, action_clipped: bool) -> dict[str, Any]:
        b, v, r, w = self._state
        meas = self.sensor.measure(self.time, b, v, r, w, self._accel)
        f_torque = self._alloc @ self._applied_thrusts
        force, torque, wind = self._disturbance
        return {
            "measurement": meas,
            "applied": {"thrust": f_torque[0], "torque": f_torque[1:],
                        "rotor_thrusts": self._applied_thrusts, "motor_speeds": self.rotor_speeds},
            # the state arrays and the wrench are fresh every step (see _read_state/_compute_disturbance)
            "truth": {M.POSITION: b, M.VELOCITY: v, M.ATTITUDE: r, M.ANGULAR_VELOCITY: w,
                      "wind": wind.copy(), "force": force, "torque": torque},
            "setpoint": self.setpoint.copy(),
            "action_clipped": action_clipped,
            "failure": self._failure,
            "time": self.time,
        }

    def _observation_and_reward(self, meas: Mapping[str, NDArray[np.float64]],
                                action: NDArray[np.float64]) -> tuple[NDArray[np.float32], float]:
        """The observation (with ``action``, the action just applied) and the reward, from one vector."""
        r = meas[M.ATTITUDE]
        x = np.concatenate([meas[M.POSITION] - self.setpoint, meas[M.VELOCITY], r[:, 0], r[:, 1],
                            meas[M.ANGULAR_VELOCITY], action])
        obs = np.minimum(np.maximum(x, self._obs_low), self._obs_high).astype(np.float32)  # (faster than clip)
        if self._failure:
            return obs, -self.reward_weights["failure"]
        phi = math.acos(min(1.0, max(-1.0, 0.5 * (r[0, 0] + r[1, 1] + r[2, 2] - 1.0))))
        x[15:] -= self._last_action  # the action-rate term
        return obs, math.exp(-(float(self._reward_w @ (x * x)) + self._w_att * phi * phi))

    # ---- rendering ----------------------------------------------------------------------
    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array' to gym.make")
            return None
        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.model, *self._render_size)
            self._camera = mujoco.MjvCamera()
            self._camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            self._camera.trackbodyid = self._body
            self._camera.distance = 2.5
            self._camera.azimuth = 120.0
            self._camera.elevation = -20.0
        self._renderer.update_scene(self.data, camera=self._camera)
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
