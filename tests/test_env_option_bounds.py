"""Env options have physical ranges (second audit A8, A9): a huge or tiny finite value is refused at construction
with one line naming the option, the allowed range and its unit, the same text at N = 1 (``gym.make``) and N = 3
(:class:`HoverBatchEnv`), never a bare OverflowError / ZeroDivisionError / scipy or MuJoCo error, and never accepted
to make every reset fail or a reward term inf.  The ranges admit every preset and the values at their ends fly
with finite observations, rewards and reward terms.  A refused assignment or reset changes nothing.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import fawtgym  # noqa: F401  (registers fawtgym/Hover-v0)
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.sensors import FIELD_RANGES, SENSOR_PRESETS, SensorSpec
from fawtgym.envs.vehicles import VEHICLE_NAMES, make_vehicle
from fawtgym.envs.wind import make_wind, wind_names

HUGE = 10**400  # an int beyond float range: float(HUGE) raises OverflowError
BIG = "an int of about 401 digits (int)"  # check_number shows a long int by its length


def _error(call: Callable[[], Any]) -> str:
    """The one-line ValueError text of ``call`` (any other exception, or a warning on the way, fails)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning (overflow, divide) on the way to the error
        with np.errstate(all="raise", under="ignore"), pytest.raises(ValueError) as info:
            call()
    assert type(info.value) is ValueError, type(info.value)
    text = str(info.value)
    assert "\n" not in text, text
    return text


def _texts(kwargs: dict[str, Any]) -> str:
    """The error of the env options ``kwargs`` through gym.make (N = 1) and HoverBatchEnv(3): one text."""
    texts = {_error(lambda: gym.make("fawtgym/Hover-v0", **kwargs)), _error(lambda: HoverBatchEnv(3, **kwargs))}
    assert len(texts) == 1, texts
    return texts.pop()


S500 = {"base": "s500"}
IMU = {"base": "mocap_imu"}

