"""The env step's checked-once paths compute the same law as the checked public calls (bitwise), and raise the
same errors before anything changes."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.wind import make_wind


@pytest.mark.parametrize("name", ["calm", "fawt-50", "dryden-light", "gust-1cos"])
def test_wind_step_trusted_equals_step(name: str) -> None:
    a = make_wind(name)
    a.reset(3, seed=7)
    b = copy.deepcopy(a)
    rng = np.random.default_rng(0)
    for k in range(40):
        points = rng.normal(size=(3, 5, 3)) + np.array([0.0, 0.0, -1.5])
        vel = rng.normal(size=(3, 3))
        t = 0.005 * (k + 1)
        np.testing.assert_array_equal(a.step(t, 0.005, points, vel), b.step_trusted(t, 0.005, points, vel))


def test_wind_step_trusted_still_finds_non_finite() -> None:
    wind = make_wind("fawt-50")
    wind.reset(1, seed=0)
    points = np.zeros((1, 5, 3))
    points[0, 2, 1] = np.nan
    with pytest.raises(ValueError, match="points_ned must be finite"):
        wind.step_trusted(0.005, 0.005, points, np.zeros((1, 3)))


@pytest.mark.parametrize("n", [1, 3])
def test_nan_action_raises_before_any_change(n: int) -> None:
    env = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu", init_noise=0.5)
    env.reset(seed=3)
    before = copy.deepcopy(env)
    a = env.hover_action().astype(float)
    a[n - 1, 2] = np.inf
    with pytest.raises(ValueError, match=rf"actions\[{n - 1}, 2\] is inf; every action entry must be finite"):
        env.step(a)
    good = env.hover_action()
    out, ref = env.step(good), before.step(good)
    np.testing.assert_array_equal(out[0], ref[0])
    np.testing.assert_array_equal(out[1], ref[1])


def test_single_env_nan_action_message() -> None:
    env = HoverEnv(wind="fawt-50")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"^action\[3\] is nan; every action entry must be finite"):
        env.step(np.array([0.5, 0.5, 0.5, np.nan], dtype=np.float32))


def test_info_arrays_are_not_overwritten_by_later_steps() -> None:
    env = HoverBatchEnv(2, wind="fawt-50", sensors="mocap_imu", init_noise=0.5)
    env.reset(seed=1)
    _, _, _, _, info = env.step(env.hover_action())
    saved = copy.deepcopy(info)
    for _ in range(5):
        env.step(env.hover_action())

    def same(x: object, y: object) -> None:
        if isinstance(x, dict):
            assert isinstance(y, dict) and x.keys() == y.keys()
            for key in x:
                same(x[key], y[key])
        else:
            np.testing.assert_array_equal(x, y)

    same(info, saved)


@pytest.mark.parametrize("wind", ["fawt-50", "dryden-moderate"])
def test_episode_after_a_reset_equals_a_fresh_env(wind: str) -> None:
    """The gust filters' step matrices are kept across episodes (computed once per env): a second episode is
    bitwise the first episode of a fresh env with the same seed."""
    used = HoverBatchEnv(2, wind=wind, sensors="mocap_imu", init_noise=0.5)
    used.reset(seed=4)
    for _ in range(30):
        used.step(used.hover_action())
    fresh = HoverBatchEnv(2, wind=wind, sensors="mocap_imu", init_noise=0.5)
    obs_a, _ = used.reset(seed=9)
    obs_b, _ = fresh.reset(seed=9)
    np.testing.assert_array_equal(obs_a, obs_b)
    for _ in range(30):
        a, b = used.step(used.hover_action()), fresh.step(fresh.hover_action())
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[4]["truth"]["wind"], b[4]["truth"]["wind"])
