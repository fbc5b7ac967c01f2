"""Issue 14 audit (D10, D1, D3, D2, D8, D7, D9): the env's state and settings cannot be changed past their checks.

Kernel state is handed out as read-only views (assigning raises one line naming what to use instead), settings are
validated properties, a failed reset changes nothing, and every refusal has the same text at N = 1 and N = 3 (and for
HoverEnv where it has the attribute); a refused call leaves the trajectory bitwise as if it had never been made.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv


def _error(kind: type[Exception], call: Callable[[], Any]) -> str:
    """The one-line text of the ``kind`` error ``call`` raises."""
    with pytest.raises(kind) as err:
        call()
    text = str(err.value)
    assert "\n" not in text, text
    assert type(err.value) is kind, type(err.value)
    return text


def _rollout(env: HoverBatchEnv, steps: int = 15) -> list[np.ndarray]:
    """``steps`` hover steps: observations, rewards and the truth's force, as bytes-comparable arrays."""
    out = []
    for _ in range(steps):
        obs, reward, _, _, info = env.step(env.hover_action())
        out += [obs.copy(), reward.copy(), info["truth"]["force"].copy(), info["time"].copy()]
    return out


def _same(a: list[np.ndarray], b: list[np.ndarray]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.tobytes() == y.tobytes()


def _fresh(n: int, **kwargs: Any) -> HoverBatchEnv:
    env = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu", **kwargs)
    env.reset(seed=0)
    return env


# ---- D10: kernel state is read-only ---------------------------------------------------------------------------------
KERNEL_STATE = {
    "rotor_speeds": (lambda e: e, r"HoverBatchEnv\.rotor_speeds is kernel state \(read-only\): they follow the "),
    "time": (lambda e: e, r"HoverBatchEnv\.time is kernel state \(read-only\): it advances with step"),
    "mass_scale": (lambda e: e, r"HoverBatchEnv\.mass_scale is kernel state \(read-only\): set mass_scale per row "
                                r"with a randomizer"),
    "inertia_scale": (lambda e: e, r"HoverBatchEnv\.inertia_scale is kernel state \(read-only\): set inertia_scale"),
    "drag_scale": (lambda e: e, r"HoverBatchEnv\.drag_scale is kernel state \(read-only\): set drag_scale per row "
                                r"with a randomizer"),
    "state": (lambda e: e.sensor, r"BatchSensorModel\.state is the sensor kernel's state \(read-only\): set the "
                                  r"turn-on biases through gyro_bias / accel_bias"),
    "count": (lambda e: e.sensor, r"BatchSensorModel\.count is the sensor kernel's state \(read-only\)"),
    "no_noise": (lambda e: e.sensor, r"BatchSensorModel\.no_noise is the sensor kernel's state \(read-only\)"),
}


@pytest.mark.parametrize("name", sorted(KERNEL_STATE))
def test_kernel_state_cannot_be_assigned_or_written(name):
    owner_of, pattern = KERNEL_STATE[name]
    texts = set()
    for n in (1, 3):
        env, ref = _fresh(n), _fresh(n)
        owner = owner_of(env)
        before = np.array(getattr(owner, name))
        # the audit's reproducers: a wrong shape (heap corruption on main), a wrong type, NaN
        for value in (np.ones((2, 4)), np.zeros(1), "x", np.full(before.shape, np.nan)):
            texts.add(_error(AttributeError, lambda v=value, o=owner: setattr(o, name, v)))
        view = getattr(owner, name)
        with pytest.raises(ValueError, match="read-only"):
            view[...] = 5
        assert not view.flags.writeable
        np.testing.assert_array_equal(getattr(owner, name), before)
        _same(_rollout(env), _rollout(ref))  # the refused writes changed nothing
    assert len(texts) == 1, texts
    assert re.search(pattern, texts.pop())


@pytest.mark.parametrize("name", ["pose_pos", "pose_vel", "pose_att", "gyro_bias", "accel_bias"])
def test_sensor_views_are_read_only(name):
    env = _fresh(3)
    with pytest.raises(ValueError, match="read-only"):
        getattr(env.sensor, name)[0] = np.nan


def test_external_wrench_views_are_read_only_and_the_setter_still_works():
    env, ref = _fresh(3), _fresh(3)
    for name in ("external_force", "external_torque"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(env, name)[0, 0] = np.nan
    _same(_rollout(env), _rollout(ref))
    env.external_force = [0.1, 0.0, 0.0]
    ref.set_external_wrench([0.1, 0.0, 0.0])
    _same(_rollout(env), _rollout(ref))


def test_single_env_state_is_a_copy_or_read_only():
    env = HoverEnv()
    env.reset(seed=0)
    speeds = env.rotor_speeds
    speeds[0] = 0.0  # a copy: the env's state is untouched
    assert env.rotor_speeds[0] != 0.0
    with pytest.raises(ValueError, match="read-only"):
        env.sensor.gyro_bias[0] = 1.0


# ---- D1: HoverBatchEnv.init_noise is checked like HoverEnv's ---------------------------------------------------------
@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf"), "a", True, np.True_, None, 1j, [1.0]])
def test_init_noise_checked_at_assignment_same_text_everywhere(value):
    texts = set()
    for make in (HoverEnv, lambda: HoverBatchEnv(1), lambda: HoverBatchEnv(3)):
        env = make()
        texts.add(_error(ValueError, lambda e=env: setattr(e, "init_noise", value)))
        assert env.init_noise == 1.0  # unchanged
    assert texts == {"init_noise must be a finite real number in [0, 10] (10: a start up to 1 m, 1 m/s, 30 deg, "
                     f"1 rad/s off hover), got {value!r} ({type(value).__name__})"}, texts


def test_refused_init_noise_changes_no_trajectory():
    env, ref = _fresh(3), _fresh(3)
    with pytest.raises(ValueError):
        env.init_noise = float("nan")
    env.reset(seed=4)
    ref.reset(seed=4)
    _same(_rollout(env), _rollout(ref))
    env.init_noise = np.float32(0.5)  # numpy reals accepted, stored as float
    assert type(env.init_noise) is float and env.init_noise == 0.5


# ---- D3: the setpoint getters hand out read-only views ---------------------------------------------------------------
@pytest.mark.parametrize("make", [lambda: _fresh(1), lambda: _fresh(3)], ids=["N1", "N3"])
def test_batch_setpoint_getter_is_read_only(make):
    env, ref = make(), make()
    with pytest.raises(ValueError, match="read-only"):
        env.setpoint[0, 2] = 5.0  # below the floor: the setter would refuse it
    with pytest.raises(ValueError, match="read-only"):
        env.setpoint[:, 1] = np.nan
    _same(_rollout(env), _rollout(ref))
    held = env.setpoint
    env.setpoint = [0.0, 0.0, -2.0]  # the setter copies in place: a view taken before follows it
    ref.setpoint = [0.0, 0.0, -2.0]
    np.testing.assert_array_equal(held, np.tile([0.0, 0.0, -2.0], (env.num_envs, 1)))
    _same(_rollout(env), _rollout(ref))


def test_single_setpoint_getter_is_read_only():
    env = HoverEnv()
    env.reset(seed=0)
    before = env.setpoint.copy()
    with pytest.raises(ValueError, match="read-only"):
        env.setpoint[2] = 5.0
    np.testing.assert_array_equal(env.setpoint, before)
    obs, reward, terminated, _, info = env.step(env.hover_action())
    assert not terminated and info["failure"] == ""


# ---- D2: a reset whose randomizer fails (or whose draws are refused) changes nothing ---------------------------------
class _FailOnce:
    """A randomizer that draws nothing, except at call ``bad`` where it returns ``draw`` (refused) or raises."""

    def __init__(self, bad: int, draw: Any = None) -> None:
        self.calls, self.bad, self.draw = 0, bad, draw

    def __call__(self, rows: np.ndarray, rngs: list[np.random.Generator]) -> dict[str, Any]:
        self.calls += 1
        if self.calls != self.bad:
            return {}
        if self.draw is None:
            raise RuntimeError("randomizer failed")
        return self.draw(rows.size)


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("seed", [9, None], ids=["seeded", "unseeded"])
@pytest.mark.parametrize(("draw", "kind", "pattern"), [
    (lambda k: {"mass_scale": -np.ones(k)}, ValueError, r"randomizer draw 'mass_scale' must be > 0 with shape"),
    (None, RuntimeError, r"randomizer failed"),
], ids=["refused", "raises"])
def test_failed_reset_changes_nothing(n, seed, draw, kind, pattern):
    env = HoverBatchEnv(n, wind="dryden-light", sensors="mocap_imu", randomizer=_FailOnce(2, draw))
    ref = HoverBatchEnv(n, wind="dryden-light", sensors="mocap_imu", randomizer=_FailOnce(0))
    env.reset(seed=3)
    ref.reset(seed=3)
    _same(_rollout(env, 5), _rollout(ref, 5))
    setpoint, noise, time = env.setpoint.copy(), env.init_noise, env.time.copy()
    text = _error(kind, lambda: env.reset(seed=seed, options={"setpoint": [0, 0, -3.0], "init_noise": 0.5}))
    assert re.fullmatch(pattern + ".*", text), text
    np.testing.assert_array_equal(env.setpoint, setpoint)  # the audit's reproducer: the set point was applied
    assert env.init_noise == noise
    np.testing.assert_array_equal(env.time, time)
    _same(_rollout(env, 10), _rollout(ref, 10))  # continues bitwise as if the failed reset never happened
    env.reset()  # the row generators are where they were (not advanced by the failed reset's draws)
    ref.reset()
    _same(_rollout(env, 10), _rollout(ref, 10))


# ---- D8: upper bounds for init_noise, the set point and max_position_error ------------------------------------------
BOUNDS = [
    ("init_noise", 1e300, r"init_noise must be a finite real number in \[0, 10\] \(10: a start up to 1 m, 1 m/s, "
                          r"30 deg, 1 rad/s off hover\), got 1e\+300"),
    ("init_noise", 1e6, r"init_noise must be a finite real number in \[0, 10\] .*, got 1000000.0"),
    ("init_noise", np.nextafter(10.0, 11.0), r"init_noise must be a finite real number in \[0, 10\] "),
    ("setpoint", [1e12, 0.0, -1.0], r"setpoint coordinates must be at most 10000 m in magnitude \(10 km from the "
                                    r"origin\), got \[1000000000000.0, 0.0, -1.0\]"),
    ("setpoint", [0.0, 0.0, -1e5], r"setpoint coordinates must be at most 10000 m in magnitude"),
    ("max_position_error", 1e300, r"max_position_error must be a finite real number in \(0, 1e\+09\] m \(1e\+09: "
                                  r"the SITL plant's 'no box'\), got 1e\+300"),
]


@pytest.mark.parametrize(("name", "value", "pattern"), BOUNDS, ids=[f"{n}={v!r}"[:40] for n, v, _ in BOUNDS])
def test_upper_bounds_one_line_same_text_everywhere(name, value, pattern):
    texts = set()
    for make in (HoverEnv, lambda **kw: HoverBatchEnv(1, **kw), lambda **kw: HoverBatchEnv(3, **kw)):
        with np.errstate(all="raise"):  # no overflow warning on the way to the error
            texts.add(_error(ValueError, lambda m=make: m(**{name: value})))
        env, ref = make(), make()
        env.reset(seed=0)
        ref.reset(seed=0)
        texts.add(_error(ValueError, lambda e=env: setattr(e, name, value)))  # the setters: same check
        if name != "max_position_error":
            texts.add(_error(ValueError, lambda e=env: e.reset(seed=1, options={name: value})))
        ref.reset(seed=1)
        env.reset(seed=1)
        obs, ref_obs = env.step(env.hover_action())[0], ref.step(ref.hover_action())[0]
        assert obs.tobytes() == ref_obs.tobytes()
    assert len(texts) == 1, texts
    assert re.fullmatch(pattern + ".*", texts.pop())


def test_upper_bounds_themselves_are_usable():
    env = HoverBatchEnv(3, init_noise=10.0, max_position_error=1e9, setpoint=[1e4, -1e4, -1e4])
    obs, _ = env.reset(seed=0)
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(env.single_observation_space.high))
    _, reward, _, _, info = env.step(env.hover_action())
    assert np.all(np.isfinite(reward)) and not np.any(info["failure"] == "diverged")


# ---- D7: vehicle vector fields refuse bool / complex / str, naming the field -----------------------------------------
VECTOR_FIELDS = [
    ("inertia", (True, True, True)), ("body_drag", (True, False, True)), ("inertia", ("a", "b", "c")),
    ("cop_offset", "abc"), ("inertia", (0.03 + 1j, 0.03, 0.06)), ("cop_offset", np.array([1j, 0, 0])),
    ("body_drag", None), ("inertia", [[0.03, 0.0], [0.03]]), ("cop_offset", np.array([True, False, True])),
]


@pytest.mark.parametrize(("field", "value"), VECTOR_FIELDS, ids=[f"{f}={v!r}"[:40] for f, v in VECTOR_FIELDS])
def test_vehicle_vector_fields_refuse_non_real_entries(field, value):
    import gymnasium as gym

    import fawtgym  # noqa: F401  (registers the env ids)

    vehicle = {"base": "s500", field: value}
    texts = {_error(ValueError, lambda: gym.make("fawtgym/Hover-v0", vehicle=vehicle)),
             _error(ValueError, lambda: HoverEnv(vehicle=vehicle)),
             _error(ValueError, lambda: HoverBatchEnv(1, vehicle=vehicle)),
             _error(ValueError, lambda: HoverBatchEnv(3, vehicle=vehicle))}
    assert texts == {f"vehicle field {field!r} must be real numbers (not bool, complex or str), got {value!r}"}, texts


def test_vehicle_vector_fields_accept_numpy_reals():
    env = HoverBatchEnv(1, vehicle={"base": "s500", "inertia": np.array([0.03, 0.03, 0.05], dtype=np.float32),
                                    "body_drag": np.array([1, 1, 2], dtype=np.int64), "cop_offset": [0, 0, -0.02]})
    assert env.preset.body_drag == (1.0, 1.0, 2.0) and type(env.preset.inertia[0]) is float


# ---- D9: reward_weights read-only, documented ValueErrors, draws named, step_async guards ---------------------------
def test_reward_weights_are_read_only_everywhere():
    import gymnasium as gym

    import fawtgym  # noqa: F401  (registers the env ids)

    texts = set()
    for env in (gym.make("fawtgym/Hover-v0").unwrapped, HoverEnv(), HoverBatchEnv(1), HoverBatchEnv(3)):
        with pytest.raises(TypeError):
            env.reward_weights["pos"] = 1e6  # was silently ignored (the kernel reads a copy)
        texts.add(_error(AttributeError, lambda e=env: setattr(e, "reward_weights", "x")))
        assert dict(env.reward_weights)["pos"] == 2.0
    assert texts == {"reward_weights is fixed at construction (the step kernels hold a copy): pass "
                     "reward_weights={...} to the constructor instead"}


@pytest.mark.parametrize(("kwargs", "text"), [
    ({"vehicle": 5}, "vehicle must be a preset name, a VehiclePreset, a mapping or a .yaml/.json path, got 5 (int)"),
    ({"vehicle": 1j}, "vehicle must be a preset name, a VehiclePreset, a mapping or a .yaml/.json path, got 1j "
                      "(complex)"),
    ({"wind": 5}, "wind must be a name, a WindModel or a mapping, got 5 (int)"),
    ({"wind": 2.5 + 0j}, "wind must be a name, a WindModel or a mapping, got (2.5+0j) (complex)"),
])
def test_bad_vehicle_or_wind_type_is_the_documented_value_error(kwargs, text):
    import gymnasium as gym

    import fawtgym  # noqa: F401  (registers the env ids)

    texts = {_error(ValueError, lambda: gym.make("fawtgym/Hover-v0", **kwargs)),
             _error(ValueError, lambda: HoverBatchEnv(1, **kwargs)),
             _error(ValueError, lambda: HoverBatchEnv(3, **kwargs))}
    assert texts == {text}


def test_mean_wind_accepts_numpy_bools():
    a = HoverBatchEnv(2, wind={"name": "dryden-light", "mean_wind": np.True_})
    b = HoverBatchEnv(2, wind={"name": "dryden-light", "mean_wind": True})
    a.reset(seed=0)
    b.reset(seed=0)
    _same(_rollout(a, 5), _rollout(b, 5))
    HoverBatchEnv(1, wind={"name": "dryden-light", "mean_wind": np.False_})


@pytest.mark.parametrize(("force", "torque"), [
    ((True, False, True), (0.0, 0.0, 0.0)), ((1j, 0, 0), (0.0, 0.0, 0.0)), ((0.0, 0.0, 0.0), ("a", 0, 0)),
    ((0.0, np.nan, 0.0), (0.0, 0.0, 0.0)), ((0.0, 0.0), (0.0, 0.0, 0.0)), ([[0.0], [0.0, 1.0]], (0.0, 0.0, 0.0)),
])
def test_external_wrench_refuses_non_real_entries(force, torque):
    texts = set()
    for make in (HoverEnv, lambda: HoverBatchEnv(1), lambda: HoverBatchEnv(3)):
        env, ref = make(), make()
        env.reset(seed=0)
        ref.reset(seed=0)
        text = _error(ValueError, lambda e=env: e.set_external_wrench(force, torque))
        texts.add(re.sub(r"\(3,\)( or \(\d, 3\))?", "(3,)", text))
        obs, ref_obs = env.step(env.hover_action())[0], ref.step(ref.hover_action())[0]
        assert obs.tobytes() == ref_obs.tobytes()  # the refused wrench changed nothing
    assert texts == {f"external wrench must be two (3,) arrays of finite real numbers (force NED [N], torque FRD "
                     f"[N m]), got {force!r}, {torque!r}"}, texts


DRAWS = [
    ({"mass_scale": "a"}, r"randomizer draw 'mass_scale' must be > 0 with shape \((\d),\) \(one per starting row\) of "
                          r"real numbers, got 'a' \(str, dtype <U1\)"),
    ({"mass_scale": [True] * 9}, r"randomizer draw 'mass_scale' must be > 0 .* of real numbers, got \[True"),
    ({"drag_scale": np.ones(9, dtype=complex)}, r"randomizer draw 'drag_scale' must be >= 0 .* of real numbers"),
    ({"wind": 5}, r"randomizer draw 'wind' must be a list of (\d) WindModel \(one per starting row\), got 5 \(int\)"),
    ({"wind": "fawt-50"}, r"randomizer draw 'wind' must be a list of (\d) WindModel"),
    # s500: idle / max thrust of 4 rotors k_T omega^2 (omega 88, 880 rad/s, k_T 1.15e-5) over the weight 1 kg * g
    ({"mass_scale": np.full(9, 5.0)}, rf"randomizer draw 'mass_scale' must be in "
                                      rf"\({4 * 1.15e-5 * 88**2 / 9.80665:.4g}, {4 * 1.15e-5 * 880**2 / 9.80665:.4g}\) "
                                      r"for vehicle 's500' "
                                      r"to hover \(weight between the rotors' idle and maximum thrust\), got "
                                      r"np.float64\(5.0\) for starting row 0"),
]


@pytest.mark.parametrize(("draw", "pattern"), DRAWS, ids=[repr(d)[:40] for d, _ in DRAWS])
def test_bad_randomizer_draws_name_the_key(draw, pattern):
    texts = set()
    for n in (1, 3):
        def randomizer(rows, rngs, n=n):
            return {k: (v[:n] if isinstance(v, (list, np.ndarray)) else v) for k, v in draw.items()}

        env = HoverBatchEnv(n, randomizer=randomizer)
        text = _error(ValueError, lambda e=env: e.reset(seed=0))
        assert re.fullmatch(pattern + ".*", text), text
        texts.add(text.split(", got ")[0].replace(f"({n},)", "(N,)").replace(f"list of {n} ", "list of N "))
    assert len(texts) == 1, texts  # the same text at N = 1 and N = 3 but for N and the value drawn


@pytest.mark.parametrize(("name", "call"), [
    ("setpoint", lambda e: setattr(e, "setpoint", [0.0, 0.0, -2.0])),
    ("set_external_wrench() called", lambda e: e.set_external_wrench((0.1, 0, 0))),
    ("set_external_wrench() called", lambda e: setattr(e, "external_force", (0.1, 0, 0))),
    ("init_noise", lambda e: setattr(e, "init_noise", 0.5)),
    ("max_steps", lambda e: setattr(e, "max_steps", 5)),
    ("max_position_error", lambda e: setattr(e, "max_position_error", 1.0)),
])
def test_setters_refuse_while_a_step_async_step_runs(name, call):
    env, ref = _fresh(3), _fresh(3)
    env.step_async(env.hover_action())
    text = _error(RuntimeError, lambda: call(env))
    prefix = name if name.endswith("called") else f"setting {name}"
    assert text == f"HoverBatchEnv: {prefix} while a step_async() step is running: call step_wait() first"
    got, want = env.step_wait(), ref.step(ref.hover_action())
    assert got[0].tobytes() == want[0].tobytes()
    _same(_rollout(env), _rollout(ref))  # nothing was applied
    call(env)  # allowed again after step_wait


def test_external_wrench_error_is_one_line_for_arrays():
    env = HoverBatchEnv(2)
    text = _error(ValueError, lambda: env.set_external_wrench(np.full((2, 3), np.nan), np.zeros((2, 3))))
    assert text.startswith("external wrench must be two (3,) or (2, 3) arrays of finite real numbers (force NED [N], "
                           "torque FRD [N m]), got array([[nan, nan, nan], [nan, nan, nan]]), array([[0., 0., 0.],")


@pytest.mark.parametrize("value", [(True, False, True), (1j, 0, 0), ("a", 0, 0), (0.0, np.nan, 0.0), (0.0, 0.0)])
@pytest.mark.parametrize("name", ["gyro_bias", "accel_bias"])
def test_sensor_bias_setters_refuse_non_real_entries(name, value):
    texts = set()
    for n in (1, 3):
        sensor = HoverBatchEnv(n, sensors="mocap_imu").sensor
        before = np.array(getattr(sensor, name))
        texts.add(_error(ValueError, lambda s=sensor: setattr(s, name, value)).replace(f"({n}, 3)", "(N, 3)"))
        np.testing.assert_array_equal(getattr(sensor, name), before)
    assert texts == {f"{name} must be 3 finite real numbers or (N, 3), got {value!r}"}, texts


# ---- the aero coefficients: the shared array cannot be replaced (an env would silently keep the old one) -------------
def test_aero_coefficients_cannot_be_replaced_and_refuse_bools():
    texts = set()
    for env in (HoverEnv(wind="fawt-50"), HoverBatchEnv(1, wind="fawt-50"), HoverBatchEnv(3, wind="fawt-50")):
        texts.add(_error(AttributeError, lambda e=env: setattr(e.aero, "coefficients", np.ones(8))))
        for name, value in (("k_d", True), ("k_r", np.True_), ("cop", (True, False, True)), ("body_drag", (1j, 0, 0))):
            with pytest.raises(ValueError, match=rf"AeroModel\.{name} must be "):
                setattr(env.aero, name, value)
    assert texts == {"AeroModel.coefficients is the array the env's step kernels read: edit it in place or assign "
                     "k_d, k_r, cop, body_drag (checked) instead"}
    env, ref = _fresh(2), _fresh(2)
    env.aero.k_d = 3 * env.aero.k_d  # the setters still act from the next step on
    ref.aero.coefficients[6] *= 3  # as does the documented in-place edit
    _same(_rollout(env), _rollout(ref))
