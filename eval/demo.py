"""``fawtgym demo``: fly a short FAWT hover with PX4-style control, with and without the FFTS-ESO feedforward.

The s500 hovers at the seed-000 FAWT point (ffts_eso_tse3_fawt_wang2024.txt Sec. 7.3); the fan array
(wind ``fawt-50``, Table 3's 50 % duty) is switched on mid-episode.  Two agents fly the same wind
and sensor-noise realization: ``PX4Agent`` (PX4 v1.13 cascade, S500 parameters) and
``PX4ObserverAgent("ffts_eso")`` (the same + F = F0 - phi_hat, tau = tau0 - tau_hat, Sec. 7.2).  It
prints position/attitude error statistics before and after the fan starts, the disturbance the
observer estimated against the truth, and any failure.  Missing components are reported, not raised.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np


def _fly(make_agent: Any, env: Any, seed: int) -> dict[str, Any]:
    agent = make_agent(env)
    obs, info = env.reset(seed=seed)
    agent.reset(info)
    sp = env.unwrapped.setpoint
    pos, att, times = [], [], []
    est = truth = None
    failure = ""
    while True:
        action = agent.act(obs, info)
        obs, _, term, trunc, info = env.step(action)
        t = info["truth"]
        pos.append(float(np.linalg.norm(t["position"] - sp)))
        r_d = agent.attitude_setpoint[0]
        att.append(math.acos(min(max((float(np.einsum("ji,ji->", r_d, t["attitude"])) - 1) / 2, -1.0), 1.0)))
        times.append(info["time"])
        if hasattr(agent, "raw_estimate"):
            est = np.concatenate([a.ravel() for a in agent.raw_estimate])
            truth = np.concatenate([t["force"], t["torque"]])
        if term or trunc:
            failure = info["failure"] if term else ""
            break
    return {"pos": np.array(pos), "att": np.array(att), "t": np.array(times), "est": est, "truth": truth,
            "failure": failure}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fawtgym demo", description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=12.0, help="episode length [s] (default 12)")
    parser.add_argument("--fan-on", type=float, default=4.0, help="fan switch-on time [s] (default 4)")
    parser.add_argument("--duty", type=int, default=50, choices=(30, 40, 50, 60, 70), help="FAWT duty [%%]")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    if not 0 <= args.fan_on < args.seconds:
        parser.error("need 0 <= --fan-on < --seconds")
    try:
        import gymnasium as gym

        import fawtgym  # noqa: F401  (registers fawtgym/Hover-v0)
        from fawtgym.agents.px4_agent import PX4Agent, PX4ObserverAgent
    except ImportError as exc:
        print(f"fawtgym demo: a required component is missing ({exc}); nothing to fly.", file=sys.stderr)
        return 2
    wind: Any = {"name": f"fawt-{args.duty}", "on_time": args.fan_on}
    try:
        from fawtgym.envs.wind import wind_names

        if f"fawt-{args.duty}" not in wind_names():
            raise ValueError(f"wind preset fawt-{args.duty} is not available")
    except (ImportError, ValueError) as exc:
        print(f"fawtgym demo: FAWT wind missing ({exc}); flying in calm air instead.")
        wind = "calm"
    agents: list[tuple[str, Any]] = [("PX4", lambda env: PX4Agent.for_env(env))]
    try:
        import fawtgym.observers as observers

        if "ffts_eso" not in observers.observer_names():
            raise ValueError("observer 'ffts_eso' is not registered")
        from fawtgym.eval.reproduce.table4 import FLIGHT_GAINS

        agents.append(("PX4+FFTS-ESO", lambda env: PX4ObserverAgent.for_env(env, observer="ffts_eso",
                                                                             observer_kwargs=FLIGHT_GAINS)))
    except (ImportError, ValueError) as exc:
        print(f"fawtgym demo: FFTS-ESO unavailable ({exc}); flying PX4 alone.")

    print(f"s500 hovering 1.5 m in front of the fan array; wind {wind if isinstance(wind, str) else wind['name']}"
          + ("" if isinstance(wind, str) else f" switched on at {args.fan_on:g} s")
          + f"; {args.seconds:g} s, mocap + IMU sensors, seed {args.seed}.")
    print(f"{'controller':>14s} | {'pos err before fan':>18s} | {'pos err with fan':>25s} | "
          f"{'Phi with fan':>12s} | result")
    results = {}
    for name, make in agents:
        env = gym.make("fawtgym/Hover-v0", vehicle="s500", wind=wind, sensors="mocap_imu", control_rate=200.0,
                       episode_seconds=args.seconds, init_noise=0.0)
        t0 = time.time()
        try:
            r = _fly(make, env, args.seed)
        except Exception as exc:  # report, do not crash the demo
            print(f"{name:>14s} | failed to run: {type(exc).__name__}: {exc}")
            continue
        finally:
            env.close()
        before = r["t"] <= args.fan_on
        after = ~before
        fmt = lambda a, f: f"{f(a):.3f}" if a.size else "n/a"
        print(f"{name:>14s} | {'mean ' + fmt(r['pos'][before], np.mean) + ' m':>18s} | "
              f"{'mean ' + fmt(r['pos'][after], np.mean) + ' max ' + fmt(r['pos'][after], np.max) + ' m':>25s} | "
              f"{fmt(r['att'][after], np.mean) + ' rad':>12s} | "
              f"{('FAILED: ' + r['failure']) if r['failure'] else 'held hover'} ({time.time() - t0:.0f} s wall)")
        results[name] = r
    for name, r in results.items():
        if r["est"] is not None:
            print(f"{name}: disturbance at the end, estimate vs truth: force [N] {np.round(r['est'][:3], 2)} vs "
                  f"{np.round(r['truth'][:3], 2)}, torque [N m] {np.round(r['est'][3:], 3)} vs "
                  f"{np.round(r['truth'][3:], 3)}")
    if len(results) == 2:
        a, b = (results[k]["pos"][results[k]["t"] > args.fan_on].mean() for k in results)
        print(f"with the fan on, the observer feedforward changes the mean position error by {100 * (b / a - 1):+.0f} %"
              " (seed-000 Table 4 at 50 % duty: -57 %). Full study: fawtgym reproduce table4")
    return 0 if results else 1


if __name__ == "__main__":
    raise SystemExit(main())
