"""``fawtgym demo``: PX4-style hover in front of the fan array, with and without the FFTS-ESO feedforward.

The s500 hovers 1.5 m in front of the fan-array wind tunnel (FAWT) of Wang et al. (2024), Sec. 7.3.
Two agents fly the same wind and sensor-noise realization: ``px4`` (PX4 v1.13 cascade, S500
parameters) and ``px4+ffts_eso`` (the same plus the feedforward F = F0 - phi_hat, tau = tau0 - tau_hat
of Sec. 7.2, with the paper's flight gains).  Both are flown by the evaluation runner
(:func:`fawtgym.eval.runner.fly_cell`) and measured by its metrics (:mod:`fawtgym.eval.metrics`).

By default the demo flies the ``table4-<duty>`` scenario (75 s, fan on at 5 s and off at 50 s, as
``fawtgym reproduce table4`` flies it) and prints Table 4's metric: the time-averaged position and
attitude error, re-weighted to the paper's 210 s schedule, next to the paper's number at that duty.
``--seconds S --fan-on T`` flies a short custom window instead; it prints the time average over that
window, labelled as such, and no paper comparison (the windows differ).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any

#: the two agents, in the agent grammar (fawtgym.agents.spec), and how they are labelled
AGENTS = (("px4", "PX4"), ("px4+ffts_eso", "PX4+FFTS-ESO"))
#: longest custom window [s] (a demo, not a study: the study is fawtgym eval / reproduce table4)
MAX_SECONDS = 600.0


def _fmt(v: Any, digits: int = 4) -> str:
    return "n/a" if v is None or not math.isfinite(float(v)) else f"{float(v):.{digits}f}"


def main(argv: Sequence[str] | None = None) -> int:
    from fawtgym.cli_parser import ArgumentParser, duty_percent, nonnegative_float, positive_float, seed

    parser = ArgumentParser(prog="fawtgym demo", description=__doc__.split("\n\n")[0],
                            epilog="By default the demo flies the Table 4 hover of Wang et al. (2024) (75 s, about a "
                                   "minute) and prints Table 4's metric beside the paper's numbers; --seconds flies a "
                                   "short custom window instead, labelled as such and not compared with the paper. "
                                   "The duty is in percent, as in the wind names fawt-30 ... fawt-70.")
    parser.add_argument("--duty", type=duty_percent(30.0, 70.0), default=50.0,
                        help="FAWT duty in percent (default 50); Table 4's rows are 30, 40, 50, 60, 70; other duties "
                             "from 30 to 70 only with --seconds")
    parser.add_argument("--seed", type=seed, default=0, help="seed of the wind and sensor noise (default 0)")
    parser.add_argument("--seconds", type=positive_float, default=None,
                        help=f"fly a custom window of this many seconds (at most {MAX_SECONDS:g}) instead of the "
                             "Table 4 hover")
    parser.add_argument("--fan-on", type=nonnegative_float, default=None,
                        help="with --seconds: fan switch-on time [s] (default a third of --seconds)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))

    from fawtgym.eval.reproduce.table4 import PAPER_TABLE4
    from fawtgym.eval.scenarios import TABLE4_DUTIES, get_scenario, scenario_from_mapping

    duty = args.duty
    if args.seconds is None:
        if args.fan_on is not None:
            parser.error(f"--fan-on {args.fan_on:g} needs --seconds (the Table 4 hover has its own schedule)")
        if duty not in TABLE4_DUTIES:
            parser.error(f"--duty {duty:g}: Table 4 has the duties {', '.join(map(str, TABLE4_DUTIES))}; "
                         "for another duty fly a custom window with --seconds")
        scenario = get_scenario(f"table4-{int(duty)}")
        paper = True
    else:
        if args.seconds > MAX_SECONDS:
            parser.error(f"--seconds {args.seconds:g}: a demo window is at most {MAX_SECONDS:g} s "
                         "(longer studies: fawtgym eval)")
        fan_on = args.seconds / 3 if args.fan_on is None else args.fan_on
        if not fan_on < args.seconds:
            parser.error(f"--fan-on {fan_on:g} must be earlier than --seconds {args.seconds:g}")
        wind: dict[str, Any] = ({"name": f"fawt-{int(duty)}"} if duty in TABLE4_DUTIES
                                else {"name": "fawt", "duty": duty / 100})
        wind["on_time"] = fan_on
        scenario = scenario_from_mapping("demo", {"wind": wind, "seconds": args.seconds})
        paper = False

    from fawtgym.eval.runner import fly_cell

    on, off = scenario.fan_schedule
    print(f"s500 hovering 1.5 m in front of the fan array, FAWT {duty:g} % duty, fan on at {on:g} s"
          + (f" and off at {off:g} s" if off is not None else "") + f" of a {scenario.seconds:g} s hover; "
          f"motion capture + IMU at {scenario.control_rate:g} Hz; seed {args.seed}.")
    results: dict[str, dict[str, Any]] = {}
    steps = int(round(scenario.seconds * scenario.control_rate))
    for agent, label in AGENTS:
        bar = None
        if not args.no_progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=steps, desc=label, unit="step", leave=False, dynamic_ncols=True, file=sys.stderr)
        try:
            cell, _ = fly_cell(agent, scenario.to_dict(), [args.seed], progress=None if bar is None else bar.update)
        finally:
            if bar is not None:
                bar.close()
        results[label] = cell["episodes"][0]

    if paper:
        print("Table 4's metric: time-averaged error, re-weighted to the paper's 210 s schedule (fan on 20-170 s).")
        print(f"{'controller':>14s} | {'position [m]':>12s} | {'paper [m]':>9s} | {'attitude [rad]':>14s} | "
              f"{'paper [rad]':>11s} | result")
        row = PAPER_TABLE4[int(duty)]
        for i, (label, e) in enumerate(results.items()):
            p_pos, p_att = row[i], row[2 + i]
            print(f"{label:>14s} | {_fmt(e['pos_err_paper_schedule']):>12s} | "
                  f"{'Failed!' if p_pos is None else _fmt(p_pos):>9s} | {_fmt(e['att_err_paper_schedule']):>14s} | "
                  f"{'Failed!' if p_att is None else _fmt(p_att):>11s} | "
                  f"{('FAILED: ' + e['failure']) if e['failure'] else 'held hover'}")
        key = "pos_err_paper_schedule"
    else:
        print(f"Time-averaged error over this {scenario.seconds:g} s window (fan on from {on:g} s): a demo window, "
              "not Table 4's schedule, so no paper numbers beside it.")
        print(f"{'controller':>14s} | {'position [m]':>12s} | {'attitude [rad]':>14s} | result")
        for label, e in results.items():
            print(f"{label:>14s} | {_fmt(e['pos_err_mean']):>12s} | {_fmt(e['att_err_mean']):>14s} | "
                  f"{('FAILED: ' + e['failure']) if e['failure'] else 'held hover'}")
        key = "pos_err_mean"
    eso = results["PX4+FFTS-ESO"]
    print(f"PX4+FFTS-ESO disturbance estimate vs truth (RMS error): force {_fmt(eso['force_rmse'], 3)} N, "
          f"torque {_fmt(eso['torque_rmse'], 4)} N m.")
    a, b = (results[label][key] for _, label in AGENTS)
    if all(v is not None and math.isfinite(v) and v > 0 for v in (a, b)):
        line = f"The observer feedforward changes the position error by {100 * (b / a - 1):+.0f} %"
        if paper and row[0] is not None:
            line += f" (Table 4 at {duty:g} %: {100 * (row[1] / row[0] - 1):+.0f} %)"
        print(line + ". Full study: fawtgym reproduce table4; leaderboard: fawtgym eval.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
