"""``fawtgym eval``: fly agents x scenarios x seeds on the same wind, write resumable cells, print the leaderboard.

Examples::

    fawtgym eval                       # the quick leaderboard: 4 agents x 3 scenarios x 3 seeds, ~2 min on 2 cores
    fawtgym eval --full                # every observer, every duty, 10 seeds (about an hour on 2 cores)
    fawtgym eval --agents px4,px4+ffts_eso,px4+geso --scenarios table4-50,fawt-50-steady --seeds 5 --out results/q
    fawtgym eval --agents px4,px4+leso --wind dryden-moderate --duration 20 --seeds 3 --out results/dryden
    fawtgym eval --agents px4,mypkg.agents:MyAgent --scenarios my_scenarios.yaml --out results/mine

Each (agent, scenario) cell flies its seeds as the rows of one batched env; every agent meets the same
wind and sensor noise per (scenario, seed).  Rerunning the same command skips the finished cells.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from fawtgym.cli_parser import ArgumentParser
from fawtgym.core.checks import shown

from .leaderboard import DEFAULT_BASELINE
from .runner import DEFAULT_RECORD_HZ, MAX_SEEDS, check_seeds
from .scenarios import Scenario

#: the quick leaderboard (the README's main command): (agents, scenarios, seeds); ranked on the first scenario
QUICK = ("px4,px4+ffts_eso,px4+leso,px4+geso", "table4-50,fawt-50-steady,dryden-moderate", 3)
#: ``--full``: PX4 alone and with every observer that estimates a disturbance, every Table 4 duty, steady and outdoor
FULL = ("px4,px4+ffts_eso,px4+leso,px4+fxtsdo,px4+sto,px4+geso,px4+qb,px4+hc_eso",
        "table4-50,table4-30,table4-40,table4-60,table4-70,fawt-30-steady,fawt-50-steady,fawt-70-steady,"
        "dryden-moderate,gust-1cos", 10)


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {shown(text)}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {shown(text)}")
    return v


def _seeds(text: str) -> list[int]:
    """``5`` -> seeds 0..4; ``10:15`` -> 10..14; ``1,4,9`` -> those seeds."""
    try:
        if ":" in text:
            a, b = (int(x) for x in text.split(":"))
            if b - a > MAX_SEEDS:  # checked before the list is built (0:10**18 would not fit in memory)
                raise ValueError
            seeds = list(range(a, b))
        elif "," in text:
            seeds = [int(x) for x in text.split(",") if x.strip()]
        else:
            count = _positive_int(text)
            if count > MAX_SEEDS:
                raise ValueError
            seeds = list(range(count))
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(f"must be a count (5), a range (10:15) or a list (1,4,9) of at most "
                                         f"{MAX_SEEDS} seeds in [0, 2**32), got {shown(text)}") from None
    try:
        return check_seeds(seeds)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must give 1 to {MAX_SEEDS} distinct seeds in [0, 2**32), "
                                         f"got {shown(text)}") from None


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {shown(text)}") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {shown(text)}")
    return v


def build_parser() -> argparse.ArgumentParser:
    from fawtgym.agents.spec import GRAMMAR

    from .scenarios import scenario_names

    p = ArgumentParser(prog="fawtgym eval", description=__doc__.split("\n\n")[0],
                                epilog=f"agents: {GRAMMAR}. scenarios: {', '.join(scenario_names())} "
                                       "(fawt-<duty>-steady: any duty 30-70), or .yaml/.json files.")
    p.add_argument("--full", action="store_true", help="the full study's defaults (every observer, every Table 4 "
                                                       "duty, 10 seeds) instead of the quick leaderboard's")
    p.add_argument("--agents", default=None, help=f"comma list of agents (default {QUICK[0]})")
    p.add_argument("--scenarios", default=None, help=f"comma list of scenario names or files (default {QUICK[1]}); "
                                                     "the leaderboard ranks on the first")
    p.add_argument("--wind", default=None, help="shorthand for one ad hoc scenario: this wind (e.g. fawt-50) ...")
    p.add_argument("--duration", type=_positive_float, default=None, help="... flown for this many seconds")
    p.add_argument("--seeds", type=_seeds, default=None, help=f"seed count ({QUICK[2]} = seeds 0-{QUICK[2] - 1}, the "
                                                              "default), a range 10:15, or a list 1,4,9")
    p.add_argument("--out", type=Path, default=None, help="results folder (default results/quick, results/full "
                                                          "with --full, results/eval otherwise)")
    p.add_argument("--baseline", default=DEFAULT_BASELINE,
                   help=f"agent the others are compared with, paired (default {DEFAULT_BASELINE})")
    p.add_argument("--rank-on", default=None, help="scenario the printed leaderboard ranks on (default: the first)")
    p.add_argument("--workers", type=_positive_int, default=2, help="local worker processes (default 2)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local processes, or a Ray cluster (pip install 'fawtgym[ray]')")
    p.add_argument("--ray-address", default=None, help="Ray cluster address (default: start a local instance)")
    p.add_argument("--record-hz", type=_positive_float, default=DEFAULT_RECORD_HZ,
                   help=f"rate of the traces kept for figures (default {DEFAULT_RECORD_HZ:g} Hz)")
    p.add_argument("--html", action="store_true", help="also write the leaderboard web page")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    ns = parser.parse_args(argv)
    import fawtgym  # noqa: F401  (registers envs and observers)
    from fawtgym.agents.spec import parse_agents

    from . import leaderboard as lb
    from .runner import read_run, run_cells, update_run_file
    from .scenarios import adhoc_scenario, check_scenario, resolve_scenarios

    if (ns.wind is None) != (ns.duration is None):
        parser.error("--wind and --duration go together (one ad hoc scenario)")
    preset = FULL if ns.full else QUICK
    if ns.out is None:
        custom = ns.agents is not None or ns.scenarios is not None or ns.wind is not None
        ns.out = Path("results/eval" if custom else ("results/full" if ns.full else "results/quick"))
    ns.seeds = ns.seeds if ns.seeds is not None else list(range(preset[2]))
    try:
        agents = [s.name for s in parse_agents(ns.agents or preset[0])]
        items = [] if ns.scenarios is None and ns.wind else (ns.scenarios or preset[1]).split(",")
        scenarios = resolve_scenarios(items)
        if ns.wind is not None:
            scenarios.append(adhoc_scenario(ns.wind, ns.duration))
        for sc in scenarios:
            check_scenario(sc)
        check_agents(agents, scenarios[0])
        if ns.baseline != DEFAULT_BASELINE:  # the default may be absent: no paired column then
            run_file = Path(ns.out) / "run.json"
            known = list(dict.fromkeys([*(read_run(run_file)["agents"] if run_file.is_file() else []), *agents]))
            ns.baseline = lb.asked_baseline(ns.baseline, known)
        if ns.rank_on is not None and ns.rank_on not in [s.name for s in scenarios]:
            raise ValueError(f"--rank-on {shown(ns.rank_on)} is not one of the scenarios: "
                             f"{', '.join(s.name for s in scenarios)}")
        if ns.backend == "ray":
            try:
                import ray  # noqa: F401
            except ImportError:
                raise ValueError("--backend ray needs Ray: pip install 'fawtgym[ray]'") from None
        _check_out(ns.out)
        command = "fawtgym eval " + " ".join(shlex.quote(a) for a in argv)
        update_run_file(ns.out, agents, scenarios, ns.seeds, ns.baseline, command, ns.record_hz)
    except ValueError as exc:
        parser.error(str(exc))
    print(f"{len(agents)} agent(s) x {len(scenarios)} scenario(s) x {len(ns.seeds)} seed(s) -> {ns.out}", flush=True)
    summary = run_cells(ns.out, agents, scenarios, ns.seeds, backend=ns.backend, workers=ns.workers,
                        ray_address=ns.ray_address, record_hz=ns.record_hz, progress=not ns.no_progress)
    print(f"{len(summary['done'])} cell(s) flown, {len(summary['skipped'])} already finished, "
          f"{len(summary['errors'])} failed to run ({summary['wall_seconds']:.0f} s)")
    for (agent, sc), msg in summary["errors"].items():
        print(f"fawtgym eval: cell {agent} on {sc} failed to run: {msg}", file=sys.stderr)
    try:
        board = lb.leaderboard(ns.out, ns.rank_on or scenarios[0].name,  # the default px4 may not have flown
                               None if ns.baseline == DEFAULT_BASELINE else ns.baseline)
    except ValueError as exc:
        print(f"fawtgym eval: no leaderboard: {exc}", file=sys.stderr)
        return 1
    paths = lb.write_outputs(board, ns.out)
    if ns.html:
        from .leaderboard_html import write_html

        paths.append(write_html(board, ns.out, ns.out / "html"))
    head, rows = lb.ranked_rows(board)
    print(f"\nLeaderboard on {board['scenario']} ({len(board['seeds'])} seeds, paired):")
    print(lb.markdown_table(head, rows))
    print("written: " + ", ".join(str(p) for p in paths))
    return 1 if summary["errors"] else 0


def check_agents(agents: Sequence[str], scenario: Scenario) -> None:
    """Build every agent once for a one-vehicle env of ``scenario`` (bad gains, parameters or plugins fail here,
    before any work, with the agent's one-line ValueError)."""
    from fawtgym.agents.spec import agent_action_type, make_agent
    from fawtgym.envs.hover_batch_env import HoverBatchEnv

    for name in agents:
        env = HoverBatchEnv(num_envs=1, **scenario.env_options(), action_type=agent_action_type(name))
        try:
            _, info = env.reset(seed=0)
            agent = make_agent(name, env)
            try:
                agent.reset(info)
            except (ValueError, TypeError, KeyError) as exc:
                raise ValueError(f"agent {shown(name)} cannot start on scenario {shown(scenario.name)}: {exc}") from exc
        finally:
            env.close()


def _check_out(out: Path) -> None:
    """Fail before any work if ``out`` cannot be a writable folder."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a folder")
    probe = out
    while not probe.exists():
        probe = probe.parent
    import os

    if not probe.is_dir():
        raise ValueError(f"--out {str(out)!r}: {str(probe)!r} is a file, not a folder")
    if not os.access(probe, os.W_OK):
        raise ValueError(f"--out {str(out)!r}: {str(probe)!r} is not writable")


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
