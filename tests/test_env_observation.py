"""The shared observation law (envs/observation.py): layout, clipping, batch rows, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.core.frames import euler_to_rot
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.observation import hover_observation, observation_bounds


def batch(n: int = 3) -> tuple[dict, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    meas = {"position": rng.normal(size=(n, 3)), "velocity": rng.normal(size=(n, 3)),
            "attitude": np.stack([euler_to_rot(*rng.normal(scale=0.3, size=3)) for _ in range(n)]),
            "angular_velocity": rng.normal(size=(n, 3))}
    return meas, rng.normal(size=(n, 3)), rng.uniform(size=(n, 4))


def test_layout_rows_and_clipping():
    low, high = observation_bounds(2.0, [0, -1, -1, -1], [1, 1, 1, 1])
    assert high[0] == 3.0 and high[3] == 30.0 and high[12] == 40.0 and low[15] == 0.0 and low[16] == -1.0
    meas, sp, act = batch()
    act[1, 0] = 1.5  # outside the action box: clipped to 1, as the env clips what it applies
    meas["velocity"][2, 1] = -45.0
    obs = hover_observation(meas, sp, act, low, high)
    assert obs.dtype == np.float32 and obs.shape == (3, 19)
    expected = np.concatenate([meas["position"] - sp, meas["velocity"], meas["attitude"][:, :, 0],
                               meas["attitude"][:, :, 1], meas["angular_velocity"], act], axis=1)
    np.testing.assert_array_equal(obs, np.clip(expected, low, high).astype(np.float32))
    assert obs[1, 15] == 1.0 and obs[2, 4] == -30.0
    one = hover_observation({k: v[1:2] for k, v in meas.items()}, sp[1:2], act[1:2], low, high)
    np.testing.assert_array_equal(one[0], obs[1])  # a row does not depend on the others


def test_env_space_is_the_bounds():
    env = HoverEnv(action_type="ctbr", max_position_error=1.5)
    low, high = observation_bounds(1.5, env.action_space.low, env.action_space.high)
    np.testing.assert_array_equal(env.observation_space.low, low)
    np.testing.assert_array_equal(env.observation_space.high, high)
    env.close()


def test_bad_input_is_one_clear_error():
    low, high = observation_bounds(2.0, [0] * 4, [1] * 4)
    for n in (1, 3):
        meas, sp, act = batch(n)
        meas["angular_velocity"][n - 1, 2] = np.nan
        with pytest.raises(ValueError, match=rf"entry 14 of row {n - 1} is nan; measurements, set point and last "
                                             "action must be finite"):
            hover_observation(meas, sp, act, low, high)
    meas, sp, act = batch(1)
    with pytest.raises(ValueError, match=r"takes a batch of N rows: position, velocity, angular_velocity \(N, 3\) and "
                                         r"attitude \(N, 3, 3\), got \(3,\), \(3,\), \(3,\) and \(3, 3\)"):
        hover_observation({k: v[0] for k, v in meas.items()}, sp[0], act[0], low, high)
