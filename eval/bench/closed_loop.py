"""``fawtgym bench closed-loop``: real-time factor of PX4 + FFTS-ESO hovering in FAWT-50 wind at 1 kHz physics.

One process, interleaved rounds, best round kept (least disturbed by other load on the machine):

* ``closed loop``: env (s500, ``fawt-50``, ``mocap_imu`` sensors, 1 kHz physics) + ``PX4ObserverAgent("ffts_eso")``,
  one vehicle; real-time factor = simulated seconds / wall seconds;
* its parts: the env stepping alone (the closed loop's own recorded actions, the same trajectory) and the
  agent + observer alone (on a recorded
  measurement batched as (1, ...) arrays), as real-time factors of the same simulated time, and the PX4 agent
  without its observer (the cascade's own share); and the agent + observer on the single env's own info
  (unbatched arrays, what the closed loop hands it: the agent's input conversion included);
* the agent + observer vectorized over N vehicles (batch-first), as aggregate vehicle-seconds per
  wall second.  Target: closed loop >= 100x real time on one core.

All four run after a short warm-up (the compiled kernels load from numba's cache, or compile, on their
first call), so compile time is in none of them; all ratios come from one run.

Batched (``--batch-sizes``, aggregate over N vehicles: vehicle-seconds simulated per wall second, one
process: numpy's OpenBLAS is pinned to 1 thread; MuJoCo's rollout runs the physics on one thread per core,
each with its own ``MjData``, from :data:`~fawtgym.envs.hover_batch_env.THREADED_ROWS` rows on (below, on the
calling thread); the "per CPU s" column counts every thread of the process):

* ``closed loop``: :class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv` (N vehicles, same options as
  above) + one batch-first ``PX4ObserverAgent("ffts_eso")`` for all N;
* ``pipelined``: the same N vehicles as two envs of N / 2 rows with an agent each, each stepping on its own worker
  thread (``HoverBatchEnv.step_async``: MuJoCo's rollout runs without the GIL), so one half's agent and step
  kernels (serial work) run while the other half's physics does;
* ``sharded``: the same N vehicles as one env of N / k rows per core (k: the env's physics threads for N),
  each with ``physics_threads=0`` (its physics on its own thread) and its own agent, each shard's closed loop on its
  own thread (:class:`~fawtgym.eval.sharded.ShardedLoop`): the hot kernels release the GIL, so both cores run
  physics, env kernels and agents alike, with no hand-off inside a step;
* ``env alone``: the same batch env stepped with the hover action;
* ``physics only``: the ``mujoco.rollout`` call the env makes (same model, N x substeps, same control
  layout, same threads, MuJoCo's profiler timers off as in the env: ``fawtgym/envs/mujoco_timers.py``) and nothing
  else: the ceiling for any env built on this physics;
* ``calm env`` / ``fawt env``: vehicle-steps per second of the batch env alone (calm air, exact
  sensors, 100 Hz control; FAWT-50 + mocap_imu at the closed loop's control rate).

The target line's ratio closed loop / physics only pairs the two step by step (the ``interleaved`` job): after every
closed-loop step the env's own rollout call runs again on the env's own arrays, threads and ``MjData`` (from the state
the step left, with its controls, into the output buffer the next step overwrites before reading it: the trajectory
is unchanged, a test checks it), timed apart; per round the sum of those physics-only times over the sum of the
closed-loop steps' times, and the line prints the median over rounds.  Paired within milliseconds, with the caches
the loop itself leaves, the ratio keeps little of a shared VM's drift (its second vCPU can lose a third of its speed
for seconds at a time): on the 2-vCPU VM of docs/performance.md the rounds of one run agree to about +-0.02, where the
jobs run back to back (also printed, for the plain and the pipelined loop) spread by +-0.1.  The table's column
(plain loop) divides the best round of each job, which can pair a fast physics round with a slow closed-loop one.
The sharded loop is paired in blocks (the ``sharded_paired`` job): :data:`SHARD_BLOCK` steps of every shard, then as
many steps of each physics-only layout, each timed: the N-row env's own rollout call (the plain loop's ceiling) and
the shards' own rollout calls at once on their threads (the sharded loop's own physics); per round the physics-only
time of each layout over the sharded blocks' time; the target line takes the faster layout's (the higher ceiling).
The target line reports both loops: the sharded one (the
fastest way to fly N vehicles here) and the plain one (one env, one agent, one thread orchestrating).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fawtgym.cli_parser import ArgumentParser, positive_float, positive_int


def _make_env(control_rate: float) -> Any:
    import gymnasium as gym

    import fawtgym  # noqa: F401

    return gym.make("fawtgym/Hover-v0", vehicle="s500", wind="fawt-50", sensors="mocap_imu",
                    control_rate=control_rate, physics_rate=1000.0, episode_seconds=1e6, init_noise=0.0)


def _agent(env: Any) -> Any:
    from fawtgym.agents.px4_agent import PX4ObserverAgent
    from fawtgym.eval.reproduce.table4 import FLIGHT_GAINS

    return PX4ObserverAgent.for_env(env, observer="ffts_eso", observer_kwargs=FLIGHT_GAINS)


def _time_closed_loop(env: Any, agent: Any, steps: int,
                      record: list[Any] | None = None) -> tuple[float, float]:
    """The closed loop from ``reset(seed=0)``; ``record`` (a list) receives each action and whether the episode
    ended after it (for :func:`_time_env`)."""
    obs, info = env.reset(seed=0)
    agent.reset(info)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        action = agent.act(obs, info)
        obs, _, term, trunc, info = env.step(action)
        if record is not None:
            record.append((np.array(action, copy=True), term or trunc))  # the agent may reuse its buffer
        if term or trunc:
            obs, info = env.reset()
            agent.reset(info)
    return time.perf_counter() - t0, time.process_time() - c0


def _time_env(env: Any, actions: list[Any]) -> tuple[float, float]:
    """The env alone flying the closed loop's own recorded actions from the same seed: the same trajectory
    (the env is deterministic), so the same work per step -- not a fixed hover action, with which the vehicle
    drifts out of its box in FAWT-50 wind within ~100 steps and the rest would time a terminated env."""
    env.reset(seed=0)
    t0, c0 = time.perf_counter(), time.process_time()
    for action, ended in actions:
        env.step(action)
        if ended:
            env.reset()
    return time.perf_counter() - t0, time.process_time() - c0


def _batched_info(info: dict[str, Any], n: int) -> dict[str, Any]:
    return {part: {k: np.repeat(np.asarray(v, dtype=float)[None], n, axis=0) for k, v in info[part].items()}
            for part in ("measurement", "applied")}


def _time_agent(env: Any, agent: Any, steps: int, n: int) -> tuple[float, float]:
    _, info = env.reset(seed=0)
    binfo = _batched_info(info, n)
    agent.reset(binfo)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        agent.act(None, binfo)
    return time.perf_counter() - t0, time.process_time() - c0


def _time_agent_single_info(env: Any, agent: Any, steps: int) -> tuple[float, float]:
    """The agent + observer on the single env's own info (unbatched (3,)-shaped arrays, as the closed loop hands
    it over), on a recorded step."""
    obs, info = env.reset(seed=0)
    agent.reset(info)
    obs, _, _, _, info = env.step(env.unwrapped.hover_action())
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        agent.act(obs, info)
    return time.perf_counter() - t0, time.process_time() - c0


def pin_blas_one_thread() -> str:
    """Best effort: numpy's OpenBLAS to 1 thread (one-core figures).  Returns what was done."""
    import ctypes
    import glob
    import os

    for lib_path in glob.glob(os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs", "*openblas*")):
        lib = ctypes.CDLL(lib_path)
        for name in ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads", "openblas_set_num_threads"):
            if hasattr(lib, name):
                getattr(lib, name)(1)
                return f"numpy OpenBLAS pinned to 1 thread ({name})"
    return "could not pin numpy's BLAS threads (see the per-CPU-s column)"


#: control steps per block of the sharded loop's pairing with the physics-only call (``sharded_paired``)
SHARD_BLOCK = 10


def _batch_jobs(n: int, control_rate: float, vehicle_steps: int, shards: int | None = None
                ) -> dict[str, tuple[Any, float]]:
    """Timed jobs for N vehicles: name -> (job() -> (wall, cpu), simulated vehicle-seconds); ``shards``: envs of the
    sharded loop (None: the env's own physics threads for N, one per core; 1 or fewer than 2 rows each: no sharded
    loop)."""
    import mujoco
    from mujoco import rollout

    from fawtgym.envs import mujoco_timers
    from fawtgym.envs.hover_batch_env import _CONTROL_SPEC, HoverBatchEnv, default_physics_threads
    from fawtgym.eval.sharded import ShardedLoop

    kw: dict[str, Any] = dict(vehicle="s500", physics_rate=1000.0, episode_seconds=1e6, init_noise=0.0)
    env = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu", control_rate=control_rate, **kw)
    calm = HoverBatchEnv(n, wind="calm", sensors="none", control_rate=100.0, **kw)
    agent = _agent(env)
    halves = [HoverBatchEnv(m, wind="fawt-50", sensors="mocap_imu", control_rate=control_rate, **kw)
              for m in (n // 2, n - n // 2)] if n >= 2 else []
    half_agents = [_agent(h) for h in halves]
    k = max(default_physics_threads(n), 1) if shards is None else shards
    sharded = ShardedLoop.build(n, _agent, k, wind="fawt-50", sensors="mocap_imu", control_rate=control_rate,
                                **kw) if 2 <= k <= n // 2 else None
    steps = max(vehicle_steps // n, 5)

    recorded: list[NDArray[np.float64]] = []  # the closed loop's actions (the first run's): the env-alone job's

    def closed() -> tuple[float, float]:
        obs, info = env.reset(seed=0)
        agent.reset(info)
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(steps):
            action = agent.act(obs, info)
            obs, _, _, _, info = env.step(action)
            if len(recorded) < steps:
                recorded.append(np.array(action, copy=True))  # the agent may reuse its output buffer
        return time.perf_counter() - t0, time.process_time() - c0

    def pipelined() -> tuple[float, float]:
        """The closed loop of the same N vehicles as two envs of N / 2 rows (rows 0.. and N / 2.. of the N-row env's
        seeds), each with its own agent, each stepping on its own worker thread (``step_async``: MuJoCo's rollout
        runs without the GIL): each half's agent acts, and its step kernels run, while the other half's physics
        does.  The high half takes one step more than the low one (started first, waited for last)."""
        (low, high), (agent_low, agent_high) = halves, half_agents
        obs_low, info_low = low.reset(seed=0)
        obs_high, info_high = high.reset(seed=low.num_envs)
        agent_low.reset(info_low)
        agent_high.reset(info_high)
        action_low = agent_low.act(obs_low, info_low)
        t0, c0 = time.perf_counter(), time.process_time()
        high.step_async(agent_high.act(obs_high, info_high))
        for _ in range(steps):
            low.step_async(action_low)
            obs_high, _, _, _, info_high = high.step_wait()
            high.step_async(agent_high.act(obs_high, info_high))  # while the low half's physics runs
            obs_low, _, _, _, info_low = low.step_wait()
            action_low = agent_low.act(obs_low, info_low)  # while the high half's physics runs
        high.step_wait()
        return time.perf_counter() - t0, time.process_time() - c0

    def interleaved() -> tuple[float, float]:
        """The closed loop with the env's own physics-only call after every step: the step's ``mujoco.rollout``
        call again, on the env's own arrays, threads and ``MjData`` (from the state the step left, with its
        controls, into the output buffer the next step overwrites before reading: the trajectory is unchanged),
        timed apart.  Returns (closed-loop wall s, physics-only wall s) over the same steps: their ratio pairs the
        two step by step, in the same milliseconds and with the same caches."""
        obs, info = env.reset(seed=0)
        agent.reset(info)
        closed = physics = 0.0
        clock = time.perf_counter
        for _ in range(steps):
            t0 = clock()
            action = agent.act(obs, info)
            obs, _, _, _, info = env.step(action)
            t1 = clock()
            env._rollout_rows(env._mj_state, env._ctrl, env._out)
            t2 = clock()
            closed += t1 - t0
            physics += t2 - t1
        return closed, physics

    def sharded_loop() -> tuple[float, float]:
        assert sharded is not None
        sharded.reset(seed=0)
        t0, c0 = time.perf_counter(), time.process_time()
        sharded.step(steps)
        return time.perf_counter() - t0, time.process_time() - c0

    def sharded_paired() -> tuple[float, float, float]:
        """The sharded loop in blocks of :data:`SHARD_BLOCK` steps, each block followed by as many steps of both
        physics-only layouts, each timed: the N-row env's own rollout call (one rollout on its threads, the plain
        loop's ceiling) and the shards' own rollout calls, each on its shard's thread at once (the sharded loop's
        own physics, from each shard's state, with its controls, into the output buffer its next step overwrites
        before reading it: the trajectories are unchanged).  Returns (sharded-loop wall s, the N-row env's
        physics-only wall s, the shards' physics-only wall s) over the same steps, paired within a block (~0.1 s)."""
        assert sharded is not None
        sharded.reset(seed=0)
        env.reset(seed=0)
        env.step(env.hover_action())
        loop = physics_env = physics_shards = 0.0
        clock = time.perf_counter

        def shard_physics(k: int, e: Any, a: Any) -> None:
            for _ in range(block):
                e._rollout_rows(e._mj_state, e._ctrl, e._out)

        for done in range(0, steps, SHARD_BLOCK):
            block = min(SHARD_BLOCK, steps - done)
            t0 = clock()
            sharded.step(block)
            t1 = clock()
            for _ in range(block):
                env._rollout_rows(env._mj_state, env._ctrl, env._out)
            t2 = clock()
            sharded.each(shard_physics)
            t3 = clock()
            loop += t1 - t0
            physics_env += t2 - t1
            physics_shards += t3 - t2
        return loop, physics_env, physics_shards

    def alone(e: Any, actions: Sequence[NDArray[np.float64]] | None = None) -> tuple[float, float]:
        """The env alone: the closed loop's recorded actions (the same trajectory), or the hover action (calm)."""
        a = e.hover_action()
        e.reset(seed=0)
        t0, c0 = time.perf_counter(), time.process_time()
        for k in range(steps):
            e.step(a if actions is None else actions[k])
        return time.perf_counter() - t0, time.process_time() - c0

    def physics() -> tuple[float, float]:
        env.reset(seed=0)
        env.step(env.hover_action())
        state, ctrl, out = env._mj_state.copy(), env._ctrl.copy(), env._out.copy()
        threads = default_physics_threads(n)  # the env's own: one MjData per thread
        models, data = [env.model] * n, [mujoco.MjData(env.model) for _ in range(max(threads, 1))]
        with rollout.Rollout(nthread=threads) as r, mujoco_timers.suspended(not env.mujoco_timers):
            t0, c0 = time.perf_counter(), time.process_time()
            for _ in range(steps):
                r.rollout(models, data, state, ctrl, control_spec=_CONTROL_SPEC, skip_checks=True,
                          nstep=env.n_substeps, state=out, chunk_size=env._chunk)
            return time.perf_counter() - t0, time.process_time() - c0

    sim = n * steps / control_rate
    # closed loop and physics only back to back in every round (their paired ratio, :func:`measure_batched`)
    jobs: dict[str, tuple[Any, float]] = {"closed": (closed, sim), "physics": (physics, sim)}
    if halves:  # right after the physics-only round too (paired with it)
        jobs["pipelined"] = (pipelined, (halves[0].num_envs * steps + halves[1].num_envs * (steps + 1)) / control_rate)
    if sharded is not None:
        jobs["sharded"] = (sharded_loop, sim)
    jobs.update({"env": (lambda: alone(env, recorded), sim), "calm": (lambda: alone(calm), n * steps / 100.0),
                 "interleaved": (interleaved, sim)})
    if sharded is not None:
        jobs["sharded_paired"] = (sharded_paired, sim)
    return jobs


#: jobs that return (loop wall s, physics-only wall s of each ceiling) paired within the job, not (wall, cpu)
PAIRED_JOBS = ("interleaved", "sharded_paired")


def measure_batched(batch_sizes: Sequence[int] = (64, 256, 1024), rounds: int = 3, control_rate: float = 200.0,
                    vehicle_steps: int = 51200, shards: int | None = None) -> dict[int, dict[str, Any]]:
    """Aggregate real-time factors (vehicle-s per wall s / per CPU s) for each N, best of ``rounds``; under
    ``"interleaved"`` each round's closed loop / physics-only ratio paired step by step (the ``interleaved`` job:
    the env's own rollout call again after every closed-loop step, timed apart); under ``"sharded_paired"`` (N with
    a sharded loop: ``shards`` envs, None for one per core) each round's sharded loop / physics-only ratio paired in
    blocks of :data:`SHARD_BLOCK` steps; and under ``"paired"`` each round's [closed loop, pipelined loop (N >= 2)] /
    physics-only ratios of the jobs run back to back (a shared VM's second vCPU can lose a third of its speed for
    seconds at a time: pairing step by step leaves the least of that drift in the ratio)."""
    out: dict[int, dict[str, Any]] = {}
    for n in batch_sizes:
        jobs = _batch_jobs(n, control_rate, vehicle_steps, shards)
        timed = {k: v for k, v in jobs.items() if k not in PAIRED_JOBS}
        best = {k: [np.inf, np.inf] for k in timed}
        paired: list[list[float]] = []
        within: dict[str, list[Any]] = {k: [] for k in PAIRED_JOBS if k in jobs}
        for _ in range(rounds):
            walls = {}
            for k, (job, _) in jobs.items():
                if k in PAIRED_JOBS:  # (loop wall s, physics-only wall s of each ceiling measured)
                    loop, *physics = job()
                    within[k].append([p / loop for p in physics] if len(physics) > 1 else physics[0] / loop)
                    continue
                wall, cpu = job()
                walls[k] = wall
                best[k] = [min(best[k][0], wall), min(best[k][1], cpu)]
            rate = {k: jobs[k][1] / walls[k] for k in walls}  # real-time factors of this round
            paired.append([rate[k] / rate["physics"] for k in ("closed", "pipelined") if k in rate])
        out[n] = {k: {"wall": timed[k][1] / best[k][0], "cpu": timed[k][1] / max(best[k][1], 1e-9)} for k in timed}
        out[n]["paired"] = paired
        out[n].update(within)
    return out


def measure(steps: int = 1000, rounds: int = 3, control_rate: float = 200.0,
            batch: int = 1024) -> dict[str, dict[str, float]]:
    """Real-time factors (simulated s per wall s, and per CPU s of this process), best of ``rounds``."""
    from fawtgym.agents.px4_agent import PX4Agent

    env = _make_env(control_rate)
    agent = _agent(env)
    px4 = PX4Agent.for_env(env)
    sim = steps / control_rate
    nb = max(steps // 10, 10)
    recorded: list[Any] = []
    jobs = {"closed": (lambda: _time_closed_loop(env, agent, steps, recorded if not recorded else None), sim),
            "env": (lambda: _time_env(env, recorded), sim),
            "agent": (lambda: _time_agent(env, agent, steps, 1), sim),
            "agent_info": (lambda: _time_agent_single_info(env, agent, steps), sim),
            "px4": (lambda: _time_agent(env, px4, steps, 1), sim),
            "batch": (lambda: _time_agent(env, agent, nb, batch), batch * nb / control_rate)}
    # warm-up: the compiled kernels load (or compile) on their first call; that is not part of any timing
    _time_closed_loop(env, agent, 10)
    _time_agent(env, agent, 2, batch)
    _time_agent(env, px4, 10, 1)
    best = {k: [np.inf, np.inf] for k in jobs}
    for _ in range(rounds):
        for k, (job, _) in jobs.items():
            wall, cpu = job()
            best[k] = [min(best[k][0], wall), min(best[k][1], cpu)]
    env.close()
    return {k: {"wall": jobs[k][1] / best[k][0], "cpu": jobs[k][1] / max(best[k][1], 1e-9), "sim": sim}
            for k in jobs}


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="fawtgym bench closed-loop", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=positive_int, default=1000, help="control steps per round")
    parser.add_argument("--rounds", type=positive_int, default=3, help="timing rounds (default 3)")
    parser.add_argument("--control-rate", type=positive_float, default=200.0,
                        help="agent rate [Hz] (a multiple of the 100 Hz mocap pose rate)")
    parser.add_argument("--batch", type=positive_int, default=1024, help="N for the vectorized agent + observer")
    parser.add_argument("--batch-sizes", type=positive_int, nargs="*", default=[64, 256, 1024],
                        help="N of the batched closed loop (HoverBatchEnv); none to skip")
    parser.add_argument("--vehicle-steps", type=positive_int, default=51200,
                        help="control steps x N per batched round")
    args = parser.parse_args(argv)
    pinned = pin_blas_one_thread()
    r = measure(args.steps, args.rounds, args.control_rate, args.batch)
    print(f"PX4 + FFTS-ESO, s500 in fawt-50 wind, mocap_imu sensors, {args.control_rate:g} Hz control, 1 kHz physics "
          f"(best of {args.rounds} rounds of {r['closed']['sim']:g} simulated s); real-time factors "
          "(simulated s per wall s | per CPU s of this process):")
    rows = (("closed loop, 1 vehicle", "closed"), ("  env stepping alone", "env"),
            ("  agent + observer alone", "agent"), ("    of it, PX4 alone (no observer)", "px4"),
            ("  agent + observer on the env's single info", "agent_info"),
            (f"agent + observer, N = {args.batch} (aggregate)", "batch"))
    for label, key in rows:
        print(f"  {label:<42s} {r[key]['wall']:8.1f}x | {r[key]['cpu']:8.1f}x")
    met = r["closed"]["wall"] >= 100.0
    print(f"  SINGLE VEHICLE target >= 100x real time for the closed loop: {'met' if met else 'NOT met'}")
    if not args.batch_sizes:
        return 0
    b = measure_batched(args.batch_sizes, args.rounds, args.control_rate, args.vehicle_steps)
    from fawtgym.envs.hover_batch_env import default_physics_threads

    threads = {n: default_physics_threads(n) or 1 for n in args.batch_sizes}
    print(f"\nAGGREGATE over N vehicles (HoverBatchEnv + one batch-first agent; {pinned}; rollout threads per N: "
          f"{threads}); vehicle-seconds per wall s | per CPU s of this process, best of {args.rounds} rounds of "
          f"~{args.vehicle_steps} vehicle-steps:")
    head = (f"  {'N':>5s}  {'closed loop':>17s}  {'pipelined':>17s}  {'sharded':>17s}  {'env alone':>17s}  "
            f"{'physics only':>17s}  {'closed/physics':>14s}  {'calm env':>14s}  {'fawt env':>14s}")
    print(head)
    for n, row in b.items():
        cell = {k: f"{row[k]['wall']:7.1f}x|{row[k]['cpu']:7.1f}x" for k in row
                if k not in ("paired", *PAIRED_JOBS)}
        calm_sps = row["calm"]["wall"] * 100.0  # vehicle-steps per second at 100 Hz control
        fawt_sps = row["env"]["wall"] * args.control_rate
        print(f"  {n:5d}  {cell['closed']:>17s}  {cell.get('pipelined', '-'):>17s}  {cell.get('sharded', '-'):>17s}  "
              f"{cell['env']:>17s}  {cell['physics']:>17s}  {row['closed']['wall'] / row['physics']['wall']:14.2f}  "
              f"{calm_sps:10.0f} st/s  {fawt_sps:10.0f} st/s")
    big = max(b)
    rounds = np.array(b[big]["paired"])  # (rounds, 1 or 2): closed loop, pipelined loop over physics only
    loops = ("closed loop", "pipelined loop")[:rounds.shape[1]]
    for k, loop in enumerate(loops):
        print(f"  {loop} / physics only at N = {big}, each round's two jobs back to back: "
              f"{' '.join(f'{p:.2f}' for p in rounds[:, k])} (median {np.median(rounds[:, k]):.2f})")
    steps = np.array(b[big]["interleaved"])
    plain = float(np.median(steps))
    print(f"  closed loop / physics only at N = {big}, paired step by step (the env's own rollout call again after "
          f"every step): {' '.join(f'{p:.2f}' for p in steps)} (median {plain:.2f})")
    verdict = f"plain loop (one env and one agent on the calling thread; median of the rounds paired step by step) " \
              f"{plain:.2f}, {'met' if plain >= 0.8 else 'NOT met'}"
    if "sharded_paired" in b[big]:
        blocks = np.array(b[big]["sharded_paired"])  # (rounds, 2): against the N-row env's physics, the shards'
        k = threads[big]
        print(f"  sharded loop / physics only at N = {big} ({k} envs of ~{big // k} rows, each with its own agent on "
              f"its own thread, physics_threads=0), paired in blocks of {SHARD_BLOCK} steps:")
        for c, ceiling in enumerate(("the N-row env's rollout (the plain loop's ceiling)",
                                     "the shards' own rollouts at once")):
            print(f"    against {ceiling}: {' '.join(f'{p:.2f}' for p in blocks[:, c])} "
                  f"(median {np.median(blocks[:, c]):.2f})")
        share = float(np.median(blocks.min(axis=1)))
        verdict = (f"sharded loop (median over the rounds of the ratio to the faster physics-only layout) {share:.2f}, "
                   f"{'met' if share >= 0.8 else 'NOT met'}; {verdict}")
    print(f"  BATCHED target closed loop >= 0.8 of the physics-only ceiling at N = {big}: {verdict}")
    best_n = max(b, key=lambda k: b[k]["closed"]["cpu"])
    met = b[best_n]["closed"]["cpu"] >= 100.0
    print(f"  AGGREGATE target >= 100x real time on one core (per CPU s, best N = {best_n}): "
          f"{b[best_n]['closed']['cpu']:.1f}x, {'met' if met else 'NOT met'}")
    print("  (calm env: 100 Hz control, exact sensors; fawt env: fawt-50 + mocap_imu at "
          f"{args.control_rate:g} Hz; 'st/s' = vehicle control steps per wall second)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