# (kwargs, exact message); first the audit's A8 rows (bare errors on main), then its A9 rows (accepted on main)
CASES = [
    # A8: 10**400 for any real option
    ({"control_rate": HUGE}, f"control_rate must be a finite real number in [1, 100000] Hz, got {BIG}"),
    ({"physics_rate": HUGE}, f"physics_rate must be a finite real number in [100, 100000] Hz, got {BIG}"),
    ({"episode_seconds": HUGE}, "episode_seconds must be a finite real number in (0, 1e+09] s (1e+09 s: about 32 "
                                f"years of flight), got {BIG}"),
    ({"init_noise": HUGE}, "init_noise must be a finite real number in [0, 10] (10: a start up to 1 m, 1 m/s, 30 deg, "
                           f"1 rad/s off hover), got {BIG}"),
    ({"max_position_error": HUGE}, "max_position_error must be a finite real number in (0, 1e+09] m (1e+09: the SITL "
                                   f"plant's 'no box'), got {BIG}"),
    ({"reward_weights": {"pos": HUGE}}, f"reward weight 'pos' must be a finite real number in [0, 1e+06], got {BIG}"),
    ({"reward_weights": {"att": 1e308}}, "reward weight 'att' must be a finite real number in [0, 1e+06], got 1e+308 "
                                         "(float)"),
    ({"vehicle": {**S500, "mass": HUGE}}, f"vehicle field 'mass' must be a finite real number in [0.0001, 10000] kg, "
                                          f"got {BIG}"),
    ({"sensors": {**IMU, "gyro_density": HUGE}}, "sensor field 'gyro_density' must be a finite real number in "
                                                 f"[0, 10] (rad/s)/sqrt(Hz), got {BIG}"),
    ({"wind": {"name": "fawt-50", "on_time": HUGE}}, f"on_time must be a finite real number in [0, 1e+09] s or None, "
                                                     f"got {BIG}"),
    ({"wind": {"name": "dryden-light", "mean_wind": HUGE}}, "mean_wind must be a finite real number in [0, 100] m/s, "
                                                            "True (the log-profile speed) or False (none), "
                                                            f"got {BIG}"),
    ({"wind": {"name": "dryden-light", "direction_deg": HUGE}}, "direction_deg must be a finite real number in "
                                                                f"[-360, 360] degrees (a heading), got {BIG}"),
    ({"wind": {"name": "gust-1cos", "direction_deg": 1e300}}, "direction_deg must be a finite real number in "
                                                              "[-360, 360] degrees (a heading), got 1e+300 (float)"),
    ({"wind": {"name": "dryden-light", "altitude": 1e300}}, "altitude must be a finite real number in (0, 304.8] m "
                                                            "(the low-altitude model, up to 1000 ft), got 1e+300 "
                                                            "(float)"),
    ({"wind": {"name": "fawt-50", "spin_down_tau": 1e300}}, "spin_down_tau must be a finite real number in "
                                                            "[0.0001, 10000] s, got 1e+300 (float)"),
    ({"wind": {"name": "gust-1cos", "start_time": HUGE}}, f"start_time must be a finite real number in [0, 1e+09] s, "
                                                          f"got {BIG}"),
    # A8: float overflow, division by zero, scipy and MuJoCo errors
    ({"vehicle": {**S500, "omega_max": 1e200}}, "vehicle field 'omega_max' must be a finite real number in [1, 100000] "
                                                "rad/s, got 1e+200 (float)"),
    ({"sensors": {**IMU, "pose_rate": 5e-324}}, "sensor field 'pose_rate' must be a finite real number in "
                                                "[0.01, 100000] Hz or None, got 5e-324 (float)"),
    ({"wind": {"name": "fawt-50", "length_scale": 5e-324}}, "length_scale must be a finite real number in "
                                                            "[0.001, 100000] m, got 5e-324 (float)"),
    ({"vehicle": {**S500, "arm_length": 5e-324}}, "vehicle field 'arm_length' must be a finite real number in "
                                                  "[0.001, 100] m, got 5e-324 (float)"),
    ({"vehicle": {**S500, "inertia": (5e-324,) * 3}}, "vehicle field 'inertia' principal moments must be in "
                                                      "[1e-07, 100000] kg m^2, got [5e-324, 5e-324, 5e-324]"),
    ({"control_rate": 5e-324}, "control_rate must be a finite real number in [1, 100000] Hz, got 5e-324 (float)"),
    # A9: accepted on main, then every reset failed, or a reward term was inf, or every episode diverged
    ({"sensors": {**IMU, "position_density": 1e300}}, "sensor field 'position_density' must be a finite real number "
                                                      "in [0, 10] m/sqrt(Hz), got 1e+300 (float)"),
    ({"vehicle": {**S500, "arm_length": 1e300}}, "vehicle field 'arm_length' must be a finite real number in "
                                                 "[0.001, 100] m, got 1e+300 (float)"),
    ({"wind": {"name": "dryden-light", "mean_wind": 1e300}}, "mean_wind must be a finite real number in [0, 100] "
                                                             "m/s, True (the log-profile speed) or False (none), "
                                                             "got 1e+300 (float)"),
    ({"sensors": {**IMU, "attitude_sigma": 1e300}}, "sensor field 'attitude_sigma' must be a finite real number in "
                                                    "[0, 3.14159] rad, got 1e+300 (float)"),
    ({"sensors": {**IMU, "gyro_density": 1e308}}, "sensor field 'gyro_density' must be a finite real number in "
                                                  "[0, 10] (rad/s)/sqrt(Hz), got 1e+308 (float)"),
    ({"sensors": {**IMU, "mag_sigma": 1e308}}, "sensor field 'mag_sigma' must be a finite real number in [0, 10] "
                                               "gauss, got 1e+308 (float)"),
    ({"wind": {"name": "fawt-50", "length_scale": 1e300}}, "length_scale must be a finite real number in "
                                                           "[0.001, 100000] m, got 1e+300 (float)"),
    ({"wind": {"name": "dryden-light", "length_scale": 1e300}}, "length_scale must be a finite real number in "
                                                                "[0.001, 100000] m, got 1e+300 (float)"),
    ({"wind": {"name": "fawt-50", "span": 1e300, "rates": True}}, "span must be a finite real number in [0.001, 100] "
                                                                  "m, got 1e+300 (float)"),
    ({"wind": {"name": "gust-1cos", "amplitude": 1e300}}, "amplitude must be a finite speed or NED 3-vector of "
                                                          "magnitude at most 100 m/s, got 1e+300"),
    ({"vehicle": {**S500, "body_drag": (1e300,) * 3}}, "vehicle field 'body_drag' entries must be in [0, 100] "
                                                       "N/(m/s)^2, got [1e+300, 1e+300, 1e+300]"),
    ({"vehicle": {**S500, "rotor_drag": 1e300}}, "vehicle field 'rotor_drag' must be a finite real number in "
                                                 "[0, 0.1] N/((m/s)(rad/s)), got 1e+300 (float)"),
    ({"vehicle": {**S500, "rolling_moment": 1e300}}, "vehicle field 'rolling_moment' must be a finite real number in "
                                                     "[0, 0.1] N m/((m/s)(rad/s)), got 1e+300 (float)"),
    ({"vehicle": {**S500, "cop_offset": (0.0, 0.0, 1e300)}}, "vehicle field 'cop_offset' entries must be in "
                                                             "[-100, 100] m, got [0.0, 0.0, 1e+300]"),
    ({"vehicle": {**S500, "inertia": (1e-12,) * 3}}, "vehicle field 'inertia' principal moments must be in "
                                                     "[1e-07, 100000] kg m^2, got [1e-12, 1e-12, 1e-12]"),
    ({"vehicle": {**S500, "tau_up": 5e-324}}, "vehicle field 'tau_up' must be a finite real number in [0.0001, 10] "
                                              "s, got 5e-324 (float)"),
    ({"wind": {"name": "fawt-50", "spin_tau": 5e-324}}, "spin_tau must be a finite real number in [0.0001, 10000] "
                                                        "s, got 5e-324 (float)"),
]


