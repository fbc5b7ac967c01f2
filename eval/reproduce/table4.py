"""``fawtgym reproduce table4``: PX4 vs PX4 + FFTS-ESO hover in FAWT wind (Wang et al. 2024, Table 4, Figs. 10-11).

The flight experiment of Wang et al. 2024, Sec. 7, rebuilt in simulation: the s500 preset
(m = 1 kg, J = diag(0.03, 0.03, 0.06)) hovers at the FAWT point (1.5 m in front of the array centre)
under PX4 v1.13-style control (:class:`fawtgym.agents.px4_agent.PX4Agent`, S500 parameters) with and
without the FFTS-ESO feedforward F = F0 - phi_hat, tau = tau0 - tau_hat
(:class:`~fawtgym.agents.px4_agent.PX4ObserverAgent`, the paper's flight gains p = 1.2, k_t1..3 = 6, 3, 1,
kappa_t = 0.6, k_a1..3 = 8, 4, 2, kappa_a = 0.6; the paper's "k_r" are the translational gains k_t).

Procedure (Sec. 7.3): a hover of fixed length (paper: 210 s) with the fan array switched on for
150 s (default: on at 20 s, off at 170 s), duty 30-70 % (wind presets ``fawt-30`` .. ``fawt-70``,
Table 3), motion-capture-fed sensors (``sensors="mocap_imu"``).  Take-off and landing are not
simulated (the vehicle starts hovering at the set point), which is the paper's "omit the pose data
during take-off and landing".  Metrics, exactly Table 4's: the time average over the hover of the
position error norm ``|b^m - b^d|`` and of the attitude error principal angle
``Phi = arccos((tr(R_e) - 1)/2)``, ``R_e = (R^d)^T R^m`` (eq. 88), with ``R^d`` the controller's attitude
setpoint; computed on the true state (the paper's VICON pose).  A run "fails" when the env ends it
(ground contact, leaving the +-2 m box, divergence); its averages are then not reported, as the
paper's "Failed!".  Several seeds per cell (turbulence and sensor-noise realizations), batched: the
agents are vectorized over seeds, one env per seed.

The paper's Table 4 values are printed beside ours; the acceptance checks of the project (ordering at
every duty >= 40 %, >= 40 % reduction at 50 and 60 %, baseline within a factor 3 of Table 4) and the
paper's own claims (:func:`paper_claims`: every Table 4 number, the reductions it implies, the ordering
over duty and the 70 % failure, each with a verdict computed from our numbers) are written to
``table4.md`` as found, with the likely cause when not met.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fawtgym.agents.spec import FFTS_ESO_FLIGHT_GAINS
from fawtgym.eval.reproduce import claims as C

#: Wang et al. 2024, Table 4 (time-averaged tracking error): duty -> (pos PX4, pos PX4+ESO, att PX4, att PX4+ESO);
#: None = "Failed!".
PAPER_TABLE4: dict[int, tuple[float | None, float, float | None, float]] = {
    30: (0.0251, 0.0236, 0.0125, 0.0116),
    40: (0.0468, 0.0211, 0.0140, 0.0141),
    50: (0.0589, 0.0254, 0.0166, 0.0132),
    60: (0.0792, 0.0400, 0.0164, 0.0134),
    70: (None, 0.0557, None, 0.0139),
}
#: FFTS-ESO gains of the flight experiment (Wang et al. 2024, Sec. 7.2), as the agent grammar's px4+ffts_eso uses them
FLIGHT_GAINS: dict[str, float] = FFTS_ESO_FLIGHT_GAINS
DUTIES = (30, 40, 50, 60, 70)
#: the paper's hover: 210 s, fan on for 150 s (Sec. 7.3); (hover, on, off) [s]
PAPER_SCHEDULE = (210.0, 20.0, 170.0)
#: our default compressed hover (hover, on, off) [s]: same transients, shorter calm/steady parts
DEFAULT_SCHEDULE = (75.0, 5.0, 50.0)
#: length of the switch-on/off transient windows [s] used to extrapolate to the paper's schedule
TRANSIENT_WINDOW = 20.0
BASELINE = "px4"


def controller_names(observers: Sequence[str]) -> list[str]:
    """Column names: ``px4`` then ``px4+<observer>`` for each observer."""
    return [BASELINE] + [f"px4+{o}" for o in observers]


def make_agent(name: str, env: Any) -> Any:
    """The agent of a column (``px4`` or ``px4+<observer>``) matched to ``env``."""
    from fawtgym.agents.px4_agent import PX4Agent, PX4ObserverAgent

    if name == BASELINE:
        return PX4Agent.for_env(env)
    obs = name.split("+", 1)[1]
    kwargs = FLIGHT_GAINS if obs == "ffts_eso" else None
    return PX4ObserverAgent.for_env(env, observer=obs, observer_kwargs=kwargs)


def _stack_infos(infos: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Batch the agent-facing parts of single-env infos (measurement, applied) along a new axis."""
    out: dict[str, Any] = {}
    for part in ("measurement", "applied"):
        out[part] = {k: np.stack([np.asarray(i[part][k], dtype=float) for i in infos]) for k in infos[0][part]}
    return out


