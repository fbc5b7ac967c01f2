"""``fawtgym bench eval``: the quick leaderboard's throughput, beside the batched env alone, in one run.

The quick leaderboard (``fawtgym eval``'s defaults) is flown into a temporary folder with the chosen
number of local workers; reported: cells per minute and vehicle-seconds simulated per wall second.  In
the same run, each of its scenarios is flown by the batched env alone (``HoverBatchEnv``, the same rows,
the hover command instead of an agent, no metrics), one process: the ratio eval / env alone is what the
agents, the metrics and the process pool cost on top of the simulation.  Both are wall-clock figures of
this machine at this moment; the ratio is the portable number.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Sequence
from pathlib import Path


def time_env_alone(scenarios: Sequence[str], seeds: int) -> tuple[float, float]:
    """(wall seconds, vehicle-seconds) of the batched env alone flying every scenario once with ``seeds`` rows."""
    from fawtgym.envs.hover_batch_env import HoverBatchEnv
    from fawtgym.eval.scenarios import get_scenario

    wall = vehicle = 0.0
    for name in scenarios:
        sc = get_scenario(name)
        env = HoverBatchEnv(num_envs=seeds, **sc.env_options())
        env.reset(seed=list(range(seeds)))
        a = env.hover_action()
        t0 = time.perf_counter()
        for _ in range(env.max_steps):
            env.step(a)
        wall += time.perf_counter() - t0
        vehicle += seeds * env.max_steps * env.dt
        env.close()
    return wall, vehicle


def main(argv: Sequence[str] | None = None) -> int:
    from fawtgym.cli_parser import ArgumentParser
    from fawtgym.eval.runner import run_cells
    from fawtgym.eval.runner_cli import QUICK
    from fawtgym.eval.scenarios import resolve_scenarios

    parser = ArgumentParser(prog="fawtgym bench eval", description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=2, help="local worker processes (default 2)")
    parser.add_argument("--seeds", type=int, default=QUICK[2], help=f"seeds per cell (default {QUICK[2]})")
    ns = parser.parse_args(argv)
    if ns.workers < 1 or ns.seeds < 1:
        parser.error(f"--workers and --seeds must be >= 1, got {ns.workers} and {ns.seeds}")
    agents = QUICK[0].split(",")
    scenarios = resolve_scenarios(QUICK[1].split(","))
    seeds = list(range(ns.seeds))
    print(f"quick leaderboard: {len(agents)} agents x {len(scenarios)} scenarios x {len(seeds)} seeds, "
          f"{ns.workers} worker(s)", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        summary = run_cells(Path(tmp), agents, scenarios, seeds, workers=ns.workers, progress=True)
        cells = len(summary["done"])
        wall = summary["wall_seconds"]
    vehicle_s = sum(sc.seconds for sc in scenarios) * len(agents) * len(seeds)
    env_wall, env_vehicle = time_env_alone([s.name for s in scenarios], len(seeds))
    eval_rate = vehicle_s / wall
    env_rate = env_vehicle / env_wall
    print(f"  eval:       {cells} cells in {wall:.1f} s = {60 * cells / wall:.1f} cells/min, "
          f"{eval_rate:.1f} vehicle-s per wall-s ({ns.workers} worker(s))")
    print(f"  env alone:  {env_rate:.1f} vehicle-s per wall-s (one process, hover command, no agent)")
    print(f"  ratio eval / env alone: {eval_rate / env_rate:.2f} (per worker: {eval_rate / env_rate / ns.workers:.2f}; "
          "below 1 = what agents, metrics and processes cost)")
    if summary["errors"]:
        print(f"  errors: {summary['errors']}")
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
