"""The hover env's options, checked once for :class:`HoverEnv` and :class:`HoverBatchEnv` (one validation layer).

Every check raises a one-line ``ValueError`` naming the option, the value it got and what is allowed; the
message and the exception type do not depend on the batch size.  :func:`hover_options` checks the
constructor's arguments; :func:`check_reset_options` the ``options`` of ``reset`` (all of them before any is
applied, so a failed reset changes nothing); :func:`check_actions` the actions of ``step``.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import check_number, listed, shown
from fawtgym.core.frames import FAWT_HOVER_POINT_NED

from .mjcf import INTEGRATORS
from .motors import hover_command
from .sensors import SensorSpec, make_sensor_spec
from .vehicles import GRAVITY, VehiclePreset, make_vehicle
from .wind import WindModel, make_wind

ACTION_TYPES = ("motors", "ctbr")
RENDER_MODES = ("rgb_array",)
DEFAULT_REWARD_WEIGHTS: dict[str, float] = {
    "pos": 2.0, "vel": 0.2, "att": 1.0, "rate": 0.05, "action": 0.5, "failure": 1.0,
}
#: physics rates the env accepts [Hz]: the motor lags (5-80 ms) and the 1 kHz design rate need at least 100 Hz
PHYSICS_RATE_RANGE = (100.0, 100_000.0)
#: largest offscreen frame side [px]
MAX_RENDER_SIZE = 8192
RESET_OPTIONS = ("init_noise", "setpoint")
#: initial-state perturbation at init_noise = 1: uniform in +- these (position m, velocity m/s, tilt rad, rate rad/s)
INIT_SPREAD = {"position": 0.1, "velocity": 0.1, "attitude": math.radians(3.0), "angular_velocity": 0.1}


def hover_action_space(action_type: str) -> spaces.Box:
    """One vehicle's action space: ``motors`` Box(0, 1, (4,)); ``ctbr`` Box([0, -1, -1, -1], [1, 1, 1, 1])."""
    if action_type == "motors":
        return spaces.Box(0.0, 1.0, shape=(4,), dtype=np.float32)
    return spaces.Box(np.array([0, -1, -1, -1], dtype=np.float32), np.array([1, 1, 1, 1], dtype=np.float32),
                      dtype=np.float32)


def hover_action(preset: VehiclePreset, action_type: str) -> NDArray[np.float32]:
    """The action (4,) that holds the weight at rest: equal rotors (motors) or level with zero rates (ctbr)."""
    if action_type == "motors":
        return np.full(4, hover_command(preset), dtype=np.float32)
    return np.array([hover_thrust_ratio(preset), 0, 0, 0], dtype=np.float32)


#: control rates the env accepts [Hz]: from one step a second (the wind's longest step, DT_MAX = 1 s) to the fastest
#: physics rate
CONTROL_RATE_RANGE = (1.0, 100_000.0)
#: the longest episode [s] (about 32 years: the SITL bridge's "never ends"): the step counter stays far inside
#: int64 and float64 times keep sub-microsecond resolution; a longer "episode" (1e300) is a typo, not a flight
MAX_EPISODE_SECONDS = 1e9
#: the largest ``init_noise``: at 10 a row starts up to 1 m, 1 m/s, 30 deg and 1 rad/s off hover (:data:`INIT_SPREAD`
#: times 10); beyond it the start is no hover (tilts past 90 deg from 30 on) and huge values make every episode diverge
MAX_INIT_NOISE = 10.0
#: the largest set point coordinate [m] (10 km from the origin; MuJoCo resets states beyond 1e10 as diverged)
MAX_SETPOINT = 1e4
#: the largest ``max_position_error`` [m]: 1e9 is the SITL plant's "no box"; the float32 observation bounds stay finite
MAX_POSITION_ERROR = 1e9
#: the largest reward weight: a weighted term stays far inside float64 (a weight of 1e308 makes the reward inf)
MAX_REWARD_WEIGHT = 1e6


def check_init_noise(value: Any) -> float:
    """``init_noise`` as a float: a finite real number in [0, :data:`MAX_INIT_NOISE`] (one-line ValueError else)."""
    return check_number(value, "init_noise", minimum=0.0, inclusive_minimum=True, maximum=MAX_INIT_NOISE,
                        note="(10: a start up to 1 m, 1 m/s, 30 deg, 1 rad/s off hover)")