def run_cell(controller: str, duty: int, seeds: Sequence[int], hover_seconds: float, fan_on: float,
             fan_off: float, sensors: str = "mocap_imu", control_rate: float = 200.0,
             record_hz: float = 20.0, spin_tau: float | None = None) -> dict[str, Any]:
    """Fly one (controller, duty) cell for every seed; batched agent, one env per seed.

    Returns per-seed time-averaged position error [m] and principal angle [rad] (NaN if failed),
    failures, and error traces decimated to ``record_hz`` for the figures.
    """
    import gymnasium as gym

    import fawtgym  # noqa: F401  (registers the env)

    wind: dict[str, Any] = {"name": f"fawt-{duty}", "on_time": fan_on, "off_time": fan_off}
    if spin_tau is not None:
        wind["spin_tau"] = spin_tau
    envs = [gym.make("fawtgym/Hover-v0", vehicle="s500", wind=wind, sensors=sensors, control_rate=control_rate,
                     episode_seconds=hover_seconds, init_noise=0.0) for _ in seeds]
    agent = make_agent(controller, envs[0])
    infos = [env.reset(seed=int(s))[1] for env, s in zip(envs, seeds, strict=True)]
    agent.reset(_stack_infos(infos))
    setpoint = envs[0].unwrapped.setpoint
    n, steps = len(envs), envs[0].unwrapped.max_steps
    alive = np.ones(n, dtype=bool)
    failure = [""] * n
    every = max(1, int(round(control_rate / record_hz)))
    trace_pos = np.full((steps, n), np.nan)
    trace_att = np.full((steps, n), np.nan)
    for k in range(steps):
        actions = agent.act(None, _stack_infos(infos))
        r_d = agent.attitude_setpoint
        pos_err = np.full(n, np.nan)
        att_err = np.full(n, np.nan)
        for i, env in enumerate(envs):
            if not alive[i]:
                continue
            _, _, term, trunc, info = env.step(actions[i])
            infos[i] = info
            truth = info["truth"]
            pos_err[i] = float(np.linalg.norm(truth["position"] - setpoint))
            tr = float(np.einsum("ji,ji->", r_d[i], truth["attitude"]))
            att_err[i] = math.acos(min(max((tr - 1.0) / 2.0, -1.0), 1.0))
            if term:
                alive[i] = False
                failure[i] = info["failure"] or "terminated"
        trace_pos[k] = pos_err
        trace_att[k] = att_err
        if not alive.any():
            break
    for env in envs:
        env.close()
    failed = np.array([bool(f) for f in failure])
    dt = 1.0 / control_rate
    pos_avg = schedule_averages(trace_pos, dt, hover_seconds, fan_on, fan_off)
    att_avg = schedule_averages(trace_att, dt, hover_seconds, fan_on, fan_off)
    nan = np.full(n, np.nan)
    return {"controller": controller, "duty": duty, "seeds": list(map(int, seeds)), "failures": failure,
            "mean_position_error": np.where(failed, np.nan, pos_avg["whole"]),
            "mean_attitude_error": np.where(failed, np.nan, att_avg["whole"]),
            "paper_position_error": np.where(failed, np.nan, pos_avg.get("paper", nan)),
            "paper_attitude_error": np.where(failed, np.nan, att_avg.get("paper", nan)),
            "steady_position_error": np.where(failed, np.nan, pos_avg.get("steady", nan)),
            "trace_time": np.arange(0, steps, every) * dt + dt,
            "trace_position_error": trace_pos[::every], "trace_attitude_error": trace_att[::every]}


def schedule_averages(trace: np.ndarray, dt: float, hover: float, fan_on: float, fan_off: float,
                      window: float = TRANSIENT_WINDOW, paper: tuple[float, float, float] = PAPER_SCHEDULE
                      ) -> dict[str, np.ndarray]:
    """Time averages of an error trace (K, N) sampled every ``dt`` over a hover with the fan on in [on, off).

    ``whole``: the average over our hover (Table 4's metric for our schedule).  When the schedule has a
    calm part, a full transient ``window`` after each switch and a stationary part in between, also
    ``steady`` (fan-on average after the on-transient) and ``paper``: the average the same run would give
    on the paper's schedule ``paper = (hover, on, off)`` (210 s, fan 20-170 s), assembling the measured
    transient integrals and the calm/steady means with the paper's durations (the stationary parts are
    extrapolated, the transients are not).  On the paper's schedule ``paper == whole``.
    """
    t = (np.arange(trace.shape[0]) + 1) * dt
    out = {"whole": np.nanmean(trace, axis=0) if trace.size else np.full(trace.shape[1], np.nan)}
    on_tr = (t > fan_on) & (t <= fan_on + window)
    steady = (t > fan_on + window) & (t <= fan_off)
    off_tr = (t > fan_off) & (t <= fan_off + window)
    calm = (t <= fan_on) | (t > fan_off + window)
    if not (on_tr.any() and steady.any() and off_tr.any() and calm.any()
            and fan_off - fan_on > window and hover - fan_off >= window):
        return out
    p_hover, p_on, p_off = paper
    calm_mean = np.mean(trace[calm], axis=0)
    steady_mean = np.mean(trace[steady], axis=0)
    out["steady"] = steady_mean
    out["paper"] = (calm_mean * (p_on + p_hover - p_off - window) + trace[on_tr].sum(axis=0) * dt
                    + steady_mean * (p_off - p_on - window) + trace[off_tr].sum(axis=0) * dt) / p_hover
    return out


