"""Per-row reset of the PX4 agents: a reset row flies exactly as a fresh agent, the other rows are untouched.

The agents are replayed on recorded infos of a 3-row batched env (open loop), so the comparison is of the
agents' computations alone: agent A (3 rows) resets rows 0 and 2 at step K; a fresh agent B built on those two
rows at step K must give the same actions (to 1e-9, relative; the same law on the same rows), and A's row 1
must equal, bitwise, an agent C that was never reset partially (the same code path).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from _env_helpers import record_px4_batch

from fawtgym.agents.spec import make_agent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.observers import observer_names

AGENTS = ["px4"] + [f"px4+{o}" for o in observer_names()]
STEPS, RESET_AT = 60, 23  # 23: an odd step, so the reset rows' 100 Hz position loop runs out of phase


def take_rows(info: Mapping[str, Any], idx: np.ndarray) -> dict[str, Any]:
    """The rows ``idx`` of a batched info dict (nested dicts of (N, ...) arrays)."""
    out: dict[str, Any] = {}
    for k, v in info.items():
        if isinstance(v, Mapping):
            out[k] = take_rows(v, idx)
        elif isinstance(v, np.ndarray) and v.ndim >= 1:
            out[k] = v[idx]
        else:
            out[k] = v
    return out


@pytest.fixture(scope="module")
def recorded() -> list[dict[str, Any]]:
    """Infos of a 3-row env flown by PX4 in FAWT-50 wind with motion-capture + IMU sensors (fan on at 0.05 s)."""
    return record_px4_batch([3, 4, 5], on_time=0.05, steps=STEPS)


@pytest.mark.parametrize("name", AGENTS)
def test_reset_rows_equals_fresh_agent(name: str, recorded: list[dict[str, Any]]) -> None:
    env = HoverBatchEnv(num_envs=3, sensors="mocap_imu", control_rate=200.0)
    a, c = make_agent(name, env), make_agent(name, env)
    b = make_agent(name, env)
    mask = np.array([True, False, True])
    sub = np.flatnonzero(mask)
    a.reset(recorded[0])
    c.reset(recorded[0])
    for k in range(RESET_AT):
        assert np.array_equal(a.act(None, recorded[k]), c.act(None, recorded[k]))
    a.reset(recorded[RESET_AT], rows=mask)
    b.reset(take_rows(recorded[RESET_AT], sub))
    for k in range(RESET_AT, STEPS):
        act_a, act_c = a.act(None, recorded[k]), c.act(None, recorded[k])
        act_b = b.act(None, take_rows(recorded[k], sub))
        np.testing.assert_allclose(act_a[sub], act_b, rtol=1e-9, atol=1e-12, err_msg=f"{name} step {k}")
        assert np.array_equal(act_a[1], act_c[1]), f"{name}: untouched row changed at step {k}"
        fa, ta = a.disturbance_estimate()
        fb, tb = b.disturbance_estimate()
        for ea, eb in ((fa, fb), (ta, tb)):
            assert (ea is None) == (eb is None)
            if ea is not None:
                np.testing.assert_allclose(ea[sub], eb, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(eb).max()))
    env.close()


def test_reset_rows_validation() -> None:
    env = HoverBatchEnv(num_envs=2, sensors="mocap_imu", control_rate=200.0)
    _, info = env.reset(seed=0)
    agent = make_agent("px4+ffts_eso", env)
    with pytest.raises(ValueError, match="earlier full reset"):
        agent.reset(info, rows=np.array([True, False]))
    agent.reset(info)
    for bad in (np.array([1, 0]), np.array([True]), [True, False, True]):
        with pytest.raises(ValueError, match="bool"):
            agent.reset(info, rows=bad)
    before = agent.act(None, info)
    agent.reset(info, rows=np.array([False, False]))  # no-op
    assert np.array_equal(agent.act(None, info), make_twin_after(agent, info, before))
    env.close()


def make_twin_after(agent: Any, info: Mapping[str, Any], first: np.ndarray) -> np.ndarray:
    """The second action of a fresh twin of ``agent`` fed the same info twice (what a no-op reset must give)."""
    from fawtgym.agents.spec import make_agent as build

    twin = build("px4+ffts_eso", HoverBatchEnv(num_envs=2, sensors="mocap_imu", control_rate=200.0))
    twin.reset(info)
    assert np.array_equal(twin.act(None, info), first)
    return twin.act(None, info)


def test_crashed_row_flies_on_after_autoreset() -> None:
    """Row 0 is pushed out of the box, the env resets it, the agent resets that row: it then hovers as well as a
    fresh vehicle (calm air), while row 1 never notices."""
    env = HoverBatchEnv(num_envs=2, sensors="mocap_imu", control_rate=200.0, episode_seconds=20.0, init_noise=0.0)
    agent = make_agent("px4+ffts_eso", env)
    obs, info = env.reset(seed=0)
    agent.reset(info)
    env.set_external_wrench(force_ned=[[30.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    ended = np.zeros(2, dtype=bool)
    crashed_at = None
    errors = []
    for k in range(1200):
        obs, _, term, trunc, info = env.step(agent.act(obs, info))
        if ended.any():
            agent.reset(info, rows=ended)
        if term[0] and crashed_at is None:
            crashed_at = k
            env.set_external_wrench()
        assert not term[1]
        ended = term | trunc
        if crashed_at is not None and k > crashed_at + 200:
            errors.append(np.linalg.norm(info["truth"]["position"] - env.setpoint, axis=1))
    assert crashed_at is not None
    err = np.array(errors)
    assert err[:, 0].max() < 0.05, err[:, 0].max()
    assert err[:, 1].max() < 0.05
    env.close()
