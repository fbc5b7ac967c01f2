"""The ``fawtgym`` command line: one entry point, subcommands dispatched to the modules that own them.

Each subcommand lives in the folder that owns its job and exposes ``main(argv) -> int``; this file
only routes, so importing it stays cheap.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from fawtgym.cli_parser import ArgumentParser

#: subcommand -> (module:function, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("fawtgym.eval.demo:main", "PX4 vs PX4+FFTS-ESO on the Table 4 hover, with Table 4's metric"),
    "list": ("fawtgym.cli:list_main", "list vehicles, wind presets, observers, env ids"),
    "wind": ("fawtgym.envs.wind.cli:main", "FAWT/Dryden wind, plotted and compared to Wang et al. (2024) Table 3"),
    "eval": ("fawtgym.eval.runner_cli:main", "fly agents x scenarios x seeds on the same wind; resumable result cells"),
    "leaderboard": ("fawtgym.eval.leaderboard:main", "rank the agents of an eval run (Markdown, CSV, JSON, HTML)"),
    "train": ("fawtgym.train.cli:main", "train a Stable-Baselines3 policy (or a sweep) on the batched hover env"),
    "reproduce": ("fawtgym.cli:reproduce_main", "reproduce a paper's numerical study (see: fawtgym reproduce --help)"),
    "observe": ("fawtgym.flightlog.cli:main", "run observers on a real flight log (PX4 .ulg or MAVLink .tlog)"),
    "bench": ("fawtgym.cli:bench_main", "speed benchmarks, printed as ratios measured in one run"),
    "sitl": ("fawtgym.eval.sitl.cli:sitl_main", "our env as PX4's simulator over MAVLink (HIL lockstep on TCP 4560)"),
    "replay": ("fawtgym.eval.sitl.cli:replay_main", "fly an agent through a real autopilot in OFFBOARD over MAVLink"),
}

#: reproduce <name> -> module:function
REPRODUCTIONS: dict[str, tuple[str, str]] = {
    "seed000-sim": ("fawtgym.eval.reproduce.seed000_sim:main", "FFTS-ESO vs LESO/FxTSDO/STO, Wang et al. 2024 Sec. 6"),
    "table4": ("fawtgym.eval.reproduce.table4:main", "PX4 vs PX4+ESO hover in FAWT wind, Wang et al. (2024) Table 4"),
    "geso": ("fawtgym.eval.reproduce.geso:main", "GESO orders 1-3 with backstepping, Shi et al. (2018) Sec. VI-A"),
    "hc-eso": ("fawtgym.eval.reproduce.hc_eso:main", "HC-ESO on SO(3), Wang & Sanyal (2022) Sec. 6"),
    "qb": ("fawtgym.eval.reproduce.qb_observer:main", "QB observer by SDP, Cayero et al. (2019) Figs. 4-7"),
    "pdt-sta": ("fawtgym.eval.reproduce.pdt_sta:main", "predefined-time STA + QUEST, Silva & Santos (2023), Figs. 5-9"),
    "all": ("fawtgym.eval.reproduce.report:main", "every study above, one report with a verdict per paper claim"),
}

#: bench <name> -> module:function
BENCHMARKS: dict[str, tuple[str, str]] = {
    "env": ("fawtgym.eval.bench.env:main", "calm env steps/s vs raw MuJoCo stepping"),
    "wind": ("fawtgym.eval.bench.wind:main", "wind + aero update cost, single and N = 1024"),
    "observers": ("fawtgym.eval.bench.observers:main", "per-update cost of every observer, single and N = 1024"),
    "closed-loop": ("fawtgym.eval.bench.closed_loop:main", "PX4 + FFTS-ESO in FAWT-50 wind: real-time factor"),
    "qb-sdp": ("fawtgym.eval.bench.qb_sdp:main", "one QB-observer SDP at fixed alpha"),
    "train": ("fawtgym.eval.bench.train:main", "PPO end-to-end env-steps/s beside the training env alone"),
    "flightlog": ("fawtgym.flightlog.bench:main", "observe, one observer, on a 20-min PX4 log (a real one tiled)"),
    "eval": ("fawtgym.eval.bench.eval:main", "quick leaderboard: cells/min, vehicle-s per wall-s vs the env alone"),
    "render": ("fawtgym.eval.bench.render:main", "HoverEnv.render() frames/s vs MuJoCo's default render quality"),
}


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if isinstance(exc, ValueError) else f"{type(exc).__name__}: {text}"


def _call(target: str, argv: Sequence[str], prog: str = "fawtgym") -> int:
    """Run ``module:function(argv)``; a refused value or a missing file ends in one line on stderr and exit 2.

    The subcommands validate their arguments before long work; what a deeper validation layer still
    raises as ``ValueError`` (or a file error) is printed as one line too.  ``FAWTGYM_TRACEBACK=1``
    shows the traceback instead.
    """
    module_name, func_name = target.split(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.startswith("fawtgym"):
            print(f"{prog}: error: {module_name} is not available in this build ({exc})", file=sys.stderr)
            return 2
        print(f"{prog}: error: this command needs the Python package {exc.name!r}, which is not installed "
              f"(pip install {exc.name}, or one of fawtgym's extras: see the README)", file=sys.stderr)
        return 2
    try:
        return int(getattr(module, func_name)(list(argv)) or 0)
    except ModuleNotFoundError as exc:
        if os.environ.get("FAWTGYM_TRACEBACK") or (exc.name or "").startswith("fawtgym"):
            raise
        print(f"{prog}: error: this command needs the Python package {exc.name!r}, which is not installed "
              f"(pip install {exc.name}, or one of fawtgym's extras: see the README)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError) as exc:
        if os.environ.get("FAWTGYM_TRACEBACK"):
            raise
        print(f"{prog}: error: {_one_line(exc)} (FAWTGYM_TRACEBACK=1 shows where)", file=sys.stderr)
        return 2


def _dispatch(prog: str, table: dict[str, tuple[str, str]], argv: Sequence[str], what: str) -> int:
    names = "\n".join(f"  {k:14s} {h}" for k, (_, h) in table.items())
    parser = ArgumentParser(prog=prog, description=f"{what}. Names:\n{names}",
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    run_all = prog.endswith("bench") and "all" not in table
    parser.add_argument("name", choices=list(table) + (["all"] if run_all else []),
                        help="one of: " + ", ".join(list(table) + (["all"] if run_all else [])))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="passed to the named job (try: NAME --help)")
    ns = parser.parse_args(argv)
    if run_all and ns.name == "all":
        every = ArgumentParser(prog=f"{prog} all", formatter_class=argparse.RawDescriptionHelpFormatter,
                               description=f"Run every benchmark below with its defaults, one after the other "
                                           f"(each one's options: {prog} NAME --help).\n{names}")
        every.add_argument("--no-progress", action="store_true", help="no progress bar over the jobs")
        return _call_every(prog, table, every.parse_args(ns.args).no_progress)
    return _call(table[ns.name][0], ns.args, f"{prog} {ns.name}")


def _call_every(prog: str, table: dict[str, tuple[str, str]], no_progress: bool) -> int:
    """Every job of ``table`` with its defaults, one after the other, under a bar over the jobs on stderr (the
    jobs' printed lines pass above it); returns the worst exit status."""
    import contextlib

    from tqdm.auto import tqdm
    from tqdm.contrib import DummyTqdmFile

    codes = []
    with tqdm(total=len(table), unit="job", file=sys.stderr, dynamic_ncols=True, leave=False,
              disable=no_progress) as bar, contextlib.redirect_stdout(DummyTqdmFile(sys.stdout)):
        for name, (target, _) in table.items():
            bar.set_description(f"{prog} {name}")
            codes.append(_call(target, [], f"{prog} {name}"))
            bar.update(1)
    return max(codes)


def reproduce_main(argv: Sequence[str]) -> int:
    return _dispatch("fawtgym reproduce", REPRODUCTIONS, argv, "Reproduce a paper's numerical study")


def bench_main(argv: Sequence[str]) -> int:
    return _dispatch("fawtgym bench", BENCHMARKS, argv, "Run a speed benchmark")


def list_main(argv: Sequence[str]) -> int:
    ArgumentParser(prog="fawtgym list", description=COMMANDS["list"][1]).parse_args(argv)
    import gymnasium as gym

    import fawtgym
    from fawtgym.envs.vehicles import VEHICLE_NAMES
    from fawtgym.envs.wind import wind_names
    from fawtgym.observers import observer_names

    print("vehicles: ", ", ".join(VEHICLE_NAMES))
    print("winds:    ", ", ".join(wind_names()))
    print("observers:", ", ".join(observer_names()))
    print("env ids:  ", ", ".join(k for k in gym.registry if k.startswith(fawtgym.ENV_NAMESPACE + "/")))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = ArgumentParser(
        prog="fawtgym", description="fawtgym: quadrotor disturbance-rejection lab.",
        epilog="subcommands:\n" + "\n".join(f"  {k:10s} {h}" for k, (_, h) in COMMANDS.items()),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("command", choices=list(COMMANDS), metavar="COMMAND", help="one of: " + ", ".join(COMMANDS))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="arguments of the subcommand")
    ns = parser.parse_args(argv[:1] if argv and not argv[0].startswith("-") else argv)
    return _call(COMMANDS[ns.command][0], argv[1:], f"fawtgym {ns.command}")


if __name__ == "__main__":
    raise SystemExit(main())