def _cell_value(cell: Mapping[str, Any], key: str) -> float | None:
    """Seed-averaged metric, or None if any seed failed (the paper's "Failed!")."""
    if any(cell["failures"]):
        return None
    return float(np.mean(cell[key]))


def _fmt(v: float | None, digits: int = 4) -> str:
    return "Failed!" if v is None else f"{v:.{digits}f}"


#: Table 4 tolerances: a number within +-25 % of the paper's is reproduced, within a factor 3 (the project's
#: acceptance band for the baseline) partly; a reduction within +-10 percentage points of the one Table 4
#: implies is reproduced, a reduction of the same sign partly.
NUMBER_TOL = 0.25
NUMBER_FACTOR = 3.0
REDUCTION_TOL = 0.10
#: Table 4 shows an attitude improvement where PX4+FFTS-ESO is lower by more than this fraction
ATTITUDE_GAIN = 0.05
_LABEL = {BASELINE: "PX4", "px4+ffts_eso": "PX4+FFTS-ESO"}


def _value(results: Mapping[tuple[str, int], Mapping[str, Any]], column: str, duty: int, key: str
           ) -> tuple[str, float | None]:
    """("absent" | "failed" | "ok", seed-mean value) of one Table-4 cell of our run."""
    cell = results.get((column, duty))
    if cell is None or key not in cell:
        return "absent", None
    v = _cell_value(cell, key)
    if v is None:
        return "failed", None
    return ("ok", v) if math.isfinite(v) else ("absent", None)


def _failure_text(cell: Mapping[str, Any]) -> str:
    fails = [f for f in cell["failures"] if f]
    return f"{len(fails)} of {len(cell['failures'])} seeds ended early ({', '.join(sorted(set(fails)))})"


