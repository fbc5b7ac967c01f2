"""Settings changed after construction: either they act from the next step or they raise (nothing silently ignored).

* aero coefficients ``k_d``, ``k_r``, ``cop``, ``body_drag``: live (an env with the value assigned flies as an env
  built with it); ``rotor_positions`` read-only.
* sensor ``sigma`` / ``pose_every``: read-only (derived from the sensor spec).
* ``HoverEnv.max_steps`` / ``max_position_error``: the batch env's checked properties.
* ``render()`` before ``reset()``: RuntimeError like ``step``.
"""

import copy
import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import fawtgym  # noqa: F401  (registers the env ids)
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.sensors import SensorModel, make_sensor_spec
from fawtgym.envs.sensors_batch import BatchSensorModel
from fawtgym.envs.vehicles import make_vehicle

NOMINAL = make_vehicle("s500")
#: (aero attribute, preset field, new value): each changes the wrench in a 50 % FAWT wind
CHANGES = [("k_d", "rotor_drag", NOMINAL.rotor_drag * 10.0),
           ("k_r", "rolling_moment", NOMINAL.rolling_moment * 50.0 + 1e-5),
           ("cop", "cop_offset", (0.01, -0.02, -0.05)),
           ("body_drag", "body_drag", (0.05, 0.04, 0.1))]


def _run(env: HoverBatchEnv, steps: int = 8) -> list[np.ndarray]:
    obs, _ = env.reset(seed=3)
    out = [obs]
    for _ in range(steps):
        obs, _, _, _, info = env.step(env.hover_action())
        out += [obs, info["truth"]["force"].copy(), info["truth"]["torque"].copy()]
    return out


@pytest.mark.parametrize(("attr", "field", "value"), CHANGES)
@pytest.mark.parametrize("n", [1, 3])
def test_aero_assignment_equals_an_env_built_with_the_value(attr, field, value, n):
    kw = dict(wind="fawt-50", sensors="none")
    built = HoverBatchEnv(n, vehicle=dataclasses.replace(NOMINAL, **{field: value}), **kw)
    assigned = HoverBatchEnv(n, **kw)
    nominal = HoverBatchEnv(n, **kw)
    setattr(assigned.aero, attr, value)
    a, b, c = _run(built), _run(assigned), _run(nominal)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))  # the change matters in this wind


def test_aero_in_place_edit_and_copies():
    kw = dict(wind="fawt-50", sensors="none")
    drag = np.array(NOMINAL.body_drag) * 3.0
    built = _run(HoverBatchEnv(1, vehicle=dataclasses.replace(NOMINAL, body_drag=tuple(drag)), **kw))
    env = HoverBatchEnv(1, **kw)
    env.aero.body_drag[:] *= 3.0  # in place: a view of the env's parameters
    assert all(np.array_equal(x, y) for x, y in zip(built, _run(env), strict=True))
    env2 = HoverBatchEnv(1, **kw)
    twin = copy.deepcopy(env2)
    twin.aero.body_drag = drag  # the copy's own parameters; the original keeps the nominal
    assert all(np.array_equal(x, y) for x, y in zip(built, _run(twin), strict=True))
    assert np.array_equal(env2.aero.body_drag, NOMINAL.body_drag)
    nominal = _run(HoverBatchEnv(1, **kw))
    assert all(np.array_equal(x, y) for x, y in zip(nominal, _run(env2), strict=True))


def test_aero_assignment_acts_from_the_next_step():
    env = HoverEnv(wind="fawt-50", init_noise=0.0)
    ref = HoverEnv(wind="fawt-50", init_noise=0.0)
    env.reset(seed=1)
    ref.reset(seed=1)
    a = env.hover_action()
    f0 = env.step(a)[4]["truth"]["force"].copy()
    ref.step(a)
    env.aero.k_d *= 10.0
    f1 = env.step(a)[4]["truth"]["force"]  # held over this step, computed after the last one: the new k_d
    r1 = ref.step(a)[4]["truth"]["force"]
    assert abs(f1[0]) > 3.0 * abs(r1[0]) > 0.0  # rotor drag dominates the horizontal force at hover
    assert abs(f0[0]) < 2.0 * abs(r1[0])


@pytest.mark.parametrize(("attr", "value", "match"), [
    ("k_d", -1e-4, r"AeroModel.k_d must be a finite number >= 0, got -0.0001"),
    ("k_r", float("nan"), r"AeroModel.k_r must be a finite number, got nan"),
    ("cop", (0.0, 0.0), r"AeroModel.cop must be 3 finite numbers, got \(0.0, 0.0\)"),
    ("body_drag", (0.1, -0.1, 0.1), r"AeroModel.body_drag must be 3 finite numbers >= 0"),
    ("k_d", "x", r"AeroModel.k_d must be a finite number >= 0, got 'x'")])
