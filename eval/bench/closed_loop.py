"""``fawtgym bench closed-loop``: real-time factor of PX4 + FFTS-ESO hovering in FAWT-50 wind at 1 kHz physics.

One process, interleaved rounds, best round kept (least disturbed by other load on the machine):

* ``closed loop``: env (s500, ``fawt-50``, ``mocap_imu`` sensors, 1 kHz physics) + ``PX4ObserverAgent("ffts_eso")``,
  one vehicle; real-time factor = simulated seconds / wall seconds;
* its parts: the env stepping alone (hover action) and the agent + observer alone (on a recorded
  measurement), as real-time factors of the same simulated time;
* the agent + observer vectorized over N vehicles (batch-first), as aggregate vehicle-seconds per
  wall second.  Target (issue 6): closed loop >= 100x real time on one core.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from typing import Any

import numpy as np


def _make_env(control_rate: float) -> Any:
    import gymnasium as gym

    import fawtgym  # noqa: F401

    return gym.make("fawtgym/Hover-v0", vehicle="s500", wind="fawt-50", sensors="mocap_imu",
                    control_rate=control_rate, physics_rate=1000.0, episode_seconds=1e6, init_noise=0.0)


def _agent(env: Any) -> Any:
    from fawtgym.agents.px4_agent import PX4ObserverAgent
    from fawtgym.eval.reproduce.table4 import FLIGHT_GAINS

    return PX4ObserverAgent.for_env(env, observer="ffts_eso", observer_kwargs=FLIGHT_GAINS)


def _time_closed_loop(env: Any, agent: Any, steps: int) -> tuple[float, float]:
    obs, info = env.reset(seed=0)
    agent.reset(info)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        obs, _, term, trunc, info = env.step(agent.act(obs, info))
        if term or trunc:
            obs, info = env.reset()
            agent.reset(info)
    return time.perf_counter() - t0, time.process_time() - c0


def _time_env(env: Any, steps: int) -> tuple[float, float]:
    a = env.unwrapped.hover_action()
    env.reset(seed=0)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        env.step(a)
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


def measure(steps: int = 1000, rounds: int = 3, control_rate: float = 200.0,
            batch: int = 1024) -> dict[str, dict[str, float]]:
    """Real-time factors (simulated s per wall s, and per CPU s of this process), best of ``rounds``."""
    env = _make_env(control_rate)
    agent = _agent(env)
    sim = steps / control_rate
    nb = max(steps // 10, 10)
    jobs = {"closed": (lambda: _time_closed_loop(env, agent, steps), sim),
            "env": (lambda: _time_env(env, steps), sim),
            "agent": (lambda: _time_agent(env, agent, steps, 1), sim),
            "batch": (lambda: _time_agent(env, agent, nb, batch), batch * nb / control_rate)}
    best = {k: [np.inf, np.inf] for k in jobs}
    for _ in range(rounds):
        for k, (job, _) in jobs.items():
            wall, cpu = job()
            best[k] = [min(best[k][0], wall), min(best[k][1], cpu)]
    env.close()
    return {k: {"wall": jobs[k][1] / best[k][0], "cpu": jobs[k][1] / max(best[k][1], 1e-9), "sim": sim}
            for k in jobs}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fawtgym bench closed-loop", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=1000, help="control steps per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--control-rate", type=float, default=200.0,
                        help="agent rate [Hz] (a multiple of the 100 Hz mocap pose rate)")
    parser.add_argument("--batch", type=int, default=1024, help="N for the vectorized agent + observer")
    args = parser.parse_args(argv)
    r = measure(args.steps, args.rounds, args.control_rate, args.batch)
    print(f"PX4 + FFTS-ESO, s500 in fawt-50 wind, mocap_imu sensors, {args.control_rate:g} Hz control, 1 kHz physics "
          f"(best of {args.rounds} rounds of {r['closed']['sim']:g} simulated s); real-time factors "
          "(simulated s per wall s | per CPU s of this process):")
    rows = (("closed loop, 1 vehicle", "closed"), ("  env stepping alone", "env"),
            ("  agent + observer alone", "agent"), (f"agent + observer, N = {args.batch} (aggregate)", "batch"))
    for label, key in rows:
        print(f"  {label:<42s} {r[key]['wall']:8.1f}x | {r[key]['cpu']:8.1f}x")
    met = r["closed"]["wall"] >= 100.0
    print(f"  target >= 100x real time for the closed loop: {'met' if met else 'NOT met'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