def paper_claims(results: Mapping[tuple[str, int], Mapping[str, Any]], duties: Sequence[int],
                 eso_column: str = "px4+ffts_eso", pos_key: str = "mean_position_error",
                 att_key: str | None = "mean_attitude_error",
                 how_to_fly: str = "`fawtgym reproduce table4` flies all five duties") -> list[C.Claim]:
    """Wang et al. 2024, Table 4 and Sec. 7.5, claim by claim, with verdicts computed from our cells.

    ``results[(column, duty)]``: cells of :func:`run_cell` (``failures`` and the metric keys).  Claims:
    each Table 4 number (position [m] and attitude principal angle [rad] of eq. 88, PX4 and
    PX4+FFTS-ESO, per duty; tolerance :data:`NUMBER_TOL` / :data:`NUMBER_FACTOR`), the 70 % "Failed!",
    the position-error reduction Table 4 implies at 30-60 % (:data:`REDUCTION_TOL`), the ordering of the
    two schemes at 30-60 % (Sec. 7.5), the baseline's growth with duty and the attitude improvements.
    Duties our run did not fly are listed as ``not checked``.
    """
    P = C.WANG2024
    eso_label = _LABEL.get(eso_column, eso_column)
    metric = ("metric: Table 4's average on the paper's 210 s schedule" if pos_key.startswith("paper_")
              else "metric: time average over our hover")
    flown = [d for d in DUTIES if d in duties and (BASELINE, d) in results and (eso_column, d) in results]
    skip = f"duty {{d}} % was not flown in this run ({how_to_fly})"
    out: list[C.Claim] = []
    quantities = (("position", 0, BASELINE, pos_key, "m"), ("position", 1, eso_column, pos_key, "m"),
                  ("attitude", 2, BASELINE, att_key, "rad"), ("attitude", 3, eso_column, att_key, "rad"))
    for d in DUTIES:
        for qty, idx, col, key, unit in quantities:
            label = _LABEL.get(col, col)
            paper = PAPER_TABLE4[d][idx]
            if paper is None and qty == "attitude":
                continue  # the same 'Failed!' as the position entry
            if paper is None:
                statement = f"{d} % duty: {label} fails to hold the hover (Table 4 'Failed!')"
                crit = "reproduced if every seed's run ends early, partly if some do, not if none"
                if d not in flown:
                    out.append(C.unchecked(P, "Table 4", statement, "Failed!", crit, skip.format(d=d)))
                    continue
                cell = results[(col, d)]
                n_fail = sum(1 for f in cell["failures"] if f)
                n = len(cell["failures"])
                verdict = C.REPRODUCED if n_fail == n else C.PARTLY if n_fail else C.NOT
                ours = "Failed!" if n_fail == n else f"held hover in {n - n_fail} of {n} seeds"
                reason = _failure_text(cell)
                if n_fail < n:
                    held = [float(v) for v, f in zip(cell[pos_key], cell["failures"], strict=True) if not f]
                    reason += f"; where it held, its position error was {C.fmt(float(np.mean(held)))} m"
                out.append(C.Claim(P, "Table 4", statement, "Failed!", ours, crit, verdict, reason))
                continue
            statement = f"{d} % duty: {label} time-averaged {qty} error"
            paper_txt = f"{paper:.4f} {unit}"
            crit = (f"within +-{100 * NUMBER_TOL:.0f} % reproduced, within a factor {NUMBER_FACTOR:g} partly; "
                    + metric)
            if d not in flown or key is None:
                why = skip.format(d=d) if d not in flown else f"our run did not record the {qty} error"
                out.append(C.unchecked(P, "Table 4", statement, paper_txt, crit, why))
                continue
            state, ours = _value(results, col, d, key)
            if state == "absent":
                out.append(C.unchecked(P, "Table 4", statement, paper_txt, crit,
                                       f"our run did not record the {qty} error"))
                continue
            if state == "failed":
                out.append(C.Claim(P, "Table 4", statement, paper_txt, "Failed!", crit, C.NOT,
                                   f"our {label} run failed: {_failure_text(results[(col, d)])}"))
                continue
            verdict, reason = C.relative_verdict(ours, paper, NUMBER_TOL, NUMBER_FACTOR)
            out.append(C.Claim(P, "Table 4", statement, paper_txt, f"{ours:.4f} {unit}", crit, verdict, reason))
    # reductions implied by Table 4 (computed from its numbers, not typed in)
    red_crit = (f"within +-{100 * REDUCTION_TOL:.0f} percentage points reproduced; a reduction of the same sign "
                "partly; " + metric)
    for d in (30, 40, 50, 60):
        b_p, e_p = PAPER_TABLE4[d][0], PAPER_TABLE4[d][1]
        assert b_p is not None
        r_p = 1.0 - e_p / b_p
        statement = f"{d} % duty: {eso_label} lowers the position error of PX4 by {100 * r_p:.0f} %"
        where = "Table 4 (reduction from its numbers)"
        if d not in flown:
            out.append(C.unchecked(P, where, statement, f"{100 * r_p:.0f} %", red_crit, skip.format(d=d)))
            continue
        (sb, b), (se, e) = _value(results, BASELINE, d, pos_key), _value(results, eso_column, d, pos_key)
        if se != "ok":
            out.append(C.Claim(P, where, statement, f"{100 * r_p:.0f} %", "observer run failed", red_crit, C.NOT,
                               f"our {eso_label} run did not hold the hover"))
            continue
        if sb != "ok":
            out.append(C.Claim(P, where, statement, f"{100 * r_p:.0f} %", "PX4 failed, observer held", red_crit,
                               C.PARTLY, "the ordering holds but the reduction is not a number: our PX4 run failed"))
            continue
        r = 1.0 - e / b
        if abs(r - r_p) <= REDUCTION_TOL:
            verdict, reason = C.REPRODUCED, f"ours {100 * r:.0f} % vs {100 * r_p:.0f} %"
        elif r > 0:
            verdict, reason = C.PARTLY, (f"ours {100 * r:.0f} % vs {100 * r_p:.0f} %: same sign, "
                                         f"{100 * abs(r - r_p):.0f} points apart")
        else:
            verdict, reason = C.NOT, f"ours {100 * r:.0f} %: the observer does not lower the error"
        out.append(C.Claim(P, where, statement, f"{100 * r_p:.0f} %", f"{100 * r:.0f} % ({C.fmt(b)} -> {C.fmt(e)} m)",
                           red_crit, verdict, reason))
    # Sec. 7.5: with disturbance rejection the time-averaged position error is lower at 30-60 %
    statement = f"{eso_label} has the lower time-averaged position error at every duty from 30 to 60 %"
    crit = "holds at every duty flown -> reproduced, at some -> partly, at none -> not"
    span = [d for d in flown if 30 <= d <= 60]
    if not span:
        out.append(C.unchecked(P, "Sec. 7.5, Table 4", statement, "yes", crit,
                               f"no duty from 30 to 60 % was flown in this run ({how_to_fly})"))
    else:
        flags, labels, vals = [], [], []
        for d in span:
            (sb, b), (se, e) = _value(results, BASELINE, d, pos_key), _value(results, eso_column, d, pos_key)
            flags.append(se == "ok" and (sb == "failed" or (b is not None and e is not None and e < b)))
            labels.append(f"{d} %")
            vals.append(f"{d} %: {C.fmt(e)} vs PX4 {C.fmt(b) if sb == 'ok' else 'Failed!'} m")
        verdict, reason = C.count_verdict(flags, labels)
        missing = [f"{d} %" for d in (30, 40, 50, 60) if d not in span]
        if missing:
            reason += f"; checked only at the duties flown (not flown: {', '.join(missing)})"
        out.append(C.Claim(P, "Sec. 7.5, Table 4", statement, "yes (30-60 %)", "; ".join(vals), crit, verdict,
                           reason))
    # the baseline's error grows with the duty (Table 4: 0.0251 ... 0.0792, then Failed!)
    statement = "PX4's position error grows with the duty (Table 4 column 'PX4')"
    crit = "rises at every step between the duties flown (a failure counts as the largest) -> reproduced"
    seq = [PAPER_TABLE4[d][0] for d in DUTIES]
    paper_txt = " < ".join("Failed!" if v is None else f"{v:.4f}" for v in seq)
    if len(flown) < 2:
        out.append(C.unchecked(P, "Table 4", statement, paper_txt, crit,
                               f"needs two duties or more; this run flew {len(flown)} ({how_to_fly})"))
    else:
        vals_b = []
        for d in flown:
            sb, b = _value(results, BASELINE, d, pos_key)
            vals_b.append(math.inf if sb == "failed" else (b if b is not None else math.nan))
        rises = [f"{a} -> {b} %" for a, b, x, y in zip(flown, flown[1:], vals_b, vals_b[1:], strict=False)
                 if not (y > x or (math.isinf(x) and math.isinf(y)))]
        if not rises:
            verdict, reason = C.REPRODUCED, f"rises at every step over {', '.join(f'{d} %' for d in flown)}"
            if len(flown) < len(DUTIES):
                reason += " (the duties flown)"
        elif vals_b[-1] > vals_b[0]:
            verdict, reason = C.PARTLY, f"highest at the top duty but falls at {', '.join(rises)}"
        else:
            verdict, reason = C.NOT, f"does not rise: {', '.join(rises)}"
        ours_txt = ", ".join(f"{d} %: {'Failed!' if math.isinf(v) else C.fmt(v)}"
                             for d, v in zip(flown, vals_b, strict=True))
        out.append(C.Claim(P, "Table 4", statement, paper_txt, ours_txt, crit, verdict, reason))
    # attitude: Table 4 shows PX4+FFTS-ESO lower where (PX4 - ESO) / PX4 > ATTITUDE_GAIN
    gains = [d for d in DUTIES if PAPER_TABLE4[d][2] is not None
             and 1.0 - PAPER_TABLE4[d][3] / PAPER_TABLE4[d][2] > ATTITUDE_GAIN]  # type: ignore[operator]
    statement = (f"{eso_label} lowers the time-averaged attitude error at "
                 f"{', '.join(f'{d} %' for d in gains)} (Table 4)")
    crit = "ours lower at every such duty flown -> reproduced, at some -> partly, at none -> not"
    span = [d for d in gains if d in flown]
    if att_key is None or not span:
        out.append(C.unchecked(P, "Table 4", statement, "yes", crit,
                               "none of these duties was flown in this run" if att_key else
                               "our run did not record the attitude error"))
    else:
        flags, vals = [], []
        for d in span:
            (sb, b), (se, e) = _value(results, BASELINE, d, att_key), _value(results, eso_column, d, att_key)
            flags.append(se == "ok" and (sb == "failed" or (b is not None and e is not None and e < b)))
            vals.append(f"{d} %: {C.fmt(e)} vs PX4 {C.fmt(b) if sb == 'ok' else 'Failed!'} rad")
        verdict, reason = C.count_verdict(flags, [f"{d} %" for d in span])
        missing = [f"{d} %" for d in gains if d not in span]
        if missing:
            reason += f"; checked only at the duties flown (not flown: {', '.join(missing)})"
        out.append(C.Claim(P, "Table 4", statement, "yes", "; ".join(vals), crit, verdict, reason))
    return out


