"""``fawtgym leaderboard RESULTS``: rank the agents of an eval run, with honest uncertainty.

Ranking rule (on one scenario, ``--scenario``, default the run's first): agents that flew every seed to
the end come first, ordered by the mean over seeds of the time-averaged position error
(``pos_err_mean``, Wang et al. 2024 Table 4's metric); agents with failures come after them, fewer
failures first, then by the mean error of the episodes they completed; equal means are ordered by the
upper end of the 95 % interval.  Beside each mean: its 95 % bootstrap interval (BCa), the failure rate
with its Wilson interval, and the paired difference to the baseline agent (``--baseline``, default
``px4``) over the seeds both completed, with its interval.  The column "beats next" says whether the
paired difference to the next-ranked agent excludes zero (95 %): where it does not, the two are not
distinguishable with these seeds.

Outputs (in the results folder, or ``--out``): ``leaderboard.md``, ``leaderboard.csv`` (one row per
agent and scenario, every metric with its interval), ``leaderboard.json`` (everything), and with
``--html`` a self-contained page ``html/index.html`` with its figures.  ``--best`` prints the winner's
agent name alone on the last line (what the SITL replay reads).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fawtgym.cli_parser import ArgumentParser
from fawtgym.core.checks import shown

from .metrics import METRIC_LABELS, NUMERIC_METRICS
from .runner import iter_missing, load_run
from .stats import Estimate, failure_rate, mean_ci, paired_difference

PRIMARY = "pos_err_mean"
DEFAULT_BASELINE = "px4"
#: per-scenario columns of the printed table: (metric, header)
TABLE_METRICS = (("att_err_mean", "att. error [rad]"), ("force_rmse", "force RMSE [N]"),
                 ("torque_rmse", "torque RMSE [N m]"))


def _values(cell: Mapping[str, Any], metric: str, completed: bool = True) -> list[float | None]:
    """Per-seed values of ``metric``; None for failed episodes when ``completed``."""
    out = []
    for e in cell["episodes"]:
        v = e.get(metric)
        out.append(None if (completed and e["failure"]) or v is None else float(v))
    return out


def summarize_cell(cell: Mapping[str, Any], baseline: Mapping[str, Any] | None) -> dict[str, Any]:
    """Aggregates of one cell: every metric's mean and interval, failures, the paired difference to ``baseline``."""
    eps = cell["episodes"]
    k = sum(1 for e in eps if e["failure"])
    out: dict[str, Any] = {"agent": cell["agent"], "scenario": cell["scenario"]["name"], "n": len(eps),
                           "failures": k, "failure_rate": failure_rate(k, len(eps)).to_dict(),
                           "failure_rules": sorted({e["failure"] for e in eps if e["failure"]}),
                           "metrics": {}}
    for m in NUMERIC_METRICS:
        vals = _values(cell, m, completed=m not in ("failure_time", "time_flown"))
        out["metrics"][m] = mean_ci(vals).to_dict()
    if baseline is not None and baseline is not cell:
        diff, rel = paired_difference(_values(cell, PRIMARY), _values(baseline, PRIMARY))
        out["vs_baseline"] = {"agent": baseline["agent"], "difference": diff.to_dict(), "relative": rel}
    return out


def _rank_key(s: Mapping[str, Any]) -> tuple:
    m = s["metrics"][PRIMARY]
    value = m["value"] if m["value"] is not None else math.inf
    high = m["high"] if m["high"] is not None else math.inf
    return (s["failures"] > 0, s["failures"], value, high, s["agent"])


def asked_baseline(baseline: str, agents: Sequence[str]) -> str:
    """An asked-for baseline (``--baseline``) as the run names it: its canonical name in any spelling the agent
    grammar reads; ValueError unless it is one of ``agents``."""
    from fawtgym.agents.spec import parse_agent

    try:
        baseline = parse_agent(baseline).name
    except ValueError:
        pass  # not an agent name at all: refused just below
    if baseline not in agents:
        raise ValueError(f"--baseline {shown(baseline)} is not an agent of this run; agents: {', '.join(agents)}")
    return baseline


