"""The leaderboard as a self-contained web page: ``index.html`` + PNG figures in one folder, no server, no network.

Figures (matplotlib, written next to the page):

* ``ranking.png``: mean position error with its 95 % interval, per scenario and agent (failures marked);
* ``table4_bars.png``: when the run has ``table4-<duty>`` scenarios, grouped bars per duty like Wang et
  al. (2024) Table 4, our agents beside the paper's PX4 and PX4 + FFTS-ESO numbers;
* ``traces_<scenario>.png``: position error and attitude error over time (seed mean, band = seed range),
  the fan-on interval shaded;
* ``estimation_<scenario>.png``: the observers' force and torque estimation errors over time;
* ``wind_psd.png``: the spectrum of the stream-wise wind the vehicles met (first seed, fan-on stationary
  part) against the model's analytic (Dryden) spectrum, sampled at the control rate.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .html_page import HtmlPage
from .runner import read_traces

_COLORS = ["tab:blue", "tab:red", "tab:green", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:gray",
           "tab:olive", "tab:cyan"]


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _color(agents: Sequence[str], agent: str) -> str:
    return _COLORS[agents.index(agent) % len(_COLORS)]


def _ranking_figure(board: Mapping[str, Any], path: Path) -> None:
    plt = _plt()
    agents = board["ranking"] + [a for a in board["agents"] if a not in board["ranking"]]
    scenarios = [s["name"] for s in board["scenarios"] if board["summaries"][s["name"]]]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.3 * len(scenarios) * max(1, len(agents)) * 0.45 + 2), 4.2))
    width = 0.8 / max(1, len(agents))
    for j, agent in enumerate(agents):
        xs, ys, lo, hi, failed = [], [], [], [], []
        for i, sc in enumerate(scenarios):
            s = board["summaries"][sc].get(agent)
            if s is None:
                continue
            m = s["metrics"]["pos_err_mean"]
            x = i - 0.4 + width * (j + 0.5)
            if s["failures"]:
                failed.append((x, s["failures"], s["n"]))
            if m["value"] is None:
                continue
            xs.append(x)
            ys.append(m["value"])
            lo.append(m["value"] - (m["low"] if m["low"] is not None else m["value"]))
            hi.append((m["high"] if m["high"] is not None else m["value"]) - m["value"])
        ax.bar(xs, ys, width * 0.92, yerr=[lo, hi], capsize=3, color=_color(board["agents"], agent), label=agent)
        for x, k, n in failed:
            ax.annotate(f"{k}/{n}\nfailed", (x, 0), xytext=(0, 3), textcoords="offset points", ha="center",
                        fontsize=7, color="darkred")
    ax.set_xticks(range(len(scenarios)), scenarios, fontsize=8)
    ax.set_ylabel("mean position error [m]")
    ax.set_title("Mean position error per scenario (95 % CI; means over the episodes flown to the end)", fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7, ncols=min(4, len(agents)))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _table4_figure(board: Mapping[str, Any], path: Path) -> bool:
    from .reproduce.table4 import PAPER_TABLE4
    from .scenarios import table4_duty

    duties = sorted(d for d in (table4_duty(s) for s in board["scenarios"]) if d is not None)
    if not duties:
        return False
    plt = _plt()
    agents = board["agents"]
    series = [(a, _color(agents, a), None) for a in agents] + [("paper PX4", "black", 0), ("paper PX4+FFTS-ESO",
                                                                                          "dimgray", 1)]
    width = 0.8 / len(series)
    fig, ax = plt.subplots(figsize=(max(7.0, 1.6 * len(duties) + 2), 4.2))
    top = 0.0
    for j, (label, color, paper_col) in enumerate(series):
        for i, d in enumerate(duties):
            x = i - 0.4 + width * (j + 0.5)
            if paper_col is not None:
                v = PAPER_TABLE4[d][paper_col]
                if v is None:
                    ax.annotate("Failed!", (x, 0), xytext=(0, 3), textcoords="offset points", ha="center",
                                fontsize=7, rotation=90, color="black")
                    continue
                ax.bar(x, v, width * 0.92, color="white", edgecolor=color, hatch="//", label=label if i == 0 else None)
                top = max(top, v)
                continue
            s = board["summaries"][f"table4-{d}"].get(label)
            if s is None:
                continue
            if s["failures"]:
                ax.annotate(f"failed {s['failures']}/{s['n']}", (x, 0), xytext=(0, 3), textcoords="offset points",
                            ha="center", fontsize=7, rotation=90, color="darkred")
                ax.bar(x, 0, width * 0.92, color=color, label=label if i == 0 else None)
                continue
            m = s["metrics"]["pos_err_paper_schedule"]
            if m["value"] is None:
                continue
            err = [[m["value"] - (m["low"] or m["value"])], [(m["high"] or m["value"]) - m["value"]]]
            ax.bar(x, m["value"], width * 0.92, yerr=err, capsize=2, color=color, label=label if i == 0 else None)
            top = max(top, m["value"] + err[1][0])
    ax.set_xticks(range(len(duties)), [f"{d} % duty" for d in duties])
    ax.set_ylim(0, top * 1.25 if top > 0 else 1)
    ax.set_ylabel("mean position error [m]")
    ax.set_title("FAWT hover, Table 4 metric on the paper's 210 s schedule:\nours (solid, 95 % CI) beside "
                 "Wang et al. (2024) (hatched)", fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7, ncols=min(4, len(series)))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _shade_fan(ax: Any, scenario: Mapping[str, Any]) -> None:
    wind = scenario.get("wind")
    if isinstance(wind, Mapping) and wind.get("on_time") is not None:
        off = wind.get("off_time", scenario.get("seconds"))
        ax.axvspan(wind["on_time"], off if off is not None else scenario["seconds"], color="tab:cyan", alpha=0.12,
                   lw=0, label="fan on")
    if isinstance(wind, Mapping) and wind.get("name") == "gust-1cos":
        ax.axvline(wind.get("start_time", 0.0), color="tab:cyan", lw=1, label="gust starts")


def _band(ax: Any, t: np.ndarray, y: np.ndarray, color: str, label: str) -> None:
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean, lo, hi = np.nanmean(y, axis=1), np.nanmin(y, axis=1), np.nanmax(y, axis=1)
    ax.plot(t, mean, color=color, lw=0.9, label=label)
    ax.fill_between(t, lo, hi, color=color, alpha=0.15, lw=0)


def _traces_figures(board: Mapping[str, Any], results: Path, folder: Path, scenario: Mapping[str, Any]
                    ) -> tuple[str | None, str | None]:
    plt = _plt()
    name = scenario["name"]
    agents = [a for a in board["agents"] if a in board["summaries"][name]]
    read = {a: read_traces(results, a, name) for a in agents}
    traces = {a: t for a, t in read.items() if t is not None}
    if not traces:
        return None, None
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for a, t in traces.items():
        _band(ax1, t["time"], t["pos_err"], _color(board["agents"], a), a)
        _band(ax2, t["time"], t["att_err"], _color(board["agents"], a), a)
    for ax in (ax1, ax2):
        _shade_fan(ax, scenario)
        ax.grid(alpha=0.3)
    ax1.set_ylabel("|b - b_d| [m]")
    ax2.set_ylabel("Phi vs command [rad]")
    ax2.set_xlabel("time [s]")
    ax1.legend(fontsize=7, ncols=min(3, len(traces) + 1), loc="upper right")
    ax1.set_title(f"{name}: position and attitude error (line: seed mean, band: seed range)", fontsize=9)
    fig.tight_layout()
    trace_name = f"traces_{_safe(name)}.png"
    fig.savefig(folder / trace_name, dpi=110)
    plt.close(fig)
    est = {a: t for a, t in traces.items() if np.isfinite(t["force_err"]).any() or np.isfinite(t["torque_err"]).any()}
    if not est:
        return trace_name, None
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for a, t in est.items():
        c = _color(board["agents"], a)
        if np.isfinite(t["force_err"]).any():
            _band(ax1, t["time"], t["force_err"], c, a)
        if np.isfinite(t["torque_err"]).any():
            _band(ax2, t["time"], t["torque_err"], c, a)
    for ax in (ax1, ax2):
        _shade_fan(ax, scenario)
        ax.grid(alpha=0.3)
        ax.set_yscale("log")
    ax1.set_ylabel("|phi_hat - phi_D| [N]")
    ax2.set_ylabel("|tau_hat - tau_D| [N m]")
    ax2.set_xlabel("time [s]")
    ax1.legend(fontsize=7, loc="upper right")
    ax1.set_title(f"{name}: disturbance estimation error of each observer", fontsize=9)
    fig.tight_layout()
    est_name = f"estimation_{_safe(name)}.png"
    fig.savefig(folder / est_name, dpi=110)
    plt.close(fig)
    return trace_name, est_name


def _safe(name: str) -> str:
    from .runner import slug

    return slug(name)


def _wind_psd_figure(board: Mapping[str, Any], results: Path, path: Path) -> bool:
    import scipy.signal

    from fawtgym.core.frames import FAWT_HOVER_POINT_NED
    from fawtgym.envs.wind import make_wind
    from fawtgym.envs.wind.cli import analytic_psd

    panels = []
    for sc in board["scenarios"]:
        name = sc["name"]
        if not board["summaries"][name] or sc["wind"] in ("calm", {"name": "calm"}):
            continue
        agent = next(iter(board["summaries"][name]))
        t = read_traces(results, agent, name)
        if t is None or t["wind_row0"].shape[0] < 256:
            continue
        dt = _control_dt(sc)
        w = t["wind_row0"]
        times = (np.arange(w.shape[0]) + 1) * dt
        wind_spec = sc["wind"]
        start, stop = 0.0, times[-1] + dt
        if isinstance(wind_spec, Mapping) and wind_spec.get("on_time") is not None:
            start = float(wind_spec["on_time"]) + 5.0  # after the spin-up
            stop = float(wind_spec.get("off_time") or stop)
        if isinstance(wind_spec, Mapping) and wind_spec.get("name") == "gust-1cos":
            continue  # a discrete gust has no spectrum
        sel = (times > start) & (times <= stop)
        if sel.sum() < 256:
            continue
        seg = w[sel]
        mean = seg.mean(axis=0)
        axis = mean / np.linalg.norm(mean) if np.linalg.norm(mean) > 1e-6 else np.array([1.0, 0.0, 0.0])
        u = seg @ axis
        f, g = scipy.signal.welch(u - u.mean(), fs=1.0 / dt, nperseg=min(1024, u.size))
        model = make_wind(wind_spec if isinstance(wind_spec, str) else
                          {k: v for k, v in wind_spec.items() if k not in ("on_time", "off_time")})
        speed = float(np.linalg.norm(mean)) if np.linalg.norm(mean) > 0.1 else 0.0
        ana: np.ndarray | None = None
        fs = 1.0 / dt
        aliases = [analytic_psd(model, FAWT_HOVER_POINT_NED, np.abs(f[1:] + k * fs), speed) for k in range(-30, 31)]
        if all(a is not None for a in aliases):  # None: a model without an analytic spectrum
            ana = np.sum([a for a in aliases if a is not None], axis=0)
        panels.append((name, f[1:], g[1:], ana, speed))
    if not panels:
        return False
    plt = _plt()
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.6), squeeze=False)
    for ax, (name, f, g, ana, speed) in zip(axes[0], panels, strict=True):
        ax.loglog(f, g, lw=0.8, label="met by the vehicle (Welch)")
        if ana is not None:
            ax.loglog(f, ana, "k--", lw=1.0, label="analytic Dryden, sampled")
        ax.set_title(f"{name} (mean {speed:.1f} m/s)", fontsize=9)
        ax.set_xlabel("frequency [Hz]")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("PSD of stream-wise wind [(m/s)^2/Hz]")
    axes[0, 0].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _control_dt(scenario: Mapping[str, Any]) -> float:
    return 1.0 / float(scenario.get("control_rate", 200.0))


def write_html(board: Mapping[str, Any], results: Path, folder: Path) -> Path:
    """Write the leaderboard page and its figures into ``folder``; returns the page's path."""
    from .leaderboard import fmt_ci, ranked_rows, scenario_rows, table4_rows

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    sc_name = board["scenario"]
    winner = board["ranking"][0]
    ws = board["summaries"][sc_name][winner]
    seeds = board["seeds"]
    page = HtmlPage(f"fawtgym leaderboard: {sc_name}",
                    f"{len(board['agents'])} agents x {len(board['scenarios'])} scenarios x {len(seeds)} seeds, "
                    "the same wind and sensor noise for every agent (paired)",
                    footer="Written by `fawtgym leaderboard --html`. Metrics from the simulator's truth; intervals "
                           "are 95 % bootstrap (BCa) for means and Wilson for failure rates.")
    vs = ws.get("vs_baseline")
    page.stats([("winner", f"`{winner}`", "good"),
                ("its mean position error", fmt_ci(ws["metrics"]["pos_err_mean"]), None),
                (f"vs {board['baseline']}", "baseline" if vs is None or vs["relative"] is None
                 else f"{100 * vs['relative']:+.0f} %", "good" if vs and (vs["relative"] or 0) < 0 else None),
                ("failures", f"{ws['failures']}/{ws['n']}", "bad" if ws["failures"] else "good")])
    page.heading("Ranking")
    head, rows = ranked_rows(board)
    classes: list[list[str | None]] = []
    for i, agent in enumerate(board["ranking"]):
        s = board["summaries"][sc_name][agent]
        row: list[str | None] = [None] * len(head)
        row[0] = "good" if i == 0 else None
        row[3] = "bad" if s["failures"] else "good"
        b = board["beats_next"].get(agent)
        row[5] = "good" if b else ("muted" if b is None else "partial")
        classes.append(row)
    page.table(head, rows, caption=f"Ranked on {sc_name}", cell_classes=classes)
    page.paragraph(board["rule"])
    _ranking_figure(board, folder / "ranking.png")
    page.figure("ranking.png", "Mean position error per scenario, 95 % CI")
    t4 = table4_rows(board)
    if t4 is not None:
        page.heading("Beside Wang et al. (2024), Table 4")
        page.paragraph("Mean position error on the paper's schedule (210 s hover, fan on 20-170 s): the transients "
                       "as flown plus the calm and fan-on stationary means weighted by the paper's durations.")
        page.table(*t4)
        if _table4_figure(board, folder / "table4_bars.png"):
            page.figure("table4_bars.png", "Ours (solid, 95 % CI) beside the paper's Table 4 (hatched)")
    page.heading("Over time")
    for sc in board["scenarios"]:
        if not board["summaries"][sc["name"]]:
            continue
        trace, est = _traces_figures(board, results, folder, sc)
        if trace:
            page.figure(trace, f"{sc['name']}: {sc.get('description', '')}")
        if est:
            page.figure(est, f"{sc['name']}: estimation errors")
    if _wind_psd_figure(board, results, folder / "wind_psd.png"):
        page.heading("The wind the vehicles met")
        page.paragraph("Spectrum of the stream-wise wind at the vehicle's centre of mass (first seed; for a scheduled "
                       "fan, the fan-on part after spin-up), against the wind model's analytic Dryden spectrum "
                       "sampled at the control rate (aliases summed).")
        page.figure("wind_psd.png", "Wind spectrum vs the analytic one")
    page.heading("Every metric")
    for sc in board["scenarios"]:
        name = sc["name"]
        if board["summaries"][name]:
            page.heading(name, 3)
            if sc.get("description"):
                page.paragraph(sc["description"])
            page.table(*scenario_rows(board, name))
    if board["missing"]:
        page.note("Missing cells: " + ", ".join(f"{a} on {s}" for a, s in board["missing"]), "partial")
    return page.write(folder / "index.html")


__all__ = ["write_html"]
