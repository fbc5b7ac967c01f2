"""``fawtgym/Hover-v0``: a quadrotor hovering at a set point, by default 1.5 m in front of a fan array.

## Description

A quad X (default the s500 of Wang et al. 2024, Sec. 7) hovers at a set point in world NED while
wind pushes it: still air, the turbulent jet of the fan-array wind tunnel (FAWT) of Wang et al.
(2024), Table 3, with the fan switched on and off on a schedule, MIL-F-8785C Dryden gusts, or a
discrete gust.  The agent commands four motors (like PX4's actuator outputs) or collective thrust
and body rates.  What it observes comes from modelled sensors (motion capture and an IMU, or exact
state); the truth (state, wind, disturbance force and torque) is in ``info["truth"]`` for metrics
only.  Frames: world NED, body FRD, SI units; rotation matrices map body to world.

This env is :class:`fawtgym.envs.hover_batch_env.HoverBatchEnv` at N = 1 (one step law, one reward, one
observation builder), with Gymnasium's single-env API: unbatched arrays and no autoreset.

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
| ``mujoco_timers`` | False | MuJoCo's profiler timers on (:mod:`fawtgym.envs.mujoco_timers`) |

## Rendering

``render()`` returns an RGB frame of the vehicle in front of the fan array with the wind and a
height cue (:mod:`fawtgym.envs.render`); ``metadata["render_fps"]`` is the control rate, so
``gymnasium.wrappers.RecordVideo`` plays in real time.  Headless: ``MUJOCO_GL=egl`` (set by
``import fawtgym`` when no display is present) or ``osmesa``.

## Version history

* v0 (fawtgym 0.1): first release.  Within v0: the observation carries the action just applied (not
  the one before); the disturbance wrench enters through the free joint (same trajectories to 5e-14);
  ``info["reward_terms"]``; ``render_fps`` follows the control rate and the frame shows the fan array; this env is the
  batch env at N = 1 (one step law: trajectories equal to rounding); bad input that was accepted
  (bool/complex/str numbers, wrongly shaped actions, a set point under the floor, a vehicle that cannot
  hover, physics rates below 100 Hz) is refused with one ``ValueError``.  The physics runs with MuJoCo's
  profiler timers off (``mujoco_timers``; bit for bit the same trajectories).

``"mocap_imu"`` sensors: motion-capture pose at 100 Hz (0.5 mm, 0.1 deg) and an IMU with turn-on
biases, as the VICON-fed PX4 of Wang et al. (2024), Sec. 7 (:mod:`fawtgym.envs.sensors`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import check_known, keyword_names, shown
from fawtgym.core.frames import rot_ned_to_quat_mj, vec_ned_to_mj

from .aero import AeroModel
from .hover_batch_env import CLOSED, HoverBatchEnv
from .options import (
    ACTION_TYPES,
    DEFAULT_REWARD_WEIGHTS,
    INIT_SPREAD,
    RENDER_MODES,
    check_actions,
    check_external_wrench,
    check_init_noise,
    check_reset_options,
    check_setpoint,
    hover_options,
)
from .render import HoverRenderer
from .sensors_batch import BatchSensorModel
from .vehicles import VehiclePreset
from .wind import WindModel
from .wind_cohorts import BatchWind

__all__ = ["ACTION_TYPES", "DEFAULT_REWARD_WEIGHTS", "INIT_SPREAD", "RENDER_MODES", "HoverEnv", "check_init_noise"]


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
        setpoint: hover set point, world NED (default: the FAWT hover point of Wang et al. 2024, Sec. 7.3); above the
            floor (z < 0), every coordinate at most 1e4 m in magnitude.
        init_noise: scale of the random initial perturbation in [0, 10] (0: start exactly hovering at the set point;
            10: up to 1 m, 1 m/s, 30 deg, 1 rad/s off hover).
        reward_weights: overrides of :data:`DEFAULT_REWARD_WEIGHTS`.
        max_position_error: half-size of the termination box [m], in (0, 1e9] (1e9: the SITL plant's "no box").
        integrator: MuJoCo integrator name.
        render_mode: ``None`` or ``"rgb_array"`` (headless via MUJOCO_GL=egl, set by default).
        mujoco_timers: whether the physics runs with MuJoCo's profiler timers (default False: a quarter of
            ``mj_step`` saved; :class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv`).
    """

    @property
    def mujoco_timers(self) -> bool:
        """Whether the physics runs with MuJoCo's profiler timers (the ``mujoco_timers`` option)."""
        return self._batch.mujoco_timers

    @property
    def metadata(self) -> dict[str, Any]:
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
                 render_height: int = 480, mujoco_timers: bool = False, **unknown: Any) -> None:
        super().__init__()
        if unknown:  # a one-line ValueError, as for every option (Python's TypeError is re-worded by gym.make)
            check_known(unknown, keyword_names(HoverEnv), "HoverEnv")
        kwargs = dict(vehicle=vehicle, wind=wind, action_type=action_type, sensors=sensors,
                      control_rate=control_rate, physics_rate=physics_rate, episode_seconds=episode_seconds,
                      setpoint=setpoint, init_noise=init_noise, reward_weights=reward_weights,
                      max_position_error=max_position_error, integrator=integrator, render_width=render_width,
                      render_height=render_height)
        hover_options(**kwargs, render_mode=render_mode)  # the render mode is this env's (the batch does not render)
        self._batch = HoverBatchEnv(1, **kwargs, mujoco_timers=mujoco_timers)
        self._batch._autoreset_on = False  # Gymnasium's single-env API: the caller resets
        b = self._batch
        self.preset = b.preset
        self.action_type = b.action_type
        self.n_substeps, self.physics_dt, self.dt = b.n_substeps, b.physics_dt, b.dt
        self.episode_seconds = b.episode_seconds
        self.action_space = b.single_action_space
        self.observation_space = b.single_observation_space
        self._act_low, self._act_high = b._act_low, b._act_high
        self._render_fps = 1.0 / self.dt
        self.render_mode = render_mode
        self._render_size = (b.options.render_height, b.options.render_width)
        self._renderer: HoverRenderer | None = None
        self.model = b.model
        self._data = mujoco.MjData(self.model)
        self._body = self.model.body("vehicle").id

    # ---- the batch of one's parts and state --------------------------------------------------
    @property
    def wind(self) -> BatchWind:
        """The wind model(s) of this env (its ``model`` is the :class:`WindModel` stepped)."""
        return self._batch.wind

    @property
    def aero(self) -> AeroModel:
        return self._batch.aero

    @property
    def sensor(self) -> BatchSensorModel:
        """The sensor model (a batch of one: ``gyro_bias`` and ``accel_bias`` are (1, 3))."""
        return self._batch.sensor

    @property
    def reward_weights(self) -> Mapping[str, float]:
        """The reward's weights (read-only, fixed at construction: :attr:`HoverBatchEnv.reward_weights`)."""
        return self._batch.reward_weights

    @reward_weights.setter
    def reward_weights(self, value: object) -> None:
        self._batch.reward_weights = value  # raises (fixed at construction)

    @property
    def init_noise(self) -> float:
        """Scale of the random initial perturbation (the batch's :attr:`HoverBatchEnv.init_noise`, checked there)."""
        return self._batch.init_noise

    @init_noise.setter
    def init_noise(self, value: Any) -> None:
        self._batch.init_noise = value

    @property
    def max_steps(self) -> int:
        """Steps per episode before truncation (``episode_seconds / dt`` at construction); assign an int >= 1 (from
        the next step; ``episode_seconds`` keeps the constructed value)."""
        return self._batch.max_steps

    @max_steps.setter
    def max_steps(self, value: Any) -> None:
        self._batch.max_steps = value

    @property
    def max_position_error(self) -> float:
        """Half-size of the termination box [m]; assign a finite positive number (the box from the next step on; the
        observation bounds stay those of construction)."""
        return self._batch.max_position_error

    @max_position_error.setter
    def max_position_error(self, value: Any) -> None:
        self._batch.max_position_error = value

    @property
    def setpoint(self) -> NDArray[np.float64]:
        """Hover set point, world NED [m] (3,), a read-only view; assign a new one any time (validated)."""
        return self._batch.setpoint[0]

    @setpoint.setter
    def setpoint(self, value: ArrayLike) -> None:
        self._batch.setpoint = check_setpoint(value)

    @property
    def rotor_speeds(self) -> NDArray[np.float64]:
        """Rotor speeds [rad/s] at the end of the last step (4,)."""
        return self._batch.rotor_speeds[0].copy()

    @property
    def time(self) -> float:
        """Episode time [s]."""
        return float(self._batch.time[0])

    def set_external_wrench(self, force_ned: ArrayLike = (0.0, 0.0, 0.0),
                            torque_frd: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """A constant extra disturbance (force world NED [N], torque body FRD [N m]) added to the aero wrench from the
        next step on (and reported in ``info["truth"]``)."""
        self._batch.set_external_wrench(*check_external_wrench(force_ned, torque_frd))

    def hover_action(self) -> NDArray[np.float32]:
        """The action that holds the weight at rest (equal rotors / level, zero rates)."""
        return self._batch._hover.copy()

    # ---- gym API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32], dict]:
        if seed is not None and (isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer))
                                 or seed < 0):
            raise ValueError(f"seed must be None or an int >= 0, got {shown(seed)}")
        check_reset_options(options)  # one vehicle: a (3,) set point
        obs, info = self._batch._reset(seed, options, single=True)
        rngs = self._batch._row_rngs
        assert rngs is not None  # the batch's reset made them
        self._np_random = rngs[0]  # the row's generator is this env's (gym.Env.np_random)
        self._np_random_seed = seed if seed is not None else getattr(self, "_np_random_seed", None)
        return obs[0], info

    def step(self, action: ArrayLike) -> tuple[NDArray[np.float32], float, bool, bool, dict]:
        if self._batch._row_rngs is None:
            raise RuntimeError("HoverEnv.step() called before reset(): call reset() first")
        a = check_actions(action, (4,), self._act_low, self._act_high, "action", finite=False)
        obs, reward, terminated, truncated, info = self._batch._step(a[None], "action", single=True)
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), info

    @property
    def data(self) -> mujoco.MjData:
        """MuJoCo's data at the last step's state (MuJoCo's z-up frame), forwarded (``mj_forward``) with the last
        step's mean rotor thrusts and the held disturbance wrench: for rendering and inspection (the physics
        steps in the batch of one's rollout)."""
        if self._batch._row_rngs is not None:
            self._sync_data()
        return self._data

    @data.setter
    def data(self, value: mujoco.MjData) -> None:
        self._data = value

    def _sync_data(self) -> None:
        """``self._data`` at the last step's state (position, attitude, velocity in MuJoCo's frame)."""
        b = self._batch
        d = self._data
        d.qpos[0:3] = vec_ned_to_mj(b._pos[0])
        d.qpos[3:7] = rot_ned_to_quat_mj(b._rot[0])
        d.qvel[0:3] = vec_ned_to_mj(b._vel[0])
        d.qvel[3:6] = vec_ned_to_mj(b._omega[0])
        d.ctrl[0:4] = b._applied[0]
        d.qfrc_applied[0:3] = vec_ned_to_mj(b._force[0] + b.external_force[0])  # the free joint: world force,
        d.qfrc_applied[3:6] = vec_ned_to_mj(b._torque[0] + b.external_torque[0])  # body torque (envs/mjcf.py)
        mujoco.mj_forward(self.model, d)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state

    # ---- rendering ----------------------------------------------------------------------
    def render(self) -> NDArray[np.uint8] | None:
        if self._batch._rollout is None:
            raise RuntimeError(CLOSED)
        if self._batch._row_rngs is None:
            raise RuntimeError("HoverEnv.render() called before reset(): call reset() first")
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array' to gym.make")
            return None
        if self._renderer is None:
            height, width = self._render_size
            self._renderer = HoverRenderer(self.model, width, height, self._body)
        b = self._batch
        wind = b._wind_com[0].copy()  # the wind at the CoM (info's truth)
        return self._renderer.render(self.data, self.setpoint, wind)

    def close(self) -> None:
        """Release the renderer and the batch's physics; step(), reset() and render() then raise RuntimeError (as
        every closed env of the package does; closing twice is allowed)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._batch.close()