def evaluate(results: Mapping[tuple[str, int], Mapping[str, Any]], duties: Sequence[int],
             eso_column: str, key: str = "mean_position_error") -> tuple[list[str], bool]:
    """Check the acceptance criteria and the paper's claims on metric ``key``; returns (lines, all met)."""
    lines: list[str] = []
    ok_all = True
    pos = {(c, d): _cell_value(results[(c, d)], key) for (c, d) in results}

    def reduction(d: int) -> float | None:
        b, e = pos[(BASELINE, d)], pos[(eso_column, d)]
        if e is None:
            return None
        if b is None:
            return 1.0
        return 1.0 - e / b

    lines.append("### Acceptance (project)")
    for d in [d for d in duties if d >= 40]:
        b, e = pos[(BASELINE, d)], pos[(eso_column, d)]
        holds = e is not None and (b is None or e < b)
        ok_all &= holds
        verdict = "met" if holds else "NOT met"
        lines.append(f"- ordering at {d} %: {eso_column} {_fmt(e)} < px4 {_fmt(b)}: **{verdict}**")
    def r_text(d: int) -> str:
        r = reduction(d)
        if r is None:
            return "n/a (observer run failed)"
        return "baseline failed, observer held hover" if pos[(BASELINE, d)] is None else f"{100 * r:.0f} %"

    for d in [d for d in (50, 60) if d in duties]:
        r = reduction(d)
        holds = r is not None and r >= 0.40
        ok_all &= holds
        lines.append(f"- reduction at {d} % >= 40 %: {r_text(d)}: **{'met' if holds else 'NOT met'}**")
    for d in duties:
        paper_b = PAPER_TABLE4[d][0]
        ours = pos[(BASELINE, d)]
        if paper_b is None:
            lines.append(f"- baseline at {d} %: paper Failed!, ours {_fmt(ours)} "
                         f"({'also failed' if ours is None else 'held hover'})")
            continue
        holds = ours is not None and paper_b / 3 <= ours <= paper_b * 3
        ok_all &= holds
        ratio = "n/a" if ours is None else f"{ours / paper_b:.2f}x"
        lines.append(f"- baseline at {d} % within a factor 3 of Table 4 ({paper_b}): ours {_fmt(ours)} = {ratio}: "
                     f"**{'met' if holds else 'NOT met'}**")
    lines.append("")
    lines.append("### The paper's claims, checked on our numbers")
    att_key = key.replace("position", "attitude")
    for c in paper_claims(results, duties, eso_column, key, att_key):
        if c.verdict != C.UNCHECKED:
            lines.append(f"- {c.where}: {c.statement}: {c.our_value} (paper {c.paper_value}): **{c.verdict}** "
                         f"({c.reason})")
    if 70 in duties:
        lines.append(f"- baseline fails at 70 %: {'yes' if pos[(BASELINE, 70)] is None else 'no'}; "
                     f"{eso_column} holds hover at 70 %: {'yes' if pos[(eso_column, 70)] is not None else 'no'}")
    return lines, ok_all