def build(run: Mapping[str, Any], cells: Mapping[tuple[str, str], Mapping[str, Any]], scenario: str | None = None,
          baseline: str | None = None) -> dict[str, Any]:
    """The leaderboard as data: ranking on ``scenario`` and every scenario's summaries."""
    scenarios = [s["name"] for s in run["scenarios"]]
    agents = list(run["agents"])
    if not scenarios:
        raise ValueError("this run has no scenario yet: fly one with fawtgym eval")
    scenario = scenario or scenarios[0]
    if scenario not in scenarios:
        raise ValueError(f"scenario {shown(scenario)} is not in this run; its scenarios: {', '.join(scenarios)}")
    if baseline is not None:
        baseline = asked_baseline(baseline, agents)
    else:  # the run's (or the default, px4): none if it did not fly
        baseline = run.get("baseline", DEFAULT_BASELINE)
        if baseline not in agents:
            baseline = None
    per: dict[str, dict[str, Any]] = {}
    for sc in scenarios:
        base_cell = cells.get((baseline, sc)) if baseline else None
        per[sc] = {a: summarize_cell(cells[(a, sc)], base_cell) for a in agents if (a, sc) in cells}
    if not per[scenario]:
        raise ValueError(f"no finished cell for scenario {shown(scenario)} yet")
    ranked = sorted(per[scenario].values(), key=_rank_key)
    order = [s["agent"] for s in ranked]
    beats: dict[str, bool | None] = {}
    for a, b in zip(order, order[1:], strict=False):
        diff, _ = paired_difference(_values(cells[(a, scenario)], PRIMARY), _values(cells[(b, scenario)], PRIMARY))
        fa, fb = per[scenario][a]["failures"], per[scenario][b]["failures"]
        if fa == 0 and fb > 0:
            beats[a] = True
        else:
            beats[a] = None if diff.high is None else bool(diff.high < 0)
    return {"scenario": scenario, "baseline": baseline, "seeds": run["seeds"], "ranking": order, "beats_next": beats,
            "summaries": per, "scenarios": run["scenarios"], "agents": agents,
            "missing": [list(p) for p in iter_missing(run, cells)],
            "rule": " ".join(__doc__.split("\n\n")[1].replace("``", "`").split())}


def _num(v: float | None, digits: int = 4) -> str:
    if v is None:
        return "n/a"
    if v != 0 and (abs(v) < 10 ** -(digits - 1) or abs(v) >= 1e4):
        return f"{v:.{max(digits - 2, 1)}e}"
    return f"{v:.{digits}f}"


def fmt_ci(e: Mapping[str, Any], digits: int = 4) -> str:
    """``value [low, high]`` (``value`` alone when there is no interval)."""
    if e["value"] is None:
        return "n/a"
    if e["low"] is None:
        return _num(e["value"], digits)
    return f"{_num(e['value'], digits)} [{_num(e['low'], digits)}, {_num(e['high'], digits)}]"


def _fmt_fail(s: Mapping[str, Any]) -> str:
    fr = s["failure_rate"]
    text = f"{s['failures']}/{s['n']}"
    if fr["low"] is not None:
        text += f" [{100 * fr['low']:.0f}-{100 * fr['high']:.0f} %]"
    if s["failure_rules"]:
        text += " " + ",".join(s["failure_rules"])
    return text


def _fmt_vs(s: Mapping[str, Any]) -> str:
    vs = s.get("vs_baseline")
    if vs is None:
        return "n/a"
    d = vs["difference"]
    if d["value"] is None:
        return "n/a"
    rel = "" if vs["relative"] is None else f" ({100 * vs['relative']:+.0f} %)"
    return f"{fmt_ci(d)}{rel}"