@pytest.mark.parametrize(("kwargs", "message"), CASES, ids=[str(k)[:60] for k, _ in CASES])
def test_out_of_range_option_one_line_same_text_at_n1_and_n3(kwargs, message):
    assert _texts(kwargs) == message


def test_the_model_classes_give_the_same_text_as_the_env():
    """The range lives in the field's model (VehiclePreset, SensorSpec, the wind): the env only forwards it."""
    assert _error(lambda: make_vehicle({**S500, "omega_max": 1e200})) == _texts({"vehicle": {**S500,
                                                                                              "omega_max": 1e200}})
    assert _error(lambda: SensorSpec("mine", pose_rate=5e-324)) == _texts({"sensors": {**IMU, "pose_rate": 5e-324}})
    spec = {"name": "fawt-50", "length_scale": 5e-324}
    assert _error(lambda: make_wind(spec)) == _texts({"wind": spec})


def test_every_preset_is_inside_the_ranges():
    for name in VEHICLE_NAMES:
        make_vehicle(name)
    for name, spec in SENSOR_PRESETS.items():
        assert SensorSpec(**{**spec.__dict__, "name": name}) == spec
    for name in wind_names():
        make_wind(name)


# the ends of the ranges fly: finite observation, reward and reward terms (a divergence is a flagged termination)
EXTREMES = [
    {"sensors": {**IMU, **{k: hi for k, (_, hi, _) in FIELD_RANGES.items() if k != "pose_rate"}}},
    {"sensors": {**IMU, "pose_rate": 0.01}, "control_rate": 1.0},
    {"vehicle": {**S500, "rotor_drag": 0.1, "rolling_moment": 0.1, "body_drag": (100.0,) * 3,
                 "cop_offset": (100.0, -100.0, 100.0)}},
    {"vehicle": {**S500, "tau_up": 1e-4, "tau_down": 10.0, "inertia": (1e-7,) * 3}},
    {"vehicle": {**S500, "inertia": (1e5,) * 3, "arm_length": 1e-3, "rotor_radius": 1e-3}},
    {"vehicle": {**S500, "arm_length": 100.0, "rotor_radius": 10.0}},
    {"wind": {"name": "dryden-severe", "mean_wind": 100.0, "length_scale": 1e5, "span": 100.0, "rates": True}},
    {"wind": {"name": "fawt-50", "length_scale": 1e-3, "span": 1e-3, "rates": True, "spin_tau": 1e-4}},
    {"wind": {"name": "gust-1cos", "amplitude": 100.0, "length": 1e-3, "speed": 1000.0, "start_time": 0.0}},
    {"reward_weights": {key: 1e6 for key in ("pos", "vel", "att", "rate", "action", "failure")}},
]


