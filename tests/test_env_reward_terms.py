"""``info["reward_terms"]``: the reward's terms, the same in the single and the batched env (row by row)."""

import math

import gymnasium as gym
import numpy as np
import pytest
from _tolerance import assert_same_law, same_law_tol

import fawtgym  # noqa: F401  (registers the ids)
from fawtgym.envs.hover_batch_env import HoverBatchEnv

TERMS = ("pos", "vel", "att", "rate", "action", "failure")
OPTIONS = {"wind": "calm", "sensors": "none", "episode_seconds": 0.5, "init_noise": 1.0}


def test_reward_is_built_from_its_terms_in_both_envs():
    env = gym.make("fawtgym/Hover-v0", **OPTIONS)
    batch = HoverBatchEnv(num_envs=3, **OPTIONS)
    _, info = env.reset(seed=4)
    _, binfo = batch.reset(seed=4)
    assert set(info["reward_terms"]) == set(TERMS) == set(binfo["reward_terms"])
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = env.unwrapped.hover_action() + rng.uniform(-0.05, 0.05, 4).astype(np.float32)
        _, reward, term, _, info = env.step(a)
        _, breward, bterm, _, binfo = batch.step(np.vstack([a, batch.hover_action()[1:]]))
        t = info["reward_terms"]
        assert all(v >= 0.0 for v in t.values())
        expected = -t["failure"] if term else math.exp(-sum(t[k] for k in TERMS[:5]))
        assert reward == pytest.approx(expected, rel=1e-12)
        for k in TERMS:  # row 0 of the batch is the single env (same seed, same actions)
            assert binfo["reward_terms"][k].shape == (3,)
            # two implementations of the reward law over up to 20 steps: absolute tolerance scaled by the largest
            # term (tests/_tolerance.py), not a fixed 1e-15 that a zero-ish term's rounding can exceed
            tol = same_law_tol(scale=max(t.values()), steps=20)
            assert binfo["reward_terms"][k][0] == pytest.approx(t[k], rel=1e-9, abs=tol)
        bt = binfo["reward_terms"]
        np.testing.assert_allclose(breward[~bterm], np.exp(-sum(bt[k] for k in TERMS[:5]))[~bterm], rtol=1e-12)
    batch.close()
    env.close()


def test_failure_term_is_the_penalty():
    env = gym.make("fawtgym/Hover-v0", wind="calm", init_noise=0.0, max_position_error=0.05,
                   reward_weights={"failure": 3.0})
    env.reset(seed=0)
    term = False
    while not term:
        _, reward, term, trunc, info = env.step(np.zeros(4, dtype=np.float32))  # motors off: it falls
        assert not trunc
    assert info["failure"] and reward == -3.0 and info["reward_terms"]["failure"] == 3.0


def test_terms_follow_the_documented_table():
    """Each term recomputed from info["measurement"], the set point and the actions with the table's formulas
    (envs/hover_env.py module docstring), with non-default weights; noisy sensors so the terms use measurements."""
    weights = {"pos": 1.5, "vel": 0.3, "att": 2.0, "rate": 0.07, "action": 0.9}
    env = gym.make("fawtgym/Hover-v0", wind="fawt-50", sensors="mocap_imu", init_noise=1.0, reward_weights=weights)
    _, info = env.reset(seed=2)
    prev = env.unwrapped.hover_action().astype(float)
    rng = np.random.default_rng(1)
    for _ in range(10):
        a = np.clip(prev + rng.uniform(-0.05, 0.05, 4), 0.0, 1.0).astype(np.float32)
        _, _, term, _, info = env.step(a)
        assert not term
        m, t = info["measurement"], info["reward_terms"]
        e = m["position"] - info["setpoint"]
        phi = math.acos(np.clip((np.trace(m["attitude"]) - 1.0) / 2.0, -1.0, 1.0))
        du = a.astype(float) - prev
        want = {"pos": weights["pos"] * e @ e, "vel": weights["vel"] * m["velocity"] @ m["velocity"],
                "att": weights["att"] * phi**2, "rate": weights["rate"] * m["angular_velocity"] @ m["angular_velocity"],
                "action": weights["action"] * du @ du, "failure": 0.0}
        # terms are sums of non-negative squares (scale: the term itself); the attitude term goes through
        # acos, whose rounding grows as 1 / sin(phi): d(phi^2) / phi^2 ~ 3 eps / (phi sin phi)
        cond = {k: 1.0 for k in TERMS}
        cond["att"] = max(1.0, 3.0 / max(phi * math.sin(phi), 1e-12))
        for k in TERMS:
            assert_same_law(t[k], want[k], scale=abs(want[k]), cond=cond[k], what=k)
        prev = a.astype(float)
    env.close()
