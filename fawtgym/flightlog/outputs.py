"""What ``fawtgym observe`` writes: the estimates over time (CSV, or Parquet with pyarrow), a per-phase
summary (JSON + text) and figures (matplotlib).

Table columns: ``time_s``, ``phase`` (ground/climb/hover/descend/move), ``mode`` (PX4 flight mode),
``estimated`` (1 where the observers ran), the known inputs ``thrust_N``, ``torque_{x,y,z}_Nm``, and per
observer ``<name>_force_{n,e,d}_N`` (world NED) and ``<name>_torque_{x,y,z}_Nm`` (body FRD).  Where
``estimated`` is 0 the estimate cells are empty (CSV) or null (Parquet), never a number.

Summary: per observer and phase, the number of samples and the mean and standard deviation of each
component over the estimated points past the settle time of their airborne segment (the observer's own
start-up transient is left out); ``ground`` is listed with zero samples -- it is shown, not estimated.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from fawtgym.core.checks import shown

from .phases import PHASES, segments
from .runner import ObserveResult

AXES_FORCE = ("n", "e", "d")
AXES_TORQUE = ("x", "y", "z")


def table_columns(result: ObserveResult) -> dict[str, np.ndarray]:
    """The output table as named columns (estimates NaN where not estimated)."""
    modes = np.full(result.t.size, "", dtype=object)
    for t0, t1, name in result.phases.modes:
        modes[(result.t >= t0) & (result.t <= t1)] = name
    cols: dict[str, np.ndarray] = {"time_s": result.t, "phase": result.phases.names().astype(object),
                                   "mode": modes, "estimated": result.estimated.astype(np.int8),
                                   "thrust_N": result.thrust}
    for i, a in enumerate(AXES_TORQUE):
        cols[f"torque_{a}_Nm"] = result.torque[:, i]
    for name, (force, torque) in result.estimates.items():
        for i, a in enumerate(AXES_FORCE):
            cols[f"{name}_force_{a}_N"] = np.where(result.estimated, force[:, i], np.nan)
        for i, a in enumerate(AXES_TORQUE):
            cols[f"{name}_torque_{a}_Nm"] = np.where(result.estimated, torque[:, i], np.nan)
    return cols


def write_table(result: ObserveResult, out_dir: Path, fmt: str = "auto") -> Path:
    """Write ``estimates.parquet`` (``fmt`` parquet, or auto with pyarrow installed) or ``estimates.csv``."""
    cols = table_columns(result)
    if fmt not in ("auto", "csv", "parquet"):
        raise ValueError(f"unknown table format {shown(fmt)}; allowed: auto, csv, parquet")
    if fmt in ("auto", "parquet"):
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            if fmt == "parquet":
                raise ValueError("--format parquet needs pyarrow: pip install pyarrow") from None
        else:
            arrays = {k: pa.array(v.tolist() if v.dtype == object else v,
                                  mask=(np.isnan(v) if v.dtype.kind == "f" else None)) for k, v in cols.items()}
            path = out_dir / "estimates.parquet"
            pq.write_table(pa.table(arrays), path)
            return path
    path = out_dir / "estimates.csv"
    names = list(cols)
    with path.open("w") as fh:
        fh.write(",".join(names) + "\n")
        rows = [_fmt_column(cols[k]) for k in names]
        for i in range(result.t.size):
            fh.write(",".join(r[i] for r in rows) + "\n")
    return path


def _fmt_column(v: np.ndarray) -> list[str]:
    if v.dtype == object:
        return [str(x) for x in v]
    if v.dtype.kind in "iub":
        return [str(int(x)) for x in v]
    return ["" if not math.isfinite(x) else f"{x:.6g}" for x in v.tolist()]


def summary(result: ObserveResult) -> dict[str, Any]:
    """Per observer, per phase: samples, mean and std of force (NED) and torque (FRD), see the module docstring."""
    out: dict[str, Any] = {}
    for name, (force, torque) in result.estimates.items():
        per: dict[str, Any] = {}
        for code, phase in enumerate(PHASES):
            m = result.settled & (result.phases.label == code)
            entry: dict[str, Any] = {"samples": int(m.sum()), "seconds": float(m.sum() / result.report["rate_hz"])}
            if m.any() and np.isfinite(force[m]).all():
                entry.update(force_mean_N=force[m].mean(0).tolist(), force_std_N=force[m].std(0).tolist())
            if m.any() and np.isfinite(torque[m]).all():
                entry.update(torque_mean_Nm=torque[m].mean(0).tolist(), torque_std_Nm=torque[m].std(0).tolist())
            per[phase] = entry
        out[name] = per
    return out


def summary_text(result: ObserveResult, summ: dict[str, Any]) -> str:
    """The summary as aligned text lines (also printed by the CLI)."""
    rep = result.report
    ts = rep["thrust_scale"]
    lines = [f"log {Path(rep['log']).name} ({rep['kind']}, PX4 {rep['px4_version'] or 'unknown'}), "
             f"{rep['duration_s']:.1f} s; vehicle {rep['vehicle']} (m = {rep['mass_kg']:g} kg); "
             f"observers at {rep['rate_hz']:g} Hz, {rep['estimated_s']:.1f} s estimated",
             f"known inputs: {rep['inputs']['source']}; thrust curve {rep['inputs']['thrust_curve']}; "
             f"thrust scale {ts['used']:.3f} (from {ts['from']}; candidates: "
             + ", ".join(f"{k} {v:.3f}" for k, v in ts["candidates"].items()
                         if k in ("estimate", "hover", "param", "preset") and v is not None) + ")",
             "mean +- std per phase, past the settle time; force world NED [N], torque body FRD [N m]"]
    for name, per in summ.items():
        for phase, e in per.items():
            if not e["samples"]:
                what = "shown, not estimated" if phase == "ground" else "no settled samples"
                lines.append(f"  {name:10s} {phase:8s} {what}")
                continue
            f = " ".join(f"{m:+7.3f}+-{s:.3f}" for m, s in zip(e.get("force_mean_N", ()), e.get("force_std_N", ()),
                                                                 strict=True)) or "(not estimated by this observer)"
            t = " ".join(f"{m:+7.4f}+-{s:.4f}" for m, s in zip(e.get("torque_mean_Nm", ()), e.get("torque_std_Nm", ()),
                                                                 strict=True)) or "(not estimated by this observer)"
            lines.append(f"  {name:10s} {phase:8s} {e['seconds']:6.1f} s  F {f}   tau {t}")
    lines += [f"warning: {w}" for w in rep["warnings"]]
    return "\n".join(lines)


def write_summary(result: ObserveResult, out_dir: Path) -> tuple[Path, str]:
    summ = summary(result)
    text = summary_text(result, summ)
    path = out_dir / "summary.json"
    path.write_text(json.dumps({"report": result.report, "phases": summ}, indent=1, default=float))
    (out_dir / "summary.txt").write_text(text + "\n")
    return path, text


def write_figures(result: ObserveResult, out_dir: Path) -> list[Path]:
    """``force.png`` and ``torque.png``: one panel per axis, every observer on the same axes, flight modes
    shaded, points that were not estimated hatched."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("Pastel1")
    mode_names = list(dict.fromkeys(name for _, _, name in result.phases.modes))
    colors = {n: cmap(i % cmap.N) for i, n in enumerate(mode_names)}
    paths = []
    for what, axes, unit, idx in (("force", AXES_FORCE, "N (world NED)", 0), ("torque", AXES_TORQUE,
                                                                            "N m (body FRD)", 1)):
        fig, panels = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
        for i, ax in enumerate(panels):
            labelled: set[str] = set()
            for t0, t1, name in result.phases.modes:
                ax.axvspan(t0, t1, color=colors[name], alpha=0.5, lw=0,
                           label=name if i == 0 and name not in labelled else None)
                labelled.add(name)
            for a, b in segments(~result.estimated):
                ax.axvspan(result.t[a], result.t[b - 1], facecolor="none", hatch="//", edgecolor="0.6", lw=0,
                           label="not estimated" if i == 0 and "-" not in labelled else None)
                labelled.add("-")
            for name, est in result.estimates.items():
                ax.plot(result.t, est[idx][:, i], lw=1.0, label=name if i == 0 else None)
            ax.set_ylabel(f"{what} {axes[i]} [{unit.split(' ')[0] if idx == 0 else 'N m'}]")
            ax.grid(alpha=0.3)
        panels[0].legend(loc="upper left", fontsize=7, ncol=4)
        panels[0].set_title(f"{Path(result.report['log']).name}: estimated disturbance {what}, {unit}")
        panels[-1].set_xlabel("time since log start [s]")
        fig.tight_layout()
        path = out_dir / f"{what}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