def ranked_rows(board: Mapping[str, Any]) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the main table (the ranking scenario, plus the mean error on the other scenarios)."""
    sc = board["scenario"]
    others = [s["name"] for s in board["scenarios"] if s["name"] != sc]
    head = ["rank", "agent", "mean position error [m] (95 % CI)", "failures (95 % CI)",
            f"vs {board['baseline'] or 'baseline'} [m] (paired)", "beats next"]
    head += [h for _, h in TABLE_METRICS] + [f"{o} [m]" for o in others]
    rows = []
    for i, agent in enumerate(board["ranking"], 1):
        s = board["summaries"][sc][agent]
        b = board["beats_next"].get(agent)
        row = [str(i), agent, fmt_ci(s["metrics"][PRIMARY]), _fmt_fail(s),
               "(baseline)" if agent == board["baseline"] else _fmt_vs(s),
               "-" if agent not in board["beats_next"] else ("yes" if b else "no" if b is False else "n/a")]
        row += [_num(s["metrics"][m]["value"]) for m, _ in TABLE_METRICS]
        for o in others:
            so = board["summaries"][o].get(agent)
            if so is None:
                row.append("missing")
            else:
                val = _num(so["metrics"][PRIMARY]["value"])
                row.append(val + (f" ({so['failures']} failed)" if so["failures"] else ""))
        rows.append(row)
    return head, rows


def markdown_table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def scenario_rows(board: Mapping[str, Any], scenario: str) -> tuple[list[str], list[list[str]]]:
    """Every metric of every agent on one scenario (detail table)."""
    metrics = [m for m in NUMERIC_METRICS if m not in ("time_flown",)]
    summaries = board["summaries"][scenario]
    metrics = [m for m in metrics if any(s["metrics"][m]["value"] is not None for s in summaries.values())]
    head = ["agent", "failures"] + [f"{METRIC_LABELS[m][0]} [{METRIC_LABELS[m][1]}]" for m in metrics]
    rows = [[a, _fmt_fail(s)] + [fmt_ci(s["metrics"][m]) for m in metrics] for a, s in summaries.items()]
    return head, rows


def table4_rows(board: Mapping[str, Any]) -> tuple[list[str], list[list[str]]] | None:
    """Our table4-<duty> means beside Wang et al. (2024) Table 4 (None if the run has no table4 scenario)."""
    from .reproduce.table4 import PAPER_TABLE4
    from .scenarios import table4_duty

    duties = [d for d in (table4_duty(s) for s in board["scenarios"]) if d is not None]
    if not duties:
        return None
    agents = board["agents"]
    head = ["duty", *[f"{a} [m]" for a in agents], "paper PX4 [m]", "paper PX4+FFTS-ESO [m]"]
    rows = []
    for d in sorted(duties):
        row = [f"{d} %"]
        for a in agents:
            s = board["summaries"][f"table4-{d}"].get(a)
            if s is None:
                row.append("missing")
            elif s["failures"]:
                row.append(f"Failed ({s['failures']}/{s['n']})")
            else:
                row.append(fmt_ci(s["metrics"]["pos_err_paper_schedule"]))
        p = PAPER_TABLE4[d]
        row += ["Failed!" if p[0] is None else f"{p[0]:.4f}", f"{p[1]:.4f}"]
        rows.append(row)
    return head, rows


def to_markdown(board: Mapping[str, Any]) -> str:
    head, rows = ranked_rows(board)
    seeds = board["seeds"]
    lines = [f"# Leaderboard: {board['scenario']}", "",
             f"{len(seeds)} seeds ({seeds[0]}..{seeds[-1]}) per cell, the same wind and sensor noise for every agent "
             "(paired).", "", markdown_table(head, rows), "", board["rule"], ""]
    t4 = table4_rows(board)
    if t4 is not None:
        lines += ["## Beside Wang et al. (2024), Table 4", "",
                  "Mean position error on the paper's schedule (210 s hover, fan on 20-170 s: our flown transients "
                  "plus the calm and fan-on stationary means weighted by the paper's durations), 95 % CI; "
                  "'Failed' if any seed failed.", "", markdown_table(*t4), ""]
    for sc in board["scenarios"]:
        name = sc["name"]
        if not board["summaries"][name]:
            continue
        lines += [f"## {name}", "", sc.get("description", ""), "", markdown_table(*scenario_rows(board, name)), ""]
    if board["missing"]:
        lines += ["Missing cells (not flown yet or failed to run): "
                  + ", ".join(f"{a} on {s}" for a, s in board["missing"]), ""]
    return "\n".join(lines)


def to_csv(board: Mapping[str, Any]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    head = ["scenario", "agent", "rank", "n", "failures", "failure_rate", "failure_rate_low", "failure_rate_high"]
    for m in NUMERIC_METRICS:
        head += [m, f"{m}_low", f"{m}_high"]
    head += ["vs_baseline", "vs_baseline_low", "vs_baseline_high", "vs_baseline_relative"]
    w.writerow(head)
    for sc, summaries in board["summaries"].items():
        for agent, s in summaries.items():
            rank = board["ranking"].index(agent) + 1 if sc == board["scenario"] else ""
            fr = s["failure_rate"]
            row: list[Any] = [sc, agent, rank, s["n"], s["failures"], fr["value"], fr["low"], fr["high"]]
            for m in NUMERIC_METRICS:
                e = s["metrics"][m]
                row += [e["value"], e["low"], e["high"]]
            vs = s.get("vs_baseline")
            d = vs["difference"] if vs else {"value": None, "low": None, "high": None}
            row += [d["value"], d["low"], d["high"], vs["relative"] if vs else None]
            w.writerow(["" if v is None else v for v in row])
    return buf.getvalue()


def write_outputs(board: Mapping[str, Any], out: Path) -> list[Path]:
    """leaderboard.md / .csv / .json in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "leaderboard.md", out / "leaderboard.csv", out / "leaderboard.json"]
    paths[0].write_text(to_markdown(board))
    paths[1].write_text(to_csv(board))
    paths[2].write_text(json.dumps(board, indent=1, allow_nan=False))
    return paths