def check_max_position_error(value: Any) -> float:
    """``max_position_error`` [m] as a float: finite, > 0 and at most :data:`MAX_POSITION_ERROR`."""
    return check_number(value, "max_position_error", minimum=0.0, maximum=MAX_POSITION_ERROR,
                        note="m (1e+09: the SITL plant's 'no box')")


def _real_array(value: Any, name: str, what: str) -> NDArray[np.float64]:
    """``value`` as a float64 array if every entry is a real number (bool, complex, str, objects refused)."""
    try:
        a = np.asarray(value)
    except ValueError as exc:  # ragged nested sequences
        raise ValueError(f"{name} must be {what}, got {shown(value)}") from exc
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be {what} (real numbers), got {shown(value)} (dtype {a.dtype})")
    return a.astype(np.float64)


def check_setpoint(value: Any, n: int | None = None) -> NDArray[np.float64]:
    """A hover set point, world NED [m]: 3 finite numbers (or (n, 3), one per row) above the floor.

    The floor is z_NED = 0 (NED z points down), so z must be < 0; every coordinate is at most :data:`MAX_SETPOINT`
    (10 km) in magnitude.  A set point just above the floor is allowed
    (the SITL plant starts resting on the ground; the env then ends the episode with a ground contact).
    Shapes broadcast as numpy's do: (3,) and (1, 3) are every row's set point (at every batch size, the single
    env included), (n, 3) one per row.  Returns (3,) or (n, 3).
    """
    shapes = "(3,) or (1, 3)" if n is None else f"(3,), (1, 3) or ({n}, 3)"
    sp = _real_array(value, "setpoint", f"3 finite NED coordinates [m] of shape {shapes}")
    if sp.shape == (1, 3) and n != 1:
        sp = sp[0]
    if sp.shape != (3,) and (n is None or sp.shape != (n, 3)) or not np.all(np.isfinite(sp)):
        raise ValueError(f"setpoint must be 3 finite NED coordinates [m] of shape {shapes}, got {shown(value)}")
    if np.any(sp[..., 2] >= 0.0):
        raise ValueError(f"setpoint z must be above the floor (z_NED < 0: NED z points down), got {shown(value)}")
    if np.any(np.abs(sp) > MAX_SETPOINT):
        raise ValueError(f"setpoint coordinates must be at most {MAX_SETPOINT:g} m in magnitude (10 km from the "
                         f"origin), got {shown(value)}")
    return sp


