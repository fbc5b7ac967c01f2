"""fawtgym.eval.sharded.ShardedLoop: N vehicles as one env per thread, each with its own agent."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.agents.px4_agent import PX4ObserverAgent
from fawtgym.core.checks import shown
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.eval.sharded import ShardedLoop, shard_sizes

KW = dict(vehicle="s500", wind="fawt-50", control_rate=200.0, physics_rate=1000.0, episode_seconds=1e6,
          init_noise=0.5)


def _agent(env):
    return PX4ObserverAgent.for_env(env, observer="ffts_eso")


@pytest.mark.parametrize("sizes", [(3, 2), (2, 2, 1), (5,)])
def test_sharded_loop_flies_the_plain_loops_vehicles_bit_for_bit(sizes):
    """Shard k's rows are the N-row env's rows offset_k.. (seeded alike): with exact sensors the stacked
    observations and true states equal the plain loop's, bit for bit, after every block (rows are independent)."""
    n = sum(sizes)
    assert shard_sizes(n, len(sizes)) == list(sizes)
    env = HoverBatchEnv(n, sensors="none", **KW)
    agent = _agent(env)
    with ShardedLoop.build(n, _agent, len(sizes), sensors="none", **KW) as loop:
        assert [e.num_envs for e in loop.envs] == list(sizes) and loop.num_envs == n
        obs, info = env.reset(seed=7)
        agent.reset(info)
        loop.reset(seed=7)
        np.testing.assert_array_equal(loop.observations(), obs)
        for _ in range(3):
            for _ in range(4):
                obs, _, _, _, info = env.step(agent.act(obs, info))
            loop.step(4)
            np.testing.assert_array_equal(loop.observations(), obs)
            np.testing.assert_array_equal(loop.info("truth", "position"), info["truth"]["position"])


def _plain_loop(env, agent, steps, seed):
    """The evaluation runner's protocol: a row restarted by the env (next step) is reset in the agent too."""
    same_step = env.autoreset_mode.value == "SameStep"
    obs, info = env.reset(seed=seed)
    agent.reset(info)
    ended = None
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(agent.act(obs, info))
        if same_step:
            ended = terminated | truncated
        if ended is not None and ended.any():
            agent.reset(info, rows=ended)
        ended = None if same_step else terminated | truncated
    return obs, info


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_restarted_rows_restart_in_the_agent_too(mode):
    """Episodes of 0.3 s (60 steps at 200 Hz): every row restarts within 100 steps, in the env and in its agent,
    as the runner restarts them; the shards fly the plain loop's trajectories bit for bit across the restarts."""
    kw = dict(KW, episode_seconds=0.3, sensors="none", autoreset_mode=mode)
    env = HoverBatchEnv(5, **kw)
    obs, info = _plain_loop(env, _agent(env), 100, seed=11)
    with ShardedLoop.build(5, _agent, 2, **kw) as loop:
        loop.reset(seed=11)
        loop.step(40)
        loop.step(60)
        np.testing.assert_array_equal(loop.observations(), obs)
        np.testing.assert_array_equal(loop.info("truth", "position"), info["truth"]["position"])


def test_noisy_sensors_start_the_same_vehicles_in_the_same_wind():
    """With noisy sensors the shards draw other samples of the per-step noise (one stream per env), but the
    vehicles start where the N-row env's do and meet the same wind."""
    env = HoverBatchEnv(4, sensors="mocap_imu", **KW)
    _, info = env.reset(seed=3)
    with ShardedLoop.build(4, _agent, 2, sensors="mocap_imu", **KW) as loop:
        loop.reset(seed=3)
        np.testing.assert_array_equal(loop.info("truth", "position"), info["truth"]["position"])
        np.testing.assert_array_equal(loop.info("truth", "force"), info["truth"]["force"])
        loop.step(3)
        assert np.all(np.isfinite(loop.observations()))


@pytest.mark.parametrize("n, shards, text", [
    (0, 1, "n must be an int >= 1 (the number of vehicles), got 0"),
    (2.0, 1, "n must be an int >= 1 (the number of vehicles), got 2.0"),
    (3, 4, "shards must be an int in [1, n = 3] (envs of at least one row each), got 4"),
    (3, 0, "shards must be an int in [1, n = 3] (envs of at least one row each), got 0"),
    (3, True, "shards must be an int in [1, n = 3] (envs of at least one row each), got True"),
])
def test_bad_sizes_are_refused_with_one_line(n, shards, text):
    with pytest.raises(ValueError) as exc:
        ShardedLoop.build(n, _agent, shards)
    assert str(exc.value) == text


def test_bad_use_is_refused_with_one_line():
    with pytest.raises(ValueError, match=r"^ShardedLoop\.build sets physics_threads=0 itself"):
        ShardedLoop.build(2, _agent, 1, physics_threads=2)
    threaded = HoverBatchEnv(2, physics_threads=2)
    with pytest.raises(ValueError) as exc:
        ShardedLoop([threaded], [_agent(threaded)])
    assert str(exc.value) == ("ShardedLoop: env 0 runs its physics on 2 threads; build each shard with "
                              "HoverBatchEnv(..., physics_threads=0) (its physics on the shard's own thread)")
    with pytest.raises(ValueError, match="one agent per env"):
        ShardedLoop([HoverBatchEnv(1, physics_threads=0)], [])
    with ShardedLoop.build(2, _agent, 2) as loop:
        with pytest.raises(RuntimeError, match=r"before reset\(\)"):
            loop.step(1)
        with pytest.raises(RuntimeError, match=r"before reset\(\)"):
            loop.observations()
        for bad in (-1, 1.5, True):
            with pytest.raises(ValueError, match=f"steps must be an int >= 0, got {bad!r}"):
                loop.step(bad)
        with pytest.raises(ValueError, match="seed must be an int >= 0, got -1"):
            loop.reset(seed=-1)


@pytest.mark.parametrize("failing_rows", [2, 1])
def test_a_shards_error_reaches_the_caller(failing_rows):
    """An agent that raises, on the calling thread's shard (2 rows) or on the other thread's (1 row): step()
    re-raises its error once both shards have stopped."""
    class Agent:
        def __init__(self, env):
            self.inner, self.broken = _agent(env), env.num_envs == failing_rows

        def reset(self, info):
            self.inner.reset(info)

        def act(self, obs, info):
            if self.broken:
                raise FloatingPointError(f"agent of {failing_rows} rows diverged")
            return self.inner.act(obs, info)

    with ShardedLoop.build(3, Agent, 2) as loop:
        loop.reset(seed=0)
        with pytest.raises(FloatingPointError, match=f"agent of {failing_rows} rows diverged"):
            loop.step(2)


def test_a_closed_loop_and_a_closed_env_refuse_to_step():
    loop = ShardedLoop.build(2, _agent, 2)
    loop.reset(seed=0)
    loop.close()
    for call in (lambda: loop.step(1), lambda: loop.reset(seed=0)):
        with pytest.raises(RuntimeError, match=r"after close\(\): build a new loop"):
            call()
    env = HoverBatchEnv(2)
    env.reset(seed=0)
    env.close()
    for call in (lambda: env.step(env.hover_action()), lambda: env.reset(seed=0)):
        with pytest.raises(RuntimeError) as exc:
            call()
        assert str(exc.value) == "the env was closed: step(), reset() and render() need a new env"


def test_num_envs_is_bounded():
    for bad in (0, 10**400, 10**6 + 1, True, 2.0):
        with pytest.raises(ValueError) as exc:
            HoverBatchEnv(bad)
        assert str(exc.value) == f"num_envs must be an int in [1, 1000000], got {shown(bad)}"