@pytest.mark.parametrize("kwargs", EXTREMES, ids=[str(k)[:60] for k in EXTREMES])
def test_range_ends_fly_finite(kwargs):
    env = HoverBatchEnv(3, **kwargs)
    obs, _ = env.reset(seed=0)
    assert np.all(np.isfinite(obs))
    for _ in range(10):
        obs, reward, _, _, info = env.step(env.hover_action())
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))
        for key, term in info["reward_terms"].items():
            assert np.all(np.isfinite(term)), key


# ---- a refused assignment or reset changes nothing ------------------------------------------------------------------
def _rollout(env: Any, steps: int = 8) -> list[np.ndarray]:
    out = [np.array(env.reset()[0], copy=True)]
    for _ in range(steps):
        obs, reward, _, _, _ = env.step(env.hover_action())
        out += [np.array(obs, copy=True), np.array(reward, copy=True)]
    return out


def _make(n: int) -> Any:
    env = gym.make("fawtgym/Hover-v0") if n == 1 else HoverBatchEnv(n)
    env.reset(seed=3)
    return env


REFUSED: list[tuple[str, Callable[[Any], Any], str]] = [
    ("init_noise", lambda env: setattr(env.unwrapped, "init_noise", HUGE),
     "init_noise must be a finite real number in [0, 10] (10: a start up to 1 m, 1 m/s, 30 deg, 1 rad/s off hover), "
     f"got {BIG}"),
    ("max_position_error", lambda env: setattr(env.unwrapped, "max_position_error", HUGE),
     f"max_position_error must be a finite real number in (0, 1e+09] m (1e+09: the SITL plant's 'no box'), got {BIG}"),
    ("reset init_noise", lambda env: env.reset(options={"init_noise": HUGE}),
     "init_noise must be a finite real number in [0, 10] (10: a start up to 1 m, 1 m/s, 30 deg, 1 rad/s off hover), "
     f"got {BIG}"),
]


@pytest.mark.parametrize(("what", "call", "message"), REFUSED, ids=[w for w, _, _ in REFUSED])
def test_refused_call_changes_nothing(what, call, message):
    texts = set()
    for n in (1, 3):
        env, ref = _make(n), _make(n)
        texts.add(_error(lambda e=env: call(e)))
        for a, b in zip(_rollout(env), _rollout(ref), strict=True):
            np.testing.assert_array_equal(a, b)  # bitwise: as if the refused call had never happened
    assert texts == {message}, texts


def test_docs_list_the_ranges_the_code_checks():
    """docs/option-ranges.md states each vehicle and sensor field's range as the code checks it."""
    from pathlib import Path

    from fawtgym.envs.vehicles import INERTIA_RANGE, SCALAR_RANGES

    text = (Path(__file__).resolve().parents[1] / "docs" / "option-ranges.md").read_text()
    rows = {line.split("|")[1].strip(): line.split("|")[2].strip() for line in text.splitlines()
            if line.startswith("| `")}
    for table in (SCALAR_RANGES, FIELD_RANGES):
        for field, (lo, hi, unit) in table.items():
            key = next(k for k in rows if f"`{field}`" in k)
            assert rows[key].startswith(f"[{lo:g}, {hi:g}] {unit}"), (field, rows[key])
    assert rows["`inertia` principal moments"] == f"[{INERTIA_RANGE[0]:g}, {INERTIA_RANGE[1]:g}] kg m^2"


@pytest.mark.parametrize(("seconds", "steps"), [(5e-324, 1), (1e-12, 1), (0.001, 1), (0.01, 1), (0.0100001, 2),
                                                (0.03, 3), (10.0, 1000)])
def test_an_episode_is_whole_control_steps_and_never_zero(seconds, steps):
    """episode_seconds rounds up to whole control steps (100 Hz here), at least one: the tiniest episode is one
    step, which ends truncated (max_steps was 0 for 5e-324 s, below the setter's own minimum of 1)."""
    env = gym.make("fawtgym/Hover-v0", episode_seconds=seconds, init_noise=0.0)
    assert env.unwrapped.max_steps == steps
    env.reset(seed=0)
    for k in range(steps):
        _, _, terminated, truncated, _ = env.step(env.unwrapped.hover_action())
        assert not terminated and truncated == (k == steps - 1)