def check_external_wrench(force: Any, torque: Any, n: int | None = None
                          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """An external wrench: force NED [N] and torque FRD [N m], each 3 finite real numbers ((3,), or (n, 3) one per
    row if ``n`` is given); returns them broadcast to (n, 3) (or (3,))."""
    shapes = "(3,)" if n is None else f"(3,) or ({n}, 3)"
    what = f"two {shapes} arrays of finite real numbers (force NED [N], torque FRD [N m])"
    error = f"external wrench must be {what}, got {shown(force)}, {shown(torque)}"
    out = []
    for value in (force, torque):
        try:
            a = _real_array(value, "external wrench", what)
        except ValueError:
            raise ValueError(error) from None
        if (a.shape != (3,) and (n is None or a.shape != (n, 3))) or not np.all(np.isfinite(a)):
            raise ValueError(error)
        out.append(a if n is None else np.broadcast_to(a, (n, 3)))
    return out[0], out[1]


def check_reward_weights(value: Any) -> dict[str, float]:
    """``reward_weights``: None or a mapping of some of :data:`DEFAULT_REWARD_WEIGHTS` to finite numbers >= 0."""
    weights = dict(DEFAULT_REWARD_WEIGHTS)
    if value is None:
        return weights
    if not isinstance(value, Mapping):
        raise ValueError(f"reward_weights must be a mapping of {list(DEFAULT_REWARD_WEIGHTS)} to numbers >= 0, "
                         f"got {shown(value)}")
    for key, w in value.items():
        if key not in DEFAULT_REWARD_WEIGHTS:
            raise ValueError(f"unknown reward weight {shown(key)}; valid: {list(DEFAULT_REWARD_WEIGHTS)}")
        weights[key] = check_number(w, f"reward weight {key!r}", minimum=0.0, inclusive_minimum=True,
                                    maximum=MAX_REWARD_WEIGHT)
    return weights


def check_sensors(spec: Any) -> SensorSpec:
    """A sensor preset name, :class:`SensorSpec` or mapping (``base`` + fields); unknown or non-numeric fields
    are named."""
    if isinstance(spec, Mapping):
        fields = {f.name for f in dataclasses.fields(SensorSpec)} - {"name"}
        unknown = set(spec) - fields - {"base"}
        if unknown:
            valid = ["base", *sorted(fields)]
            raise ValueError(f"unknown sensors field(s) {listed(unknown)}; valid: {valid}")
    return make_sensor_spec(spec)


def _render_size(value: Any, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or not (
            1 <= int(value) <= MAX_RENDER_SIZE):
        raise ValueError(f"{name} must be an int in [1, {MAX_RENDER_SIZE}] pixels, got {shown(value)}")
    return int(value)


def hover_thrust_ratio(preset: VehiclePreset) -> float:
    """Weight over the four rotors' maximum thrust, m g / (4 k_T omega_max^2): the hover throttle."""
    return preset.mass * GRAVITY / (4.0 * preset.max_thrust_per_rotor)


def hover_mass_scales(preset: VehiclePreset) -> tuple[float, float]:
    """The open interval of mass scales s at which ``preset`` can hover: s m g between the four rotors' idle thrust
    4 k_T omega_min^2 and their maximum thrust 4 k_T omega_max^2 (:func:`check_can_hover` at s = 1)."""
    weight = preset.mass * GRAVITY
    return 4.0 * preset.k_thrust * preset.omega_min**2 / weight, 4.0 * preset.max_thrust_per_rotor / weight


def check_can_hover(preset: VehiclePreset) -> None:
    """Refuse a vehicle whose hover speed is outside its rotor speed range (its hover action would leave the
    action space): the weight must be below the rotors' maximum thrust and above their idle thrust."""
    ratio = hover_thrust_ratio(preset)
    idle = preset.k_thrust * preset.omega_min**2 * 4.0 / (preset.mass * GRAVITY)
    if not (idle < 1.0 < 1.0 / ratio):
        raise ValueError(f"vehicle {shown(preset.name)} cannot hover: hover thrust ratio m g / (4 T_max) = {ratio:.4g} "
                         f"(mass {preset.mass:g} kg) must be in ({idle * ratio:.4g}, 1), i.e. its weight between the "
                         "four rotors' idle and maximum thrust")


@dataclasses.dataclass(frozen=True)
class HoverOptions:
    """The checked options of the hover env (see :mod:`fawtgym.envs.hover_env` for their meaning)."""

    preset: VehiclePreset
    wind: WindModel
    action_type: str
    sensors: SensorSpec
    control_rate: float
    physics_rate: float
    n_substeps: int
    physics_dt: float
    dt: float
    episode_seconds: float
    max_steps: int
    setpoint: NDArray[np.float64]
    init_noise: float
    reward_weights: dict[str, float]
    max_position_error: float
    integrator: str
    render_mode: str | None
    render_width: int
    render_height: int


def episode_steps(episode_seconds: float, dt: float) -> int:
    """Control steps per episode: ``episode_seconds`` rounded up to whole control steps ``dt`` (a part-step counts as
    a step), and at least one (an episode shorter than a step, down to 5e-324 s, is one step: never zero)."""
    return max(1, int(math.ceil(episode_seconds / dt - 1e-9)))


def hover_options(vehicle: Any = "s500", wind: Any = "calm", action_type: Any = "motors", sensors: Any = "none",
                  control_rate: Any = 100.0, physics_rate: Any = 1000.0, episode_seconds: Any = 10.0,
                  setpoint: ArrayLike | None = None, init_noise: Any = 1.0, reward_weights: Any = None,
                  max_position_error: Any = 2.0, integrator: Any = "Euler", render_mode: Any = None,
                  render_width: Any = 480, render_height: Any = 480) -> HoverOptions:
    """Check every constructor argument of the hover env (one-line ValueError naming the first bad one)."""
    preset = make_vehicle(vehicle)
    check_can_hover(preset)
    if not isinstance(action_type, str) or action_type not in ACTION_TYPES:
        raise ValueError(f"unknown action_type {shown(action_type)}; valid: {list(ACTION_TYPES)}")
    if render_mode == "human":
        raise ValueError("render_mode 'human' is not supported: fawtgym renders off screen only; valid: None, "
                         "'rgb_array' (record a video with gymnasium.wrappers.RecordVideo)")
    if render_mode is not None and (not isinstance(render_mode, str) or render_mode not in RENDER_MODES):
        raise ValueError(f"unknown render_mode {shown(render_mode)}; valid: {[None, *RENDER_MODES]}")
    if not isinstance(integrator, str) or integrator not in INTEGRATORS:
        raise ValueError(f"unknown integrator {shown(integrator)}; valid: {list(INTEGRATORS)}")
    control_rate = check_number(control_rate, "control_rate", minimum=CONTROL_RATE_RANGE[0], inclusive_minimum=True,
                                maximum=CONTROL_RATE_RANGE[1], note="Hz")
    physics_rate = check_number(physics_rate, "physics_rate", minimum=PHYSICS_RATE_RANGE[0], inclusive_minimum=True,
                                maximum=PHYSICS_RATE_RANGE[1], note="Hz")
    ratio = physics_rate / control_rate
    if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-9:
        raise ValueError(f"control_rate {control_rate:g} Hz must divide physics_rate {physics_rate:g} Hz "
                         f"(their ratio {ratio:g} must be a whole number)")
    n_substeps = int(round(ratio))
    physics_dt = 1.0 / physics_rate
    dt = n_substeps * physics_dt
    episode_seconds = check_number(episode_seconds, "episode_seconds", minimum=0.0, maximum=MAX_EPISODE_SECONDS,
                                   note=f"s (1e+09 s: about {MAX_EPISODE_SECONDS / 3.156e7:.0f} years of flight)")
    max_position_error = check_max_position_error(max_position_error)
    sp = FAWT_HOVER_POINT_NED.copy() if setpoint is None else check_setpoint(setpoint)
    return HoverOptions(
        preset=preset, wind=make_wind(wind), action_type=action_type, sensors=check_sensors(sensors),
        control_rate=control_rate, physics_rate=physics_rate, n_substeps=n_substeps, physics_dt=physics_dt, dt=dt,
        episode_seconds=episode_seconds, max_steps=episode_steps(episode_seconds, dt), setpoint=sp,
        init_noise=check_init_noise(init_noise), reward_weights=check_reward_weights(reward_weights),
        max_position_error=max_position_error, integrator=integrator, render_mode=render_mode,
        render_width=_render_size(render_width, "render_width"),
        render_height=_render_size(render_height, "render_height"))


def check_reset_options(options: Any, n: int | None = None
                        ) -> tuple[NDArray[np.float64] | None, float | None]:
    """``reset``'s ``options``: None or a mapping with ``setpoint`` and/or ``init_noise``; returns the checked
    (setpoint or None, init_noise or None).  Nothing is applied here, so a bad option leaves the env unchanged."""
    if options is None:
        return None, None
    if not isinstance(options, Mapping):
        raise ValueError(f"reset options must be None or a dict with keys {list(RESET_OPTIONS)}, got {shown(options)}")
    unknown = set(options) - set(RESET_OPTIONS)
    if unknown:
        raise ValueError(f"unknown reset option(s) {listed(unknown)}; valid: {list(RESET_OPTIONS)}")
    sp = check_setpoint(options["setpoint"], n) if "setpoint" in options else None
    noise = check_init_noise(options["init_noise"]) if "init_noise" in options else None
    return sp, noise


def check_actions(actions: Any, shape: tuple[int, ...], low: NDArray[np.float64], high: NDArray[np.float64],
                  name: str = "actions", rows: NDArray[np.bool_] | None = None,
                  finite: bool = True) -> NDArray[np.float64]:
    """Actions of exactly ``shape`` of real numbers (no bool, no complex), finite; returned as float64 (a copy
    unless ``finite`` is False: then the input itself if it is C-contiguous float64 already).

    Finite values outside [low, high] are the caller's to clip (and flag); NaN/inf raise naming the entry
    (only in the ``rows`` (N,) that step, if given: a row that autoresets ignores its action).  ``finite=False``
    leaves that test to a kernel in front of which the caller calls :func:`raise_action_not_finite`.
    """
    a = np.asarray(actions)
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be real numbers (int or float), got dtype {a.dtype}")
    if not finite:
        return np.ascontiguousarray(a, dtype=np.float64)
    a = a.astype(np.float64, copy=True)
    bad = ~np.isfinite(a)
    if rows is not None:
        bad &= rows[:, None]
    if bad.any():
        raise_action_not_finite(a, tuple(int(x) for x in np.argwhere(bad)[0]), name, low, high)
    return a


def raise_action_not_finite(a: NDArray[np.float64], idx: tuple[int, ...], name: str, low: NDArray[np.float64],
                            high: NDArray[np.float64]) -> None:
    """The ValueError of a non-finite action entry ``a[idx]`` (the same text wherever it is found)."""
    where = ", ".join(map(str, idx))
    raise ValueError(f"{name}[{where}] is {a[idx]}; every action entry must be finite "
                     f"(bounds {low.tolist()} .. {high.tolist()})")