def write_figures(results: Mapping[tuple[str, int], Mapping[str, Any]], duties: Sequence[int],
                  columns: Sequence[str], out: Path) -> list[Path]:
    """Figs. 10-11 style: error vs time per duty (seed mean), PX4 blue, PX4 + FFTS-ESO red."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {BASELINE: "tab:blue", "px4+ffts_eso": "tab:red"}
    paths = []
    for key, label, fname in (("trace_position_error", "|b_e| [m]", "fig10_position_error.png"),
                              ("trace_attitude_error", "Phi [rad]", "fig11_attitude_error.png")):
        fig, axes = plt.subplots(len(duties), 1, figsize=(8, 1.9 * len(duties)), sharex=True, squeeze=False)
        for ax, d in zip(axes[:, 0], duties, strict=True):
            for c in columns:
                cell = results[(c, d)]
                with warnings.catch_warnings():  # all-NaN rows after every seed failed
                    warnings.simplefilter("ignore", RuntimeWarning)
                    y = np.nanmean(cell[key], axis=1) if cell[key].size else np.array([])
                ax.plot(cell["trace_time"][: len(y)], y, lw=0.8, color=colors.get(c), label=c)
            ax.set_ylabel(f"{d} %\n{label}", fontsize=8)
            ax.grid(alpha=0.3)
        axes[0, 0].legend(fontsize=7, loc="upper right")
        axes[-1, 0].set_xlabel("hover time [s]")
        fig.suptitle(f"{'Position' if 'position' in key else 'Attitude'} tracking error (seed mean), "
                     "cf. Wang et al. 2024, Fig. " + ("10" if "position" in key else "11"), fontsize=9)
        fig.tight_layout()
        path = out / fname
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def write_report(results: Mapping[tuple[str, int], Mapping[str, Any]], duties: Sequence[int],
                 columns: Sequence[str], args: argparse.Namespace, wall: float, out: Path) -> tuple[Path, bool]:
    eso_col = "px4+ffts_eso" if "px4+ffts_eso" in columns else columns[-1]
    pos_key, att_key = _metric_keys(results, args)
    extrapolated = pos_key.startswith("paper_")
    lines = ["# Wang et al. 2024, Table 4 reproduction: PX4 vs PX4 + observer feedforward in FAWT wind", "",
             f"Command: `fawtgym reproduce table4 {' '.join(args.argv)}`  ",
             f"s500 at the FAWT point, sensors `{args.sensors}`, control rate {args.control_rate:g} Hz "
             f"(rate/attitude loops; position loop 100 Hz), 1 kHz physics; hover {args.hover_seconds:g} s with the "
             f"fan on from {args.fan_on:g} s to {args.fan_off:g} s"
             + (f" (fan spin-up time constant {args.spin_tau:g} s)" if args.spin_tau is not None else "")
             + f"; seeds {args.seeds}; wall time {wall:.0f} s.", ""]
    if extrapolated:
        lines += ["Table 4's metrics, **on the paper's schedule** (210 s hover, fan on 20-170 s): our run's measured "
                  f"switch-on/off transients ({TRANSIENT_WINDOW:g} s windows, integrated as flown) plus its calm and "
                  "fan-on stationary means weighted by the paper's durations (`schedule_averages`). Raw averages "
                  "over our shorter hover are in the second table.", ""]
    else:
        lines += ["Table 4's metrics: time averages over the whole hover.", ""]
    lines += ["Seed mean; 'Failed!' if any seed's run ended early. Paper = Wang et al. 2024, Table 4.", ""]
    head = "| duty | " + " | ".join(f"pos {c}" for c in columns) + " | pos paper PX4 | pos paper +ESO | " + \
        " | ".join(f"Phi {c}" for c in columns) + " | Phi paper PX4 | Phi paper +ESO |"
    lines += [head, "|" + "---|" * (2 * len(columns) + 5)]
    for d in duties:
        p = PAPER_TABLE4[d]
        row = [f"{d} %"]
        row += [_fmt(_cell_value(results[(c, d)], pos_key)) for c in columns]
        row += [_fmt(p[0]), _fmt(p[1])]
        row += [_fmt(_cell_value(results[(c, d)], att_key)) for c in columns]
        row += [_fmt(p[2]), _fmt(p[3])]
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", "Raw averages over our hover, and the fan-on stationary position error (after the on-transient):",
              "", "| duty | " + " | ".join(f"pos {c} (our hover)" for c in columns) + " | "
              + " | ".join(f"Phi {c} (our hover)" for c in columns) + " | "
              + " | ".join(f"pos {c} (fan-on steady)" for c in columns) + " |",
              "|" + "---|" * (3 * len(columns) + 1)]
    for d in duties:
        row = [f"{d} %"]
        row += [_fmt(_cell_value(results[(c, d)], "mean_position_error")) for c in columns]
        row += [_fmt(_cell_value(results[(c, d)], "mean_attitude_error")) for c in columns]
        row += [_fmt(_cell_value(results[(c, d)], "steady_position_error")) for c in columns]
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", "Per-seed position errors, Table-4 metric [m] (NaN = failed run) and failures:", ""]
    for d in duties:
        for c in columns:
            cell = results[(c, d)]
            fails = [f for f in cell["failures"] if f]
            lines.append(f"- {d} % {c}: {np.round(cell[pos_key], 4).tolist()}"
                         + (f", failures: {fails}" if fails else ""))
    lines.append("")
    checks, ok = evaluate(results, duties, eso_col, pos_key)
    lines += checks
    lines += ["", "### Notes", "",
              "- The hover is simulated from the set point (no take-off/landing, as the paper omits them).",
              "- The time average includes the fan switch-on/off transients, as the paper's does.",
              "- Wind: the FAWT model of `fawtgym.envs.wind.fawt` (Table 3 statistics, fan spin-up model) and the "
              "aerodynamic coefficients of `fawtgym.envs.aero`; no controller parameter was tuned for this study "
              "(PX4 v1.13 defaults + S500 airframe overrides, hover-thrust estimator on, FFTS-ESO flight gains of "
              "Sec. 7.2).",
              "- A failure here is the env ending the run: ground contact, divergence, or leaving the +-2 m box "
              "around the set point (the baseline's switch-on transient grows with the mean force, ~U^2)."]
    for d in duties:
        steady = _cell_value(results[(BASELINE, d)], "steady_position_error")
        paper_b = PAPER_TABLE4[d][0]
        if steady is not None and paper_b is not None:
            lines.append(f"- {d} %: baseline fan-on stationary error {steady:.4f} m vs Table 4's whole-hover "
                         f"{paper_b:.4f} m ({steady / paper_b:.2f}x).")
    lines += ["- If the stationary errors are below Table 4 while the averages are above it, the simulated "
              "turbulence disturbs the vehicle less than the real flow while the simulated switch-on/off "
              "transients are larger than the real ones: the agreement of an average is then partly a "
              "cancellation and is no evidence of a calibrated model.", ""]
    if not ok:
        lines += ["**Not all acceptance criteria are met.** Where the baseline is too large, the cause is the size of "
                  "the switch-on/off transients: the simulated mean aerodynamic force on the s500 at the FAWT speed "
                  "(about 4 N at 50 % duty, ~0.4 g) appears within about one second (fan spin-up model), and PX4's "
                  "default velocity-integral gain removes it with a ~5 s time constant, so the baseline is pushed "
                  "~1 m downstream at each switch. The fan-on stationary errors (second table) are the part that "
                  "compares directly with a long steady hover.", ""]
    path = out / "table4.md"
    path.write_text("\n".join(lines) + "\n")
    return path, ok


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fawtgym reproduce table4", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("results/table4"), help="output folder")
    parser.add_argument("--quick", action="store_true",
                        help="short check: duty 50 only and 2 seeds (unless --duties / --seeds are given)")
    parser.add_argument("--seeds", type=int, default=None, help="number of seeds per cell (default 5, quick 2)")
    parser.add_argument("--duties", type=str, default=None,
                        help="comma list from 30,40,50,60,70 (default all, quick 50)")
    parser.add_argument("--observers", type=str, default="ffts_eso",
                        help="comma list of registered observers fed forward (first column after PX4)")
    parser.add_argument("--paper-schedule", action="store_true",
                        help="fly the paper's 210 s hover with the fan on 20-170 s (about 3x the default cost)")
    parser.add_argument("--hover-seconds", type=float, default=DEFAULT_SCHEDULE[0],
                        help=f"hover length [s] (default {DEFAULT_SCHEDULE[0]:g}; paper 210)")
    parser.add_argument("--fan-on", type=float, default=DEFAULT_SCHEDULE[1], help="fan switch-on time [s]")
    parser.add_argument("--fan-off", type=float, default=DEFAULT_SCHEDULE[2], help="fan switch-off time [s]")
    parser.add_argument("--spin-tau", type=float, default=None,
                        help="fan spin-up/down time constant [s] of the wind model (default: the model's, 1 s)")
    parser.add_argument("--sensors", type=str, default="mocap_imu", help="env sensor preset (default mocap_imu)")
    parser.add_argument("--control-rate", type=float, default=200.0,
                        help="agent/env control rate [Hz]; must be a multiple of the 100 Hz mocap pose rate")
    return parser


def reproduce(argv: Sequence[str] | None = None, progress: bool = True) -> C.StudyOutcome:
    """Parse ``argv`` as the command line, fly the study, write its files; returns its claims and figures.

    ``progress``: print one line per finished cell.  Bad arguments exit (argparse, status 2).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    args = parser.parse_args(argv)
    args.argv = argv
    if args.paper_schedule:
        args.hover_seconds, args.fan_on, args.fan_off = PAPER_SCHEDULE
    if args.duties is None:
        args.duties = "50" if args.quick else ",".join(map(str, DUTIES))
    if args.seeds is None:
        args.seeds = 2 if args.quick else 5
    try:
        duties = [int(d) for d in args.duties.split(",") if d.strip()]
    except ValueError:
        parser.error(f"--duties must be a comma list of integers, got {args.duties!r}")
    bad = [d for d in duties if d not in PAPER_TABLE4]
    if bad or not duties:
        parser.error(f"--duties {bad or args.duties!r} not in Table 4; valid: {list(PAPER_TABLE4)}")
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    if not 0 <= args.fan_on < args.fan_off <= args.hover_seconds:
        parser.error("need 0 <= --fan-on < --fan-off <= --hover-seconds")
    observers = [o.strip() for o in args.observers.split(",") if o.strip()]
    try:
        import fawtgym.observers as obs_pkg
        from fawtgym.envs.wind import wind_names
    except ImportError as exc:  # pragma: no cover - depends on the build
        parser.exit(2, f"table4: a component is missing: {exc}\n")
    unknown = [o for o in observers if o not in obs_pkg.observer_names()]
    if unknown:
        parser.error(f"unknown observer(s) {unknown}; valid: {obs_pkg.observer_names()}")
    missing = [f"fawt-{d}" for d in duties if f"fawt-{d}" not in wind_names()]
    if missing:
        parser.exit(2, f"table4: wind preset(s) {missing} are not available in this build\n")
    columns = controller_names(observers)
    seeds = list(range(args.seeds))
    args.seeds = seeds
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    results: dict[tuple[str, int], dict[str, Any]] = {}
    for d in duties:
        for c in columns:
            t1 = time.time()
            cell = run_cell(c, d, seeds, args.hover_seconds, args.fan_on, args.fan_off, args.sensors,
                            args.control_rate, spin_tau=args.spin_tau)
            results[(c, d)] = cell
            if progress:
                v = _cell_value(cell, "mean_position_error")
                print(f"duty {d} % {c:>16s}: pos {_fmt(v)} m, Phi {_fmt(_cell_value(cell, 'mean_attitude_error'))} "
                      f"rad over our hover; paper-schedule pos {_fmt(_cell_value(cell, 'paper_position_error'))} m "
                      f"({time.time() - t1:.0f} s)", flush=True)
    wall = time.time() - t0
    figs = write_figures(results, duties, columns, out)
    report, ok = write_report(results, duties, columns, args, wall, out)
    keys = ("mean_position_error", "mean_attitude_error", "paper_position_error", "paper_attitude_error",
            "steady_position_error")
    summary = {f"{c}@{d}": {**{k: results[(c, d)][k].tolist() for k in keys},
                            "failures": results[(c, d)]["failures"]} for (c, d) in results}
    (out / "table4.json").write_text(json.dumps({"paper": PAPER_TABLE4, "ours": summary}, indent=1, default=str))
    pos_key, att_key = _metric_keys(results, args)
    eso_col = "px4+ffts_eso" if "px4+ffts_eso" in columns else columns[-1]
    claims = paper_claims(results, duties, eso_col, pos_key, att_key)
    settings = (f"duties {', '.join(f'{d} %' for d in duties)}; seeds {seeds}; hover {args.hover_seconds:g} s, fan on "
                f"{args.fan_on:g}-{args.fan_off:g} s; project acceptance {'met' if ok else 'NOT met'}")
    return C.StudyOutcome(claims, figs, report, settings)


def _metric_keys(results: Mapping[tuple[str, int], Mapping[str, Any]], args: argparse.Namespace) -> tuple[str, str]:
    """Table 4's metric keys: extrapolated to the paper's schedule when our hover is shorter and allows it."""
    on_paper = (args.hover_seconds, args.fan_on, args.fan_off) == PAPER_SCHEDULE
    extrapolated = not on_paper and any(np.isfinite(results[k]["paper_position_error"]).any() for k in results)
    return (("paper_position_error", "paper_attitude_error") if extrapolated
            else ("mean_position_error", "mean_attitude_error"))


def main(argv: Sequence[str] | None = None) -> int:
    outcome = reproduce(argv)
    assert outcome.summary is not None
    print(outcome.summary.read_text())
    print("figures:", ", ".join(str(p) for p in outcome.figures))
    print(f"{outcome.settings} (details in {outcome.summary})")
    return 0