def best(board: Mapping[str, Any]) -> str:
    """The winner's agent name (rank 1)."""
    return board["ranking"][0]


def leaderboard(results: Path, scenario: str | None = None, baseline: str | None = None) -> dict[str, Any]:
    """Load a results folder and build its leaderboard (ValueError with a one-line reason if it cannot)."""
    run, cells = load_run(results)
    if not cells:
        raise ValueError(f"{results} has no finished cell yet (run: fawtgym eval ... --out {results})")
    return build(run, cells, scenario, baseline)


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="fawtgym leaderboard", description=__doc__.split("\n\n")[0],
                                     epilog=" ".join(__doc__.split("\n\n")[1].split()))
    parser.add_argument("results", type=Path, help="results folder of 'fawtgym eval --out'")
    parser.add_argument("--scenario", default=None, help="scenario to rank on (default: the run's first)")
    parser.add_argument("--baseline", default=None, help="agent for the paired differences (default: the run's, px4)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the tables (default: the results folder)")
    parser.add_argument("--html", action="store_true", help="also write the web page (html/index.html + figures)")
    parser.add_argument("--best", action="store_true", help="print the winner's agent name alone on the last line")
    parser.add_argument("--quiet", action="store_true", help="print nothing but --best's line")
    ns = parser.parse_args(argv)
    try:
        board = leaderboard(ns.results, ns.scenario, ns.baseline)
    except ValueError as exc:
        parser.error(str(exc))
    out = ns.out or ns.results
    try:
        paths = write_outputs(board, out)
        if ns.html:
            from .leaderboard_html import write_html

            paths.append(write_html(board, ns.results, out / "html"))
    except OSError as exc:
        parser.error(f"cannot write to {out}: {exc.strerror or exc}")
    if not ns.quiet:
        head, rows = ranked_rows(board)
        print(f"Leaderboard on {board['scenario']} ({len(board['seeds'])} seeds, paired):")
        print(markdown_table(head, rows))
        if board["missing"]:
            print(f"missing cells: {', '.join(f'{a} on {s}' for a, s in board['missing'])}")
        print("written: " + ", ".join(str(p) for p in paths))
    if ns.best:
        print(best(board))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())


__all__ = ["Estimate", "best", "build", "leaderboard", "main", "to_csv", "to_markdown", "write_outputs"]
