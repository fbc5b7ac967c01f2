"""``fawtgym/Hover-v0``: a quadrotor hovering at a set point, by default 1.5 m in front of a fan array.

## Description

A quad X (default the s500 of Wang et al. 2024, Sec. 7) hovers at a set point in world NED while
wind pushes it: still air, the turbulent jet of the fan-array wind tunnel (FAWT) of Wang et al.
(2024), Table 3, with the fan switched on and off on a schedule, MIL-F-8785C Dryden gusts, or a
discrete gust.  The agent commands four motors (like PX4's actuator outputs) or collective thrust
and body rates.  What it observes comes from modelled sensors (motion capture and an IMU, or exact
state); the truth (state, wind, disturbance force and torque) is in ``info["truth"]`` for metrics
only.  Frames: world NED, body FRD, SI units; rotation matrices map body to world.

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

## Action space

``action_type="motors"`` (default): ``Box(0, 1, (4,), float32)``.

| index | action | unit |
| --- | --- | --- |
| 0-3 | rotor i speed command, 0 = idle, 1 = maximum (PX4 actuator output order) | -- |

``action_type="ctbr"``: ``Box([0, -1, -1, -1], [1, 1, 1, 1], (4,), float32)``.

| index | action | unit |
| --- | --- | --- |
| 0 | collective thrust, fraction of the maximum (4 rotors at full speed) | -- |
| 1-3 | body rate set points p, q, r (FRD), fractions of (220, 220, 200) deg/s | -- |

``env.unwrapped.hover_action()`` is the action that holds a level hover in still air.

## Observation space

``Box(float32, (19,))``, from *measurements* (never the truth), clipped to the box (one law for this env, the
batch env and ``fawtgym replay``: :func:`fawtgym.envs.observation.hover_observation`):

| index | observation | unit | bound |
| --- | --- | --- | --- |
| 0-2 | position error b^m - b_sp (NED) | m | +- (max_position_error + 1) |
| 3-5 | velocity v^m (NED) | m/s | +- 30 |
| 6-11 | columns 1 and 2 of the attitude R^m (body -> NED; Zhou et al. 2019) | -- | +- 1 |
| 12-14 | body rate Omega^m (FRD) | rad/s | +- 40 |
| 15-18 | the action just applied (at reset: the hover action) | -- | the action space |

## Rewards

Dense and bounded: ``reward = exp(-(pos + vel + att + rate + action))`` in (0, 1] on a normal step,
``-failure`` (default -1) on the step that ends the episode by a failure.  The terms, computed on
measurements, are reported in ``info["reward_terms"]`` (weights: ``reward_weights``, defaults in
:data:`DEFAULT_REWARD_WEIGHTS`):

| term | value | default weight |
| --- | --- | --- |
| ``pos`` | w_pos e.e, e = b^m - b_sp the position error | 2.0 |
| ``vel`` | w_vel v^m.v^m | 0.2 |
| ``att`` | w_att Phi^2, Phi the angle of R^m from the hover attitude (tilt and yaw) | 1.0 |
| ``rate`` | w_rate Omega^m.Omega^m | 0.05 |
| ``action`` | w_action (u - u_prev).(u - u_prev), the change of the action | 0.5 |
| ``failure`` | w_failure on a failure step, else 0 | 1.0 |

## Starting state

The set point (default the FAWT hover point, 1.5 m in front of the fan array, 1.5 m above the
floor), hovering: rotors at hover speed, plus independent uniform perturbations scaled by
``init_noise`` (default 1): position +- 0.1 m, velocity +- 0.1 m/s, tilt (a rotation vector)
+- 3 deg per axis, body rate +- 0.1 rad/s.  ``init_noise=0`` starts exactly at the set point.
``reset(options={"setpoint": ..., "init_noise": ...})`` changes either for the episode and after.

## Episode end

Termination (``info["failure"]`` names the rule): ``"ground_contact"`` (a hull corner or rotor hub
at or below the floor, z_NED >= 0), ``"out_of_bounds"`` (``|b_i - b_sp,i| > max_position_error`` on
any NED axis, default 2 m) or ``"diverged"`` (a non-finite state).  Truncation: at
``episode_seconds`` (default 10 s).

## Info

``"measurement"`` (what the sensors give: position, velocity, attitude, body rate, specific force,
gyro, magnetometer, time), ``"applied"`` (the known inputs: mean collective rotor thrust [N] and rotor
torque [N m] over the step just taken, rotor thrusts and speeds), ``"truth"`` (true state, wind at the
CoM, disturbance force NED and torque FRD exactly as applied; for metrics only), ``"reward_terms"``,
``"setpoint"`` (the NED position set point, a command), ``"action_clipped"``, ``"failure"`` and
``"time"``.

## Arguments

``gym.make("fawtgym/Hover-v0", **kwargs)``; ``fawtgym/HoverFAWT<duty>-v0`` (duty 30, 40, 50, 60, 70)
is the same with ``wind="fawt-<duty>"``.  ``gym.make_vec(..., num_envs=N)`` gives
:class:`fawtgym.envs.hover_batch_env.HoverBatchEnv` with the same arguments.  A bad value raises a
one-line ``ValueError`` naming it and what is allowed.

| argument | default | meaning |
| --- | --- | --- |
| ``vehicle`` | ``"s500"`` | ``s500``, ``pounds_x4``, ``shi_geso``, ``hummingbird``, ``x500``, or a preset/file |
| ``wind`` | ``"calm"`` | wind name, ``{"name": ..., **options}`` (e.g. ``on_time``) or a ``WindModel`` |
| ``action_type`` | ``"motors"`` | ``"motors"`` or ``"ctbr"`` (tables above) |
| ``sensors`` | ``"none"`` | ``"none"`` (exact), ``"seed000"`` (Wang et al. 2024, Table 2 noise), ``"mocap_imu"`` |
| ``control_rate`` | 100.0 | agent rate [Hz]; must divide ``physics_rate`` |
| ``physics_rate`` | 1000.0 | MuJoCo rate [Hz] |
| ``episode_seconds`` | 10.0 | truncation time [s] |
| ``setpoint`` | FAWT hover point | NED position [m] |
| ``init_noise`` | 1.0 | scale of the starting-state perturbation |
| ``reward_weights`` | table above | overrides of any weight |
| ``max_position_error`` | 2.0 | half-size of the termination box [m] |
| ``integrator`` | ``"Euler"`` | MuJoCo integrator: ``Euler``, ``RK4``, ``implicit``, ``implicitfast`` |
| ``render_mode`` | None | ``"rgb_array"`` only (``"human"`` is refused); see :mod:`fawtgym.envs.render` |
| ``render_width``, ``render_height`` | 480, 480 | frame size [px] |

## Rendering

``render()`` returns an RGB frame of the vehicle in front of the fan array with the wind and a
height cue (:mod:`fawtgym.envs.render`); ``metadata["render_fps"]`` is the control rate, so
``gymnasium.wrappers.RecordVideo`` plays in real time.  Headless: ``MUJOCO_GL=egl`` (set by
``import fawtgym`` when no display is present) or ``osmesa``.

## Version history

* v0 (fawtgym 0.1): first release.  Within v0: the observation carries the action just applied (not
  the one before); the disturbance wrench enters through the free joint (same trajectories to 5e-14);
  ``info["reward_terms"]``; ``render_fps`` follows the control rate and the frame shows the fan array.

``"mocap_imu"`` sensors: motion-capture pose at 100 Hz (0.5 mm, 0.1 deg) and an IMU with turn-on
biases, as the VICON-fed PX4 of Wang et al. (2024), Sec. 7 (:mod:`fawtgym.envs.sensors`).
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

from fawtgym.core import measurement as M
from fawtgym.core.frames import FAWT_HOVER_POINT_NED, rot_ned_to_quat_mj, vec_ned_to_mj
from fawtgym.core.so3 import exp_so3

from .aero import AeroModel
from .ctbr import MAX_RATES, RateLoop
from .mjcf import INTEGRATORS, hull_points, vehicle_mjcf
from .motors import allocation_matrix, hover_command
from .observation import hover_observation, observation_bounds
from .render import HoverRenderer
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


def check_init_noise(value: Any) -> float:
    """``init_noise`` as a float; ValueError naming it unless a finite number >= 0 (shared with the batch env)."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"init_noise must be a finite number >= 0, got {value!r}") from exc
    if not (math.isfinite(v) and v >= 0):
        raise ValueError(f"init_noise must be a finite number >= 0, got {value!r}")
    return v


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
        setpoint: hover set point, world NED (default: the FAWT hover point of Wang et al. 2024, Sec. 7.3).
        init_noise: scale of the random initial perturbation (0: start exactly hovering at the set point).
        reward_weights: overrides of :data:`DEFAULT_REWARD_WEIGHTS`.
        max_position_error: half-size of the termination box [m].
        integrator: MuJoCo integrator name.
        render_mode: ``None`` or ``"rgb_array"`` (headless via MUJOCO_GL=egl, set by default).
    """

    @property
    def metadata(self) -> dict[str, Any]:  # type: ignore[override]
        """``render_modes`` and ``render_fps``: one frame per control step, so a video plays in real time.

        An instance property (not a class dict) so that the frame rate follows this env's control
        rate, and so that ``gym.make(..., render_mode="human")`` reaches this env's own one-line error
        instead of Gymnasium's pygame wrapper.
        """
        return {"render_modes": list(RENDER_MODES), "render_fps": self._render_fps}

    @metadata.setter
    def metadata(self, value: dict[str, Any]) -> None:
        self._render_fps = value.get("render_fps", getattr(self, "_render_fps", None))

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
        if render_mode == "human":
            raise ValueError("render_mode 'human' is not supported: fawtgym renders off screen only; valid: None, "
                             "'rgb_array' (record a video with gymnasium.wrappers.RecordVideo)")
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
        self._render_fps = 1.0 / self.dt
        self.episode_seconds = _positive("episode_seconds", episode_seconds)
        self.max_steps = int(math.ceil(self.episode_seconds / self.dt - 1e-9))
        self.max_position_error = _positive("max_position_error", max_position_error)
        self.init_noise = check_init_noise(init_noise)
        self.setpoint = FAWT_HOVER_POINT_NED if setpoint is None else setpoint
        self.reward_weights = dict(DEFAULT_REWARD_WEIGHTS)
        for key, value in (reward_weights or {}).items():
            if key not in DEFAULT_REWARD_WEIGHTS:
                raise ValueError(f"unknown reward weight {key!r}; valid: {list(DEFAULT_REWARD_WEIGHTS)}")
            if not (math.isfinite(float(value)) and float(value) >= 0):
                raise ValueError(f"reward weight {key!r} must be finite and >= 0, got {value!r}")
            self.reward_weights[key] = float(value)
        w = self.reward_weights
        self._w_att = w["att"]
        self.action_type = action_type
        self.wind = make_wind(wind)
        self.aero = AeroModel(self.preset)
        self.sensor = SensorModel(make_sensor_spec(sensors), self.dt, self.physics_dt)
        self.render_mode = render_mode
        self._render_size = (int(render_height), int(render_width))
        self._renderer: HoverRenderer | None = None

        self.model = mujoco.MjModel.from_xml_string(vehicle_mjcf(self.preset, self.physics_dt, integrator,
                                                                 render_width, render_height))
        self.data = mujoco.MjData(self.model)
        self._body = self.model.body("vehicle").id
        self._rate_loop = RateLoop(self.preset, self.physics_dt) if action_type == "ctbr" else None

        if action_type == "motors":
            self.action_space = spaces.Box(0.0, 1.0, shape=(4,), dtype=np.float32)
        else:
            self.action_space = spaces.Box(np.array([0, -1, -1, -1], dtype=np.float32),
                                           np.array([1, 1, 1, 1], dtype=np.float32), dtype=np.float32)
        low, high = observation_bounds(self.max_position_error, self.action_space.low, self.action_space.high)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._external_force = [0.0, 0.0, 0.0]
        self._external_torque = [0.0, 0.0, 0.0]
        self._act_low_list = self.action_space.low.astype(float).tolist()
        self._act_high_list = self.action_space.high.astype(float).tolist()
        # exact motor lag (see _run_motors): decay factors exp(-t / tau) at the mid-substep times (thrust) and at
        # the end of the step (speed), one table per combination of rotors speeding up (bit i set) or slowing down
        n = self.n_substeps
        step_times = np.append((np.arange(n) + 0.5) * self.physics_dt, self.dt)
        sub_times = np.array([0.5 * self.physics_dt, self.physics_dt])
        tau_up, tau_down = self.preset.tau_up, self.preset.tau_down
        up, down = np.exp(-step_times / tau_up), np.exp(-step_times / tau_down)
        self._decay_tables = [[tuple(row) for row in np.stack([up if (combo >> i) & 1 else down for i in range(4)],
                                                              axis=1)[:-1].tolist()]
                              for combo in range(16)]  # n substeps x 4 rotors each
        self._decay_end = (float(up[-1]), float(down[-1]))
        self._decay_mean = (float(up[:-1].mean()), float(down[:-1].mean()))  # mean decay over the substeps
        self._decay_mean2 = (float((up[:-1] ** 2).mean()), float((down[:-1] ** 2).mean()))  # ... squared
        self._substep_decay = tuple(tuple(np.exp(-sub_times / tau).tolist()) for tau in (tau_up, tau_down))
        self._max_collective = 4.0 * self.preset.max_thrust_per_rotor
        self._max_rates = MAX_RATES.tolist()
        self._omega_min = self.preset.omega_min
        self._omega_span = self.preset.omega_max - self.preset.omega_min
        self._k_thrust = float(self.preset.k_thrust)
        self._alloc_rows = allocation_matrix(self.preset).tolist()
        hull = hull_points(self.preset)
        self._hull = [tuple(p) for p in hull.tolist()]
        self._hull_radius = float(np.linalg.norm(hull, axis=1).max())
        self._obs_low, self._obs_high = low.astype(float), high.astype(float)
        self._reward_terms = (w["pos"], w["vel"], w["action"], w["rate"])
        self._rotor_offsets = self.preset.rotor_positions.tolist()
        self._bind_views()
        self.time = 0.0

    def _bind_views(self) -> None:
        """Views into MuJoCo's buffers (stable for the life of ``self.data``; item assignment through a memoryview
        costs a quarter of a numpy slice assignment)."""
        self._ctrl_mv = memoryview(self.data.ctrl)
        self._qfrc_mv = memoryview(self.data.qfrc_applied)  # free joint: world force at the CoM, body torque
        self._warnings = self.data.warning.number
        self._qpos, self._qvel = self.data.qpos, self.data.qvel

    def __getstate__(self) -> dict[str, Any]:
        """Pickle/deepcopy: MuJoCo's model and data are copied, the views into them rebuilt on load."""
        state = self.__dict__.copy()
        for key in ("_ctrl_mv", "_qfrc_mv", "_warnings", "_qpos", "_qvel"):
            state.pop(key, None)
        state["_renderer"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind_views()

    # ---- public helpers -------------------------------------------------------------------
    def set_external_wrench(self, force_ned: ArrayLike = (0.0, 0.0, 0.0),
                            torque_frd: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """A constant extra disturbance (force world NED [N], torque body FRD [N m]) added to the aero wrench from the
        next step on (and reported in ``info["truth"]``)."""
        f, t = np.asarray(force_ned, dtype=float), np.asarray(torque_frd, dtype=float)
        if f.shape != (3,) or t.shape != (3,) or not (np.all(np.isfinite(f)) and np.all(np.isfinite(t))):
            raise ValueError(f"external wrench must be two finite 3-vectors, got {force_ned!r}, {torque_frd!r}")
        self._external_force, self._external_torque = f.tolist(), t.tolist()

    def hover_action(self) -> NDArray[np.float32]:
        """The action that holds the weight at rest (equal rotors / level, zero rates)."""
        if self.action_type == "motors":
            return np.full(4, hover_command(self.preset), dtype=np.float32)
        return np.array([self.preset.mass * GRAVITY / (4 * self.preset.max_thrust_per_rotor), 0, 0, 0],
                        dtype=np.float32)

    @property
    def setpoint(self) -> NDArray[np.float64]:
        """Hover set point, world NED [m] (3,); assign a new one any time (validated)."""
        return self._setpoint_array

    @setpoint.setter
    def setpoint(self, value: ArrayLike) -> None:
        sp = np.array(value, dtype=float)
        if sp.shape != (3,) or not np.all(np.isfinite(sp)):
            raise ValueError(f"setpoint must be 3 finite NED coordinates, got {value!r}")
        self._setpoint_array = sp

    @property
    def rotor_speeds(self) -> NDArray[np.float64]:
        """Rotor speeds [rad/s] at the end of the last step (4,)."""
        return np.array(self._speeds)

    # ---- state access ---------------------------------------------------------------------
    def _read_state(self) -> None:
        """The true state (NED/FRD) from MuJoCo as floats: position, velocity, R (row-major 9), Omega.

        MuJoCo is z-up with an FLU body: NED = diag(1, -1, -1) MuJoCo for vectors, and R_NED = S R_MuJoCo S
        with S = diag(1, -1, -1); R_MuJoCo from the unit quaternion as in ``mju_quat2Mat``.
        """
        x, y, z, qw, qx, qy, qz = self._qpos.tolist()
        vx, vy, vz, wx, wy, wz = self._qvel.tolist()
        q00, q11, q22, q33 = qw * qw, qx * qx, qy * qy, qz * qz
        q01, q02, q03, q12, q13, q23 = qw * qx, qw * qy, qw * qz, qx * qy, qx * qz, qy * qz
        self._b, self._v, self._w = [x, -y, -z], [vx, -vy, -vz], [wx, -wy, -wz]
        self._r = [q00 + q11 - q22 - q33, -2.0 * (q12 - q03), -2.0 * (q13 + q02),
                   -2.0 * (q12 + q03), q00 - q11 + q22 - q33, 2.0 * (q23 - q01),
                   -2.0 * (q13 - q02), 2.0 * (q23 + q01), q00 - q11 - q22 + q33]

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
                self.setpoint = options["setpoint"]
            if "init_noise" in options:
                self.init_noise = check_init_noise(options["init_noise"])
        rng = self.np_random
        mujoco.mj_resetData(self.model, self.data)
        s = self.init_noise
        u = lambda key, n=3: rng.uniform(-1.0, 1.0, n) * INIT_SPREAD[key] * s
        self._set_state(self.setpoint + u("position"), u("velocity"), exp_so3(u("attitude")), u("angular_velocity"))
        mujoco.mj_forward(self.model, self.data)
        self._read_state()
        self._speeds = [float(self.preset.hover_omega)] * 4
        self._last_action = self.hover_action().tolist()
        self._step_count = 0
        self.time = 0.0
        self._wind_seed, self._sensor_seed = np.random.SeedSequence(int(rng.integers(2**63))).spawn(2)
        self.wind.reset(1, seed=self._wind_seed)
        self.sensor.reset(np.random.default_rng(self._sensor_seed))
        if self._rate_loop is not None:
            self._rate_loop.reset()
        self._applied_thrusts = [self._k_thrust * w * w for w in self._speeds]
        self._accel = [0.0, 0.0, 0.0]
        self._disturbance = self._compute_disturbance()
        self._failure = ""
        return self._outputs(self._last_action, False)

    def _compute_disturbance(self) -> tuple[list[float], list[float], list[float]]:
        """Wind at [CoM, rotor hubs] and the aero wrench, held over the next step (the user's external wrench is
        added where the wrench is applied and reported, so a new one acts from the next step on)."""
        b, r = self._b, self._r
        bx, by, bz = b
        points = [bx, by, bz]
        for px, py, pz in self._rotor_offsets:  # hub positions b + R r_i
            points += (bx + r[0] * px + r[1] * py + r[2] * pz, by + r[3] * px + r[4] * py + r[5] * pz,
                       bz + r[6] * px + r[7] * py + r[8] * pz)
        v = np.array([self._v])
        wind = self.wind.step(self.time, self.dt, np.array(points).reshape(1, -1, 3), v)
        force, torque = self.aero.wrench(np.array(r).reshape(1, 3, 3), v, np.array([self._w]),
                                         np.array([self._speeds]), wind)
        return force[0].tolist(), torque[0].tolist(), wind[0, 0].tolist()

    def step(self, action: ArrayLike) -> tuple[NDArray[np.float32], float, bool, bool, dict]:
        if type(action) is np.ndarray and action.shape == (4,) and action.dtype.kind == "f":
            values = action.tolist()
        else:
            a = np.asarray(action, dtype=float).reshape(-1)
            if a.shape != (4,):
                raise ValueError(f"action must have 4 entries, got shape {np.shape(action)}")
            values = a.tolist()
        (x0, x1, x2, x3), (l0, l1, l2, l3), (h0, h1, h2, h3) = values, self._act_low_list, self._act_high_list
        if l0 <= x0 <= h0 and l1 <= x1 <= h1 and l2 <= x2 <= h2 and l3 <= x3 <= h3:  # (False for NaN)
            clipped, action_clipped = values, False
        else:
            clipped = []
            for i, (x, lo, hi) in enumerate(zip(values, self._act_low_list, self._act_high_list, strict=True)):
                if not math.isfinite(x):
                    raise ValueError(f"action[{i}] is {x}; every action entry must be finite "
                                     f"(bounds {self._act_low_list} .. {self._act_high_list})")
                clipped.append(lo if x < lo else hi if x > hi else x)
            action_clipped = clipped != values

        (fx, fy, fz), (tx, ty, tz) = self._held_wrench()  # NED/FRD -> MuJoCo world z-up / body FLU
        qfrc = self._qfrc_mv  # see envs/mjcf.py: the free joint's generalized force is exactly this wrench
        qfrc[0], qfrc[1], qfrc[2], qfrc[3], qfrc[4], qfrc[5] = fx, -fy, -fz, tx, -ty, -tz
        if self.action_type == "motors":
            self._applied_thrusts = self._run_motors(clipped)
        else:
            self._applied_thrusts = self._run_ctbr(clipped)
        self.time += self.dt
        self._step_count += 1

        warnings = self._warnings
        if warnings[_BADQPOS] or warnings[_BADQVEL] or warnings[_BADQACC]:
            # MuJoCo found NaN/inf/huge values in qpos/qvel/qacc and reset its data (mj_checkPos/Vel/Acc):
            # keep the last finite state for the observation; the episode ends here
            self._failure = "diverged"
        else:
            v0 = self._v
            self._read_state()
            v1, inv_dt = self._v, 1.0 / self.dt
            self._accel = [(v1[0] - v0[0]) * inv_dt, (v1[1] - v0[1]) * inv_dt, (v1[2] - v0[2]) * inv_dt]
            self._disturbance = self._compute_disturbance()
            b, sp = self._b, self.setpoint.tolist()  # (a public attribute users may change)
            if b[2] + self._hull_radius >= 0.0 and self._touches_ground():
                self._failure = "ground_contact"
            elif max(abs(b[0] - sp[0]), abs(b[1] - sp[1]), abs(b[2] - sp[2])) > self.max_position_error:
                self._failure = "out_of_bounds"
        obs, info = self._outputs(clipped, action_clipped)
        reward = self._reward
        self._last_action = clipped
        terminated = bool(self._failure)
        truncated = (not terminated) and self._step_count >= self.max_steps
        return obs, reward, terminated, truncated, info

    def _held_wrench(self) -> tuple[list[float], list[float]]:
        """Aero + external wrench (force NED, torque FRD) held over the next step, as applied and reported."""
        (ax, ay, az), (bx, by, bz), _ = self._disturbance
        (fx, fy, fz), (tx, ty, tz) = self._external_force, self._external_torque
        return [ax + fx, ay + fy, az + fz], [bx + tx, by + ty, bz + tz]

    def _touches_ground(self) -> bool:
        """A hull corner or rotor hub at or below the floor (z_NED >= 0)."""
        bz, (r20, r21, r22) = self._b[2], self._r[6:9]
        return any(bz + r20 * px + r21 * py + r22 * pz >= 0.0 for px, py, pz in self._hull)

    def _run_motors(self, u: list[float]) -> list[float]:
        """Exact first-order motor lag over the control step (see :mod:`.motors`); returns the mean rotor thrusts.

        With the reference ``c`` held, a rotor's speed ``w(t) = c + (w0 - c) exp(-t / tau)`` approaches ``c``
        monotonically, so its time constant (up or down) is fixed over the step.  The thrust of physics substep k
        is ``k_T w(t_k)^2`` at the mid-substep time ``t_k``; its mean over the step is, in closed form,
        ``k_T (c^2 + 2 c (w0 - c) <e> + (w0 - c)^2 <e^2>)`` with ``<e>``, ``<e^2>`` the mean decay factors.
        """
        span, w_min, w0 = self._omega_span, self._omega_min, self._speeds
        c = [x * span + w_min for x in u]
        combo = (c[0] > w0[0]) + 2 * (c[1] > w0[1]) + 4 * (c[2] > w0[2]) + 8 * (c[3] > w0[3])
        d = [w0[0] - c[0], w0[1] - c[1], w0[2] - c[2], w0[3] - c[3]]
        k = self._k_thrust
        c0, c1, c2, c3 = c
        d0, d1, d2, d3 = d
        ctrl, m, data, step = self._ctrl_mv, self.model, self.data, mujoco.mj_step
        for e0, e1, e2, e3 in self._decay_tables[combo]:  # speeds at the substep midpoints -> rotor thrusts
            w0_, w1_, w2_, w3_ = c0 + d0 * e0, c1 + d1 * e1, c2 + d2 * e2, c3 + d3 * e3
            ctrl[0], ctrl[1], ctrl[2], ctrl[3] = k * w0_ * w0_, k * w1_ * w1_, k * w2_ * w2_, k * w3_ * w3_
            step(m, data)
        end, mean, mean2 = self._decay_end, self._decay_mean, self._decay_mean2
        speeds, thrusts = [], []
        for i in range(4):
            j = 0 if (combo >> i) & 1 else 1  # the tables hold (speeding up, slowing down)
            ci, di = c[i], d[i]
            speeds.append(ci + di * end[j])
            thrusts.append(k * (ci * ci + 2.0 * ci * di * mean[j] + di * di * mean2[j]))
        self._speeds = speeds
        return thrusts

    def _run_ctbr(self, a: list[float]) -> list[float]:
        """The inner rate loop (:mod:`.ctbr`) and the exact motor lag at the physics rate; mean rotor thrusts."""
        collective = a[0] * self._max_collective
        rate_sp = [a[1] * self._max_rates[0], a[2] * self._max_rates[1], a[3] * self._max_rates[2]]
        (up_mid, up_end), (down_mid, down_end) = self._substep_decay
        k, inv_k, speeds, total = self._k_thrust, 1.0 / self._k_thrust, list(self._speeds), [0.0, 0.0, 0.0, 0.0]
        loop, qvel, ctrl, m, data = self._rate_loop, self._qvel, self._ctrl_mv, self.model, self.data
        step = mujoco.mj_step
        for _ in range(self.n_substeps):
            _, _, _, wx, wy, wz = qvel.tolist()
            t_cmd = loop.rotor_thrusts_floats(collective, rate_sp, [wx, -wy, -wz])
            for i in range(4):
                ref, w0 = math.sqrt(t_cmd[i] * inv_k), speeds[i]
                mid_decay, end_decay = (up_mid, up_end) if ref > w0 else (down_mid, down_end)
                mid = ref + (w0 - ref) * mid_decay
                thrust = k * mid * mid
                ctrl[i] = thrust
                total[i] += thrust
                speeds[i] = ref + (w0 - ref) * end_decay
            step(m, data)
        self._speeds = speeds
        return [t / self.n_substeps for t in total]

    def _outputs(self, action: list[float], action_clipped: bool) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Measurement -> observation (with ``action``, the action just applied), reward (kept in ``self._reward``)
        and info, in float arithmetic (numpy only for the arrays handed out)."""
        b, v, r, w = self._b, self._v, self._r, self._w
        meas = self.sensor.measure(self.time, np.array(b), np.array(v), np.array(r).reshape(3, 3), np.array(w),
                                   np.array(self._accel))
        lists = tuple(meas[key].ravel().tolist() for key in (M.POSITION, M.VELOCITY, M.ATTITUDE, M.ANGULAR_VELOCITY,
                                                              M.SPECIFIC_FORCE, M.GYRO, M.MAGNETOMETER))
        pos, vel, att, rate = lists[0], lists[1], lists[2], lists[3]
        sp = self.setpoint.tolist()
        e = [pos[0] - sp[0], pos[1] - sp[1], pos[2] - sp[2], *vel, *rate]
        cos_phi = 0.5 * (att[0] + att[4] + att[8] - 1.0)
        phi = math.acos(1.0 if cos_phi > 1.0 else -1.0 if cos_phi < -1.0 else cos_phi)
        last = self._last_action
        da = [action[0] - last[0], action[1] - last[1], action[2] - last[2], action[3] - last[3]]
        wp, wv, wa, ww = self._reward_terms
        t_pos = wp * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        t_vel = wv * (e[3] * e[3] + e[4] * e[4] + e[5] * e[5])
        t_rate = ww * (e[6] * e[6] + e[7] * e[7] + e[8] * e[8])
        t_action = wa * (da[0] * da[0] + da[1] * da[1] + da[2] * da[2] + da[3] * da[3])
        t_att = self._w_att * phi * phi
        t_failure = self.reward_weights["failure"] if self._failure else 0.0
        self._reward = -t_failure if self._failure else math.exp(-(t_pos + t_vel + t_rate + t_action + t_att))
        t_rot = self._applied_thrusts
        (a0, a1, a2, a3), wind = self._alloc_rows, self._disturbance[2]
        force, torque = self._held_wrench()
        wrench = [row[0] * t_rot[0] + row[1] * t_rot[1] + row[2] * t_rot[2] + row[3] * t_rot[3]
                  for row in (a0, a1, a2, a3)]
        # every array handed out is a disjoint view of one fresh buffer (one conversion instead of twenty)
        f = np.array([*pos, *vel, *att, *rate, *lists[4], *lists[5], *lists[6], *wrench[1:], *t_rot, *self._speeds,
                      *b, *v, *r, *w, *wind, *force, *torque, *sp, self.time])
        rows = f[None]  # the observation law is batch-first: this env is a batch of one
        obs = hover_observation({M.POSITION: rows[:, 0:3], M.VELOCITY: rows[:, 3:6],
                                 M.ATTITUDE: rows[:, 6:15].reshape(1, 3, 3), M.ANGULAR_VELOCITY: rows[:, 15:18]},
                                rows[:, 65:68], [action], self._obs_low, self._obs_high)[0]
        info = {
            "measurement": {M.POSITION: f[0:3], M.VELOCITY: f[3:6], M.ATTITUDE: f[6:15].reshape(3, 3),
                            M.ANGULAR_VELOCITY: f[15:18], M.SPECIFIC_FORCE: f[18:21], M.GYRO: f[21:24],
                            M.MAGNETOMETER: f[24:27], M.TIME: f[68, ...]},
            "applied": {"thrust": wrench[0], "torque": f[27:30], "rotor_thrusts": f[30:34], "motor_speeds": f[34:38]},
            "truth": {M.POSITION: f[38:41], M.VELOCITY: f[41:44], M.ATTITUDE: f[44:53].reshape(3, 3),
                      M.ANGULAR_VELOCITY: f[53:56], "wind": f[56:59], "force": f[59:62], "torque": f[62:65]},
            "reward_terms": {"pos": t_pos, "vel": t_vel, "att": t_att, "rate": t_rate, "action": t_action,
                             "failure": t_failure},
            "setpoint": f[65:68],
            "action_clipped": action_clipped,
            "failure": self._failure,
            "time": self.time,
        }
        return obs, info

    # ---- rendering ----------------------------------------------------------------------
    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array' to gym.make")
            return None
        if self._renderer is None:
            height, width = self._render_size
            self._renderer = HoverRenderer(self.model, width, height, self._body)
        wind = getattr(self, "_disturbance", (None, None, (0.0, 0.0, 0.0)))[2]  # before the first reset: still air
        return self._renderer.render(self.data, self.setpoint, np.asarray(wind, dtype=float))

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