@pytest.mark.parametrize("n", [1, 3])
def test_bad_aero_values_raise_and_change_nothing(attr, value, match, n):
    env, ref = HoverBatchEnv(n, wind="fawt-50"), HoverBatchEnv(n, wind="fawt-50")
    before = env.aero.coefficients.copy()
    with pytest.raises(ValueError, match=match):
        setattr(env.aero, attr, value)
    assert np.array_equal(env.aero.coefficients, before)
    # what the step uses is unchanged too: the aero force of a windy flight equals an untouched env's, bitwise
    env.reset(seed=2)
    ref.reset(seed=2)
    for _ in range(5):
        got, want = env.step(env.hover_action())[4], ref.step(ref.hover_action())[4]
        assert got["truth"]["force"].tobytes() == want["truth"]["force"].tobytes()
        assert got["truth"]["torque"].tobytes() == want["truth"]["torque"].tobytes()


def test_rotor_positions_are_read_only():
    env = HoverEnv()
    with pytest.raises(AttributeError, match="rotor_positions is the vehicle's geometry.*vehicle preset"):
        env.aero.rotor_positions = np.zeros((4, 3))
    with pytest.raises(ValueError, match="read-only"):
        env.aero.rotor_positions[0, 0] = 1.0
    twin = copy.deepcopy(env)
    with pytest.raises(ValueError, match="read-only"):
        twin.aero.rotor_positions[0, 0] = 1.0


@pytest.mark.parametrize("n", [1, 3])
def test_sensor_settings_are_read_only(n):
    env = HoverBatchEnv(n, sensors="mocap_imu")
    message = r"BatchSensorModel.{} is fixed at construction .* SensorSpec"
    with pytest.raises(AttributeError, match=message.format("pose_every")):
        env.sensor.pose_every = 4
    with pytest.raises(AttributeError, match=message.format("sigma")):
        env.sensor.sigma = env.sensor.sigma * 100
    for sensor in (env.sensor, copy.deepcopy(env).sensor):
        with pytest.raises(ValueError, match="read-only"):
            sensor.sigma[:] *= 100
    single = SensorModel(make_sensor_spec("mocap_imu"), 0.01)
    with pytest.raises(AttributeError, match=message.format("pose_every")):
        single.pose_every = 4
    # the per-sample sigmas read the one sigma array the kernel reads, and cannot be assigned either
    names = ("sig_pos", "sig_vel", "sig_att", "sig_rate", "sig_acc", "sig_gyro", "sig_mag")
    assert [getattr(env.sensor, k) for k in names] == env.sensor.sigma.tolist()
    assert [getattr(single, k) for k in names] == BatchSensorModel("mocap_imu", 0.01, 1).sigma.tolist()
    for model in (env.sensor, single):
        with pytest.raises(AttributeError, match=message.format("sig_pos")):
            model.sig_pos = 1.0


def test_max_steps_and_box_of_hover_env_take_effect():
    env = HoverEnv(init_noise=0.0)
    env.reset(seed=0)
    env.max_steps = 3
    assert env.max_steps == 3
    flags = [env.step(env.hover_action())[2:4] for _ in range(3)]
    assert flags == [(False, False), (False, False), (False, True)]
    env.reset(seed=0)
    env.max_steps = 1000
    env.set_external_wrench((20.0, 0.0, 0.0))
    env.max_position_error = 0.05
    assert env.max_position_error == 0.05
    steps, terminated, truncated = 0, False, False
    while not (terminated or truncated) and steps < 100:
        _, _, terminated, truncated, info = env.step(env.hover_action())
        steps += 1
    assert terminated and info["failure"] == "out_of_bounds" and steps < 20  # a 2 m box would take far longer


@pytest.mark.parametrize(("attr", "value", "match"), [
    ("max_steps", 0, r"max_steps must be an int in \[1, 2\*\*52\] \(exact as a float64\), got 0"),
    ("max_steps", 2.5, r"max_steps must be an int in \[1, 2\*\*52\] .*, got 2.5"),
    ("max_steps", True, r"max_steps must be an int in \[1, 2\*\*52\] .*, got True"),
    ("max_steps", 2**52 + 1, r"max_steps must be an int in \[1, 2\*\*52\] .*, got 4503599627370497"),
    ("max_position_error", -1.0, r"max_position_error must be a finite real number in \(0, 1e\+09\] m .*, got -1.0 "
                                 r"\(float\)"),
    ("max_position_error", float("inf"), r"max_position_error must be a finite real number in \(0, 1e\+09\] m .*, "
                                         r"got inf \(float\)")])
def test_bad_max_steps_and_box_raise_alike(attr, value, match):
    for env in (HoverEnv(), HoverBatchEnv(3)):
        before = getattr(env, attr)
        with pytest.raises(ValueError, match=f"^{match}$"):
            setattr(env, attr, value)
        assert getattr(env, attr) == before


@pytest.mark.parametrize("render_mode", ["rgb_array", None])
def test_render_before_reset_raises(render_mode):
    env = HoverEnv(render_mode=render_mode)
    with pytest.raises(RuntimeError, match=r"^HoverEnv.render\(\) called before reset\(\): call reset\(\) first$"):
        env.render()
    made = gym.make("fawtgym/Hover-v0", render_mode="rgb_array", disable_env_checker=True)
    with pytest.raises(RuntimeError, match="render\\(\\) called before reset\\(\\)"):
        made.render()
