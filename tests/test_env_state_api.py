"""User-facing state of the env: set point, external wrench timing, sensor biases, reset options, pickling."""

import copy
import pickle

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.wind import make_wind


def test_setpoint_assignment_is_validated_and_used():
    env = HoverEnv(init_noise=0.0)
    env.reset(seed=0)
    env.setpoint = [1.5, 0.0, -1.0]  # a list is fine
    obs = env.step(env.hover_action())[0]
    assert obs[2] == pytest.approx(-0.5, abs=1e-3)  # z error against the new set point
    with pytest.raises(ValueError, match="setpoint"):
        env.setpoint = [0.0, float("nan"), 0.0]
    with pytest.raises(ValueError, match="setpoint"):
        env.reset(options={"setpoint": [1.0, 2.0]})


def test_external_wrench_acts_from_the_next_step():
    env = HoverEnv(init_noise=0.0)
    _, info = env.reset(seed=0)
    env.set_external_wrench((2.0, 0.0, 0.0))
    _, _, _, _, info = env.step(env.hover_action())
    assert info["truth"]["velocity"][0] > 0.015  # 2 N on 1 kg for 10 ms
    assert info["truth"]["force"][0] == pytest.approx(2.0, abs=0.05)
    env.set_external_wrench()  # removed: the next step feels only the (tiny) drag
    v0 = info["truth"]["velocity"][0]
    _, _, _, _, info = env.step(env.hover_action())
    assert abs(info["truth"]["velocity"][0] - v0) < 0.002
    assert abs(info["truth"]["force"][0]) < 0.05

    batch = HoverBatchEnv(2, init_noise=0.0)
    batch.reset(seed=0)
    batch.set_external_wrench(np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    _, _, _, _, binfo = batch.step(batch.hover_action())
    # the batch env's row and the single env: two implementations of one law over one step of 10 physics steps
    # (tests/_tolerance.py), at the scale of the velocity changes that cancel at hover (g dt)
    assert_same_law(binfo["truth"]["velocity"][0], _single_velocity_after_wrench(), scale=9.80665 * batch.dt,
                    steps=batch.n_substeps, what="velocity after the wrench")
    assert abs(binfo["truth"]["velocity"][1, 0]) < 1e-6


def _single_velocity_after_wrench():
    env = HoverEnv(init_noise=0.0)
    env.reset(seed=0)
    env.set_external_wrench((2.0, 0.0, 0.0))
    return env.step(env.hover_action())[4]["truth"]["velocity"]


def test_sensor_bias_assignment_takes_effect():
    env = HoverEnv(init_noise=0.0, sensors="mocap_imu")
    env.reset(seed=0)
    env.sensor.gyro_bias = [1.0, -1.0, 0.5]
    info = env.step(env.hover_action())[4]
    err = info["measurement"]["gyro"] - info["truth"]["angular_velocity"]
    np.testing.assert_allclose(err, [1.0, -1.0, 0.5], atol=0.1)
    with pytest.raises(ValueError, match="gyro_bias"):
        env.sensor.gyro_bias = [1.0, 2.0]


@pytest.mark.parametrize("bad", [float("nan"), -1.0, "x"])
def test_reset_init_noise_is_validated(bad):
    env = HoverEnv()
    with pytest.raises(ValueError, match="init_noise"):
        env.reset(seed=0, options={"init_noise": bad})


def test_batch_env_list_seeds_are_reproducible_with_noisy_sensors():
    def run():
        env = HoverBatchEnv(3, sensors="mocap_imu")
        obs, _ = env.reset(seed=[7, 8, 9])
        out = [obs]
        for _ in range(5):
            out.append(env.step(env.hover_action())[0])
        return np.array(out)

    np.testing.assert_array_equal(run(), run())


def test_env_deepcopy_and_pickle_continue_identically():
    env = HoverEnv(wind="fawt-50", sensors="mocap_imu")
    env.reset(seed=3)
    a = env.hover_action()
    for _ in range(5):
        env.step(a)
    twins = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    ref = [env.step(a) for _ in range(5)]
    for twin in twins:
        got = [twin.step(a) for _ in range(5)]
        for (o1, r1, *_), (o2, r2, *_) in zip(ref, got, strict=True):
            np.testing.assert_array_equal(o1, o2)
            assert r1 == r2


def test_stepped_wind_pickles():
    wind = make_wind("fawt-50")
    wind.reset(1, seed=0)
    pts, vel = np.tile([1.5, 0.0, -1.5], (1, 5, 1)), np.zeros((1, 3))
    wind.step(0.01, 0.01, pts, vel)
    twin = pickle.loads(pickle.dumps(wind))
    np.testing.assert_array_equal(twin.step(0.02, 0.01, pts, vel), wind.step(0.02, 0.01, pts, vel))
