"""The learned-policy study: publish the trained runs, fly them on the leaderboard, write the report.

::

    python -m fawtgym.train.study publish runs/study train/study/runs     # the small files of finished runs
    python -m fawtgym.train.study report train/study/runs docs/study.md    # leaderboard + learning curves + answers

``publish`` copies, per finished run, ``model.zip``, ``vecnormalize.pkl``, ``metadata.json`` and
``evals.jsonl``, plus ``curve.json`` (the training return per rollout, read from its TensorBoard log), so
the committed runs rank on the leaderboard (``sb3:train/study/runs/NAME``) without retraining and the
curves redraw without the logs.

``report`` flies PX4, PX4 + FFTS-ESO and every published run on the study's evaluation scenarios with the
evaluation runner (paired seeds), then writes a Markdown report with: the budget of every run, the
learning curves, the leaderboard, the mean error per configuration (mean over training seeds with a 95 %
bootstrap interval over those seeds), and the two answers computed from those numbers -- does giving the
policy the observer's estimates (``state+eso``) beat ``state`` for the same budget, and does the best
policy beat PX4 and PX4 + FFTS-ESO at 50 % duty.
"""

from __future__ import annotations

import json
import math
import shutil
import sys
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: evaluation scenarios: the Table-4 hovers in the training range (30, 50 %); held out: 70 % (a duty not trained on,
#: flown as the 20 s switching hover: both transients at a tenth of the cost of the 75 s Table-4 hover, which the
#: study's budget could not afford for 20 agents on a shared 2-core machine) and outdoor Dryden turbulence
EVAL_SCENARIOS = ("table4-50", "table4-30", "fawt-70-switching", "dryden-moderate")
HELD_OUT = ("fawt-70-switching", "dryden-moderate")
BASELINES = ("px4", "px4+ffts_eso")
KEEP = ("model.zip", "vecnormalize.pkl", "metadata.json", "evals.jsonl")


def _curve(run: Path) -> dict[str, list[float]]:
    """(steps, mean training episode return) of a run's TensorBoard log; empty if it has none."""
    files = sorted(run.glob("tb/**/events.out.tfevents.*"))
    if not files:
        return {"steps": [], "ep_rew_mean": []}
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    steps: list[float] = []
    values: list[float] = []
    for f in files:
        acc = EventAccumulator(str(f), size_guidance={"scalars": 0})
        acc.Reload()
        if "rollout/ep_rew_mean" in acc.Tags()["scalars"]:
            for e in acc.Scalars("rollout/ep_rew_mean"):
                steps.append(float(e.step))
                values.append(float(e.value))
    order = np.argsort(steps, kind="stable")
    return {"steps": [steps[i] for i in order], "ep_rew_mean": [values[i] for i in order]}


def publish(src: Path, dst: Path) -> list[Path]:
    """Copy the small files of every finished run under ``src`` into ``dst/<run>`` (module docstring)."""
    out = []
    for run in sorted(p for p in Path(src).iterdir() if (p / "metadata.json").is_file()):
        meta = json.loads((run / "metadata.json").read_text())
        if not meta.get("finished"):
            print(f"skipping {run.name}: not finished ({meta.get('steps_done', 0)} steps)", file=sys.stderr)
            continue
        target = Path(dst) / run.name
        target.mkdir(parents=True, exist_ok=True)
        for name in KEEP:
            if (run / name).is_file():
                shutil.copy2(run / name, target / name)
        (target / "curve.json").write_text(json.dumps(_curve(run)))
        out.append(target)
    return out


def _group(meta: dict[str, Any]) -> str:
    c = meta["config"]
    return f"{c['algo']} {c['obs']} {c['action']}"


def _mean_ci(values: list[float]) -> str:
    from fawtgym.eval.leaderboard import fmt_ci
    from fawtgym.eval.stats import mean_ci

    return fmt_ci(mean_ci(values).to_dict())


def _diff_ci(a: list[float | None], b: list[float | None]) -> tuple[float | None, float | None, float | None]:
    """Mean(a) - mean(b) with a 95 % bootstrap interval (independent samples: different training seeds)."""
    from scipy import stats

    a_, b_ = np.array([v for v in a if v is not None]), np.array([v for v in b if v is not None])
    if a_.size < 2 or b_.size < 2:
        return (float(a_.mean() - b_.mean()) if a_.size and b_.size else None), None, None
    res = stats.bootstrap((a_, b_), lambda x, y, axis=-1: x.mean(axis=axis) - y.mean(axis=axis),
                          method="percentile", n_resamples=9999, rng=np.random.default_rng(0), vectorized=True)
    return float(a_.mean() - b_.mean()), float(res.confidence_interval.low), float(res.confidence_interval.high)


def _learning_figure(runs: list[Path], metas: dict[Path, dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups: dict[str, list[Path]] = defaultdict(list)
    for r in runs:
        groups[_group(metas[r])].append(r)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (g, members) in enumerate(sorted(groups.items())):
        c = colors[k % len(colors)]
        for j, r in enumerate(members):
            curve = json.loads((r / "curve.json").read_text()) if (r / "curve.json").is_file() else None
            if curve and curve["steps"]:
                axes[0].plot(curve["steps"], curve["ep_rew_mean"], color=c, lw=0.8, label=g if j == 0 else None)
            evals = [json.loads(line) for line in (r / "evals.jsonl").read_text().splitlines()] \
                if (r / "evals.jsonl").is_file() else []
            pts = [(e["steps"], next(iter(e["results"].values()))["pos_err_mean"]) for e in evals]
            pts = [(s, v if v is not None else np.nan) for s, v in pts]
            if pts:
                axes[1].plot(*zip(*pts, strict=True), "o-", color=c, lw=0.8, ms=3, label=g if j == 0 else None)
    axes[0].set_xlabel("env steps")
    axes[0].set_ylabel("training episode return (20 s episodes)")
    axes[1].set_xlabel("env steps")
    axes[1].set_ylabel("mean position error [m], fawt-50-switching (gap: failed)")
    axes[1].set_yscale("log")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Learning curves: one line per training seed", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(runs_dir: Path, out_md: Path, results: Path, seeds: int = 3, workers: int = 2) -> Path:
    """Fly the published runs and the baselines, write the study's report (module docstring)."""
    from fawtgym.eval import leaderboard as lb
    from fawtgym.eval.runner import load_run, run_cells, update_run_file
    from fawtgym.eval.scenarios import resolve_scenarios

    runs = sorted(p for p in Path(runs_dir).iterdir() if (p / "model.zip").is_file())
    if not runs:
        raise ValueError(f"no published run in {runs_dir}")
    metas = {r: json.loads((r / "metadata.json").read_text()) for r in runs}
    agents = [*BASELINES, *[f"sb3:{r}" for r in runs]]
    scenarios = resolve_scenarios(EVAL_SCENARIOS)
    update_run_file(results, agents, scenarios, list(range(seeds)), "px4", "fawtgym.train.study report", 20.0)
    summary = run_cells(results, agents, scenarios, list(range(seeds)), workers=workers)
    if summary["errors"]:
        raise RuntimeError(f"cells failed: {summary['errors']}")
    run, cells = load_run(results)
    board = lb.build(run, cells, "table4-50", "px4")
    fig = out_md.parent / "study" / "learning_curves.png"
    _learning_figure(runs, metas, fig)

    def per_seed(agent: str, sc: str) -> float | None:
        """An agent's mean position error over the evaluation seeds; None if any seed failed."""
        eps = cells[(agent, sc)]["episodes"]
        return None if any(e["failure"] for e in eps) else float(np.mean([e["pos_err_mean"] for e in eps]))

    groups: dict[str, list[Path]] = defaultdict(list)
    for r in runs:
        groups[_group(metas[r])].append(r)
    lines = ["# The learned-policy study: does a policy that sees the ESO's estimates reject FAWT turbulence better?",
             "", f"Generated by `python -m fawtgym.train.study report {runs_dir} {out_md}`. Every number below is "
             f"recomputed by that command from the committed models in `{runs_dir}`.", "",
             "## Set-up", "",
             "- Training: `fawtgym train --sweep train/study/ppo.yaml` and `train/study/sac.yaml`: the batched env "
             "through the SB3 adapter, the `fawt-50-switching` hover (fan on 2-12 s of 20 s episodes, motion capture + "
             "IMU at 200 Hz), duty drawn per episode from 30-60 %, 16 rows; observations normalized (VecNormalize).",
             "- Policies: `state` (the env's 19 numbers) or `state+eso` (+ the FFTS-ESO's scaled force and torque "
             "estimates, flight gains); actions `ctbr` (normalized collective thrust + body rates, hover at 0) or "
             "`residual` (+-10 % of the motor range on PX4 + FFTS-ESO's motor commands).",
             f"- Evaluation: the evaluation runner, {seeds} seeds paired across agents, on "
             f"{', '.join(EVAL_SCENARIOS)}; held out from training: {', '.join(HELD_OUT)} (a duty not trained on, "
             "and outdoor turbulence); the Table 4 hover is 75 s, longer than the 20 s training episodes.", "",
             "## Budget", "", "| run | algorithm | env steps | wall time [min] |", "|---|---|---|---|"]
    total = 0.0
    for r in runs:
        m = metas[r]
        total += float(m.get("wall_seconds", 0.0))
        lines.append(f"| {r.name} | {m['config']['algo']} | {m.get('steps_done')} | "
                     f"{float(m.get('wall_seconds', 0.0)) / 60:.1f} |")
    lines += ["", f"Total: {total / 3600:.2f} h of training on this 2-core machine (two runs at a time, one core "
              "each).", "", "## Learning curves", "", f"![learning curves](study/{fig.name})", "",
              "## Leaderboard on table4-50", "", lb.markdown_table(*lb.ranked_rows(board)), "",
              "## Per configuration (mean over training seeds, 95 % bootstrap CI over them)", "",
              "Mean position error [m] per scenario; a training seed whose policy failed any evaluation seed counts "
              "as failed.", "",
              "| configuration | " + " | ".join(EVAL_SCENARIOS) + " |", "|---|" + "---|" * len(EVAL_SCENARIOS)]
    for a in BASELINES:
        lines.append(f"| {a} | " + " | ".join(_fmt(per_seed(a, sc)) for sc in EVAL_SCENARIOS) + " |")
    for g, members in sorted(groups.items()):
        cells_txt = []
        for sc in EVAL_SCENARIOS:
            vals = [per_seed(f"sb3:{r}", sc) for r in members]
            ok = [v for v in vals if v is not None]
            fails = len(vals) - len(ok)
            text = _mean_ci(ok) if ok else "all failed"
            cells_txt.append(text + (f" ({fails}/{len(vals)} failed)" if fails else ""))
        lines.append(f"| {g} | " + " | ".join(cells_txt) + " |")
    lines += ["", "## Answers", ""]
    lines += _answers(groups, per_seed)
    out_md.parent.mkdir(parents=True, exist_ok=True)
    out_md.write_text("\n".join(lines) + "\n")
    return out_md


def _fmt(v: float | None) -> str:
    return "failed" if v is None else f"{v:.4f}"


def _answers(groups: dict[str, list[Path]], per_seed: Any) -> list[str]:
    lines = []
    for g_state in sorted(g for g in groups if " state " in f" {g} " and "state+eso" not in g):
        g_eso = g_state.replace(" state ", " state+eso ")
        if g_eso not in groups:
            continue
        for sc in ("table4-50", "fawt-70-switching"):
            a = [per_seed(f"sb3:{r}", sc) for r in groups[g_eso]]
            b = [per_seed(f"sb3:{r}", sc) for r in groups[g_state]]
            d, lo, hi = _diff_ci(a, b)
            fa, fb = sum(v is None for v in a), sum(v is None for v in b)
            if d is None:
                verdict = "cannot say (too many failed training seeds)"
            elif lo is None or hi is None:
                verdict = f"difference {d:+.4f} m, too few seeds for an interval"
            elif hi < 0:
                verdict = f"**yes**: state+eso - state = {d:+.4f} m [{lo:+.4f}, {hi:+.4f}]"
            elif lo > 0:
                verdict = f"**no, worse**: state+eso - state = {d:+.4f} m [{lo:+.4f}, {hi:+.4f}]"
            else:
                verdict = f"**not distinguishable**: state+eso - state = {d:+.4f} m [{lo:+.4f}, {hi:+.4f}]"
            lines.append(f"- Does `state+eso` beat `state` ({g_state.replace(' state', '')}, {sc})? {verdict} "
                         f"(failed training seeds: state+eso {fa}, state {fb}).")
    best_agent, best_val = None, math.inf
    for members in groups.values():
        for r in members:
            v = per_seed(f"sb3:{r}", "table4-50")
            if v is not None and v < best_val:
                best_agent, best_val = r, v
    px4, eso = per_seed("px4", "table4-50"), per_seed("px4+ffts_eso", "table4-50")
    if best_agent is None:
        lines.append("- Does the best policy beat PX4 and PX4 + FFTS-ESO at 50 % duty? **No**: every policy failed.")
    else:
        beats = [name for name, v in (("PX4", px4), ("PX4 + FFTS-ESO", eso)) if v is None or best_val < v]
        loses = [name for name, v in (("PX4", px4), ("PX4 + FFTS-ESO", eso)) if v is not None and best_val >= v]
        lines.append(f"- Does the best policy beat PX4 and PX4 + FFTS-ESO at 50 % duty? The best, `{best_agent.name}`, "
                     f"flies {best_val:.4f} m (PX4 {_fmt(px4)}, PX4 + FFTS-ESO {_fmt(eso)}): "
                     + (f"it beats {' and '.join(beats)}" if beats else "it beats neither")
                     + (f"; it does not beat {' or '.join(loses)}." if loses else "."))
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    from fawtgym.cli_parser import ArgumentParser

    p = ArgumentParser(prog="python -m fawtgym.train.study", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    pub = sub.add_parser("publish", help="copy the small files of finished runs")
    pub.add_argument("src", type=Path)
    pub.add_argument("dst", type=Path)
    rep = sub.add_parser("report", help="fly the published runs and write the report")
    rep.add_argument("runs", type=Path)
    rep.add_argument("out", type=Path)
    rep.add_argument("--results", type=Path, default=Path("results/study"))
    rep.add_argument("--seeds", type=int, default=3)
    rep.add_argument("--workers", type=int, default=2)
    ns = p.parse_args(argv)
    try:
        if ns.cmd == "publish":
            for t in publish(ns.src, ns.dst):
                print(t)
        else:
            print(report(ns.runs, ns.out, ns.results, ns.seeds, ns.workers))
    except (ValueError, OSError) as exc:
        p.error(str(exc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
