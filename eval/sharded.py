"""The closed loop of N vehicles on every core: one :class:`HoverBatchEnv` of N / k rows per thread.

A plain batched loop (one ``HoverBatchEnv(N)``, one batch-first agent) runs MuJoCo's physics on one thread per
core, but the env's own kernels and the agent run on the calling thread between two rollouts while the other cores
wait.  :class:`ShardedLoop` instead flies the same N vehicles as k envs (shards) of about N / k rows, each built with
``physics_threads=0`` (its physics on the thread that steps it) and flown by its own agent in its own loop on its
own thread (the calling thread flies shard 0).  The compiled kernels release the GIL, so every core runs physics,
env kernels and agents alike, with no hand-off inside a step.  On the 2-vCPU VM of docs/performance.md it reaches
~0.9 of the physics-only ceiling at N = 1024, where the plain loop reaches ~0.78 (``fawtgym bench closed-loop``).

Shard k's rows are rows ``offset_k``.. of the N-row env, seeded alike (``reset(seed=s)`` seeds row i with s + i: the
same initial states and wind); with exact sensors each row's trajectory is the N-row env's, bit for bit (rows are
independent).  Noisy sensors draw their per-step noise from one stream per env (HoverBatchEnv's seeding), so the
shards fly other samples of the same noise.

Example::

    from fawtgym.agents.px4_agent import PX4ObserverAgent
    from fawtgym.eval.sharded import ShardedLoop

    with ShardedLoop.build(1024, lambda env: PX4ObserverAgent.for_env(env, observer="ffts_eso"),
                           wind="fawt-50", sensors="mocap_imu", control_rate=200.0) as loop:
        loop.reset(seed=0)
        loop.step(200)                      # 1 s of flight of every vehicle
        positions = loop.info("truth", "position")   # (1024, 3)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from fawtgym.core.checks import shown


def shard_sizes(n: int, shards: int) -> list[int]:
    """Rows of each of ``shards`` envs flying ``n`` vehicles (as even as can be; the larger ones first)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an int >= 1 (the number of vehicles), got {shown(n)}")
    if isinstance(shards, bool) or not isinstance(shards, (int, np.integer)) or not 1 <= shards <= n:
        raise ValueError(f"shards must be an int in [1, n = {n}] (envs of at least one row each), got {shown(shards)}")
    return [int(n // shards + (1 if k < n % shards else 0)) for k in range(shards)]


class ShardedLoop:
    """k envs, each flown by its own agent on its own thread (module docstring).

    Args:
        envs: the shards (``HoverBatchEnv`` built with ``physics_threads=0``); shard k's rows are rows
            ``offsets[k]``.. of the N vehicles.
        agents: one agent per env (``reset(info)``, ``act(obs, info)``).
    """

    def __init__(self, envs: Sequence[Any], agents: Sequence[Any]) -> None:
        if len(envs) < 1 or len(envs) != len(agents):
            raise ValueError(f"ShardedLoop needs one agent per env and at least one env, got {len(envs)} envs and "
                             f"{len(agents)} agents")
        for k, env in enumerate(envs):
            threads = getattr(env, "physics_threads", None)
            if threads != 0:
                raise ValueError(f"ShardedLoop: env {k} runs its physics on {shown(threads)} threads; build each shard "
                                 "with HoverBatchEnv(..., physics_threads=0) (its physics on the shard's own thread)")
        self.envs, self.agents = list(envs), list(agents)
        self.offsets: list[int] = np.cumsum([0] + [e.num_envs for e in self.envs[:-1]]).tolist()
        self.num_envs = int(sum(e.num_envs for e in self.envs))
        self._pool: ThreadPoolExecutor | None = (
            ThreadPoolExecutor(len(self.envs) - 1, thread_name_prefix="ShardedLoop") if len(self.envs) > 1 else None)
        self._state: list[tuple[Any, Any] | None] = [None] * len(self.envs)
        self._ended: list[NDArray[np.bool_] | None] = [None] * len(self.envs)  # rows the env restarts next step
        self._closed = False

    @classmethod
    def build(cls, n: int, make_agent: Callable[[Any], Any], shards: int | None = None,
              **env_options: Any) -> ShardedLoop:
        """``shards`` envs (None: one per usable core, at most ``n``) of the N = ``n`` vehicles with
        ``env_options`` (those of ``HoverBatchEnv``; ``physics_threads`` is set to 0), each with ``make_agent(env)``."""
        from fawtgym.envs.hover_batch_env import HoverBatchEnv, usable_cores

        if "physics_threads" in env_options:
            raise ValueError("ShardedLoop.build sets physics_threads=0 itself (each shard's physics on its own "
                             f"thread); got physics_threads={shown(env_options['physics_threads'])}")
        k = min(usable_cores(), n) if shards is None and isinstance(n, (int, np.integer)) and n >= 1 else shards
        sizes = shard_sizes(n, k)  # type: ignore[arg-type]  # checked there
        envs = [HoverBatchEnv(m, physics_threads=0, **env_options) for m in sizes]
        return cls(envs, [make_agent(env) for env in envs])

    def reset(self, seed: int = 0) -> None:
        """Reset every shard (shard k with seed ``seed + offsets[k]``: row i of the N vehicles gets ``seed + i``)
        and its agent."""
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be an int >= 0, got {shown(seed)}")
        if self._closed:
            raise RuntimeError("ShardedLoop.reset() called after close(): build a new loop")
        for k, (env, agent) in enumerate(zip(self.envs, self.agents, strict=True)):
            obs, info = env.reset(seed=int(seed) + self.offsets[k])
            agent.reset(info)
            self._state[k] = (obs, info)
            self._ended[k] = None

    def _fly(self, k: int, steps: int) -> None:
        """``steps`` control steps of shard k; a row whose episode ended restarts in the env (its autoreset) and in
        the agent (``agent.reset(info, rows=...)`` with the info of the new episode's first step, as the evaluation
        runner does)."""
        state = self._state[k]
        assert state is not None  # reset() first (checked in step)
        env, agent = self.envs[k], self.agents[k]
        same_step = getattr(env, "autoreset_mode", None) is AutoresetMode.SAME_STEP
        obs, info = state
        ended = self._ended[k]
        for _ in range(steps):
            obs, _, terminated, truncated, info = env.step(agent.act(obs, info))
            if same_step:  # the env restarted the ended rows in this step: info is their new episode's
                ended = terminated | truncated
            if ended is not None and ended.any():
                agent.reset(info, rows=ended)
            ended = None if same_step else terminated | truncated  # next step: the env restarts these rows
        self._state[k] = (obs, info)
        self._ended[k] = ended

    def step(self, steps: int = 1) -> None:
        """``steps`` control steps of every shard, each on its own thread; returns when all are done, or raises the
        error of the first shard (in shard order) that raised, once every shard has stopped.  Ended episodes restart
        (the env's autoreset, and the agent's per-row reset: :meth:`_fly`)."""
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 0:
            raise ValueError(f"steps must be an int >= 0, got {shown(steps)}")
        if self._closed:
            raise RuntimeError("ShardedLoop.step() called after close(): build a new loop")
        if any(s is None for s in self._state):
            raise RuntimeError("ShardedLoop.step() called before reset(): call reset(seed) first")
        self.each(lambda k, env, agent: self._fly(k, int(steps)))

    def each(self, fn: Callable[[int, Any, Any], Any]) -> list[Any]:
        """``fn(k, env_k, agent_k)`` for every shard k, each on the shard's own thread (shard 0 on the calling
        thread), at once; returns their results in shard order once all are done, or raises the error of the first
        shard (in shard order) that raised, once every shard has stopped."""
        futures = [self._pool.submit(fn, k, self.envs[k], self.agents[k]) for k in range(1, len(self.envs))
                   ] if self._pool else []
        error: BaseException | None = None
        first = None
        try:
            first = fn(0, self.envs[0], self.agents[0])
        except BaseException as exc:  # re-raised once every shard has stopped
            error = exc
        wait(futures)
        for f in futures:
            error = error or f.exception()
        if error is not None:
            raise error
        return [first, *(f.result() for f in futures)]

    def observations(self) -> NDArray[np.float32]:
        """The last observations of the N vehicles, (N, obs size), in row order."""
        return np.concatenate([self._checked_state(k)[0] for k in range(len(self.envs))])

    def info(self, *keys: str) -> NDArray[np.float64]:
        """One entry of the last ``info`` of the N vehicles, in row order: ``info("truth", "position")`` (N, 3)."""
        parts = []
        for k in range(len(self.envs)):
            value: Any = self._checked_state(k)[1]
            for key in keys:
                value = value[key]
            parts.append(np.asarray(value))
        return np.concatenate(parts)

    def _checked_state(self, k: int) -> tuple[Any, Any]:
        state = self._state[k]
        if state is None:
            raise RuntimeError("ShardedLoop: no observations before reset(): call reset(seed) first")
        return state

    def close(self) -> None:
        """Stop the threads and close the envs."""
        self._closed = True
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        for env in self.envs:
            env.close()

    def __enter__(self) -> ShardedLoop:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
