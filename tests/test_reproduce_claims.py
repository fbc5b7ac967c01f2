"""Verdict logic of the paper claims (eval/reproduce/claims.py and each study's ``paper_claims``) on synthetic
results: reproduced / partly / not / not checked, and the reasons given."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from fawtgym.eval.reproduce import claims as C


def by_statement(claims: list[C.Claim], fragment: str) -> C.Claim:
    found = [c for c in claims if fragment in c.statement]
    assert len(found) == 1, (fragment, [c.statement for c in claims])
    return found[0]


# ---- shared rules ---------------------------------------------------------------------------------
def test_claim_rejects_unknown_verdicts() -> None:
    with pytest.raises(ValueError, match="verdict"):
        C.Claim("A 2020", "Table 1", "x", "1", "1", "equal", "confirmed", "r")


def test_relative_and_absolute_rules() -> None:
    assert C.relative_verdict(0.0600, 0.0589, 0.25, 3.0)[0] == C.REPRODUCED
    v, why = C.relative_verdict(0.1512, 0.0589, 0.25, 3.0)
    assert v == C.PARTLY and "2.57" in why
    assert C.relative_verdict(0.02, 0.0589, 0.25, 3.0)[0] == C.PARTLY  # 0.34x: within a factor 3 below
    assert C.relative_verdict(0.5, 0.0589, 0.25, 3.0)[0] == C.NOT
    assert C.relative_verdict(-0.06, 0.0589, 0.25, 3.0)[0] == C.NOT
    assert C.relative_verdict(None, 0.0589, 0.25, 3.0)[0] == C.NOT
    assert C.relative_verdict(math.nan, 0.0589, 0.25, 3.0)[0] == C.NOT
    assert C.absolute_verdict(0.206243, 0.2062, 5e-5, 1e-3)[0] == C.REPRODUCED
    assert C.absolute_verdict(11.4267, 11.4155, 5e-5, 0.114)[0] == C.PARTLY
    assert C.absolute_verdict(12.0, 11.4155, 5e-5, 0.114)[0] == C.NOT


def test_count_and_ordering_rules() -> None:
    assert C.count_verdict([True, True], ["a", "b"])[0] == C.REPRODUCED
    v, why = C.count_verdict([True, False, True], ["a", "b", "c"])
    assert v == C.PARTLY and "not in b" in why
    assert C.count_verdict([False], ["a"])[0] == C.NOT
    assert C.count_verdict([], [])[0] == C.UNCHECKED
    assert C.decreasing_verdict([3.0, 2.0, 1.0], list("abc"))[0] == C.REPRODUCED
    assert C.decreasing_verdict([math.inf, 0.6, 0.5], list("abc"))[0] == C.REPRODUCED  # never settles = largest
    v, why = C.decreasing_verdict([3.0, 3.5, 1.0], list("abc"))
    assert v == C.PARTLY and "a -> b" in why
    assert C.decreasing_verdict([1.0, 1.2, 1.3], list("abc"))[0] == C.NOT
    assert C.decreasing_verdict([1.0, math.nan], list("ab"))[0] == C.NOT
    assert C.tally([C.unchecked("p", "w", "s", "v", "c", "why")]) == {C.REPRODUCED: 0, C.PARTLY: 0, C.NOT: 0,
                                                                      C.UNCHECKED: 1}


# ---- Wang et al. 2024, Table 4 --------------------------------------------------------------------
def _cell(pos, att=None, failures=None):
    pos = np.asarray(pos, dtype=float)
    att = np.asarray(att if att is not None else pos / 4, dtype=float)
    return {"mean_position_error": pos, "mean_attitude_error": att, "failures": failures or [""] * pos.size}


def test_table4_claims() -> None:
    from fawtgym.eval.reproduce import table4

    res = {("px4", 50): _cell([0.060, 0.058], [0.0166, 0.0166]),
           ("px4+ffts_eso", 50): _cell([0.035, 0.033], [0.020, 0.020]),     # attitude worse than PX4
           ("px4", 70): _cell([0.20, 0.9], failures=["", "out_of_bounds"]),  # one seed of two fails
           ("px4+ffts_eso", 70): _cell([0.2], failures=["ground"])}
    claims = table4.paper_claims(res, [50, 70])
    assert len(claims) == 4 * 4 + 3 + 4 + 3  # 19 Table-4 entries, 4 reductions, ordering, growth, attitude
    px4_50 = by_statement(claims, "50 % duty: PX4 time-averaged position error")
    assert px4_50.verdict == C.REPRODUCED and px4_50.paper_value == "0.0589 m" and px4_50.our_value == "0.0590 m"
    eso_att = by_statement(claims, "50 % duty: PX4+FFTS-ESO time-averaged attitude error")
    assert eso_att.verdict == C.PARTLY and "1.52" in eso_att.reason
    red = by_statement(claims, "50 % duty: PX4+FFTS-ESO lowers the position error of PX4 by 57 %")
    assert red.verdict == C.PARTLY and "42 %" in red.our_value  # same sign, 15 points below 57 %
    fail70 = by_statement(claims, "70 % duty: PX4 fails")
    assert fail70.verdict == C.PARTLY and "1 of 2 seeds" in fail70.reason
    eso70 = by_statement(claims, "70 % duty: PX4+FFTS-ESO time-averaged position error")
    assert eso70.verdict == C.NOT and "ground" in eso70.reason
    assert by_statement(claims, "lowers the time-averaged attitude error").verdict == C.NOT
    grows = by_statement(claims, "grows with the duty")
    assert grows.verdict == C.REPRODUCED and "70 %: Failed!" in grows.our_value
    for d in (30, 40, 60):  # not flown: listed, not left out
        c = by_statement(claims, f"{d} % duty: PX4 time-averaged position error")
        assert c.verdict == C.UNCHECKED and "not flown" in c.reason
    order = by_statement(claims, "lower time-averaged position error at every duty from 30 to 60 %")
    assert order.verdict == C.REPRODUCED and "not flown: 30 %, 40 %, 60 %" in order.reason
    # PX4 holds at 70 %: the paper's "Failed!" is contradicted
    res[("px4", 70)] = _cell([0.15])
    assert by_statement(table4.paper_claims(res, [50, 70]), "70 % duty: PX4 fails").verdict == C.NOT
    # the observer does not help at 50 %: the reduction is contradicted
    res[("px4+ffts_eso", 50)] = _cell([0.07, 0.07])
    claims = table4.paper_claims(res, [50, 70])
    assert by_statement(claims, "by 57 %").verdict == C.NOT
    assert by_statement(claims, "at every duty from 30 to 60 %").verdict == C.NOT


# ---- Wang et al. 2024, Sec. 6 ---------------------------------------------------------------------
def _seed000_result(steady_force: dict, steady_torque: dict, spike: float = 20.0, seconds: float = 12.0):
    from fawtgym.eval.reproduce.seed000_sim import StudyResult

    trajs = ["HV", "SS", "FS", "HP"] * 2
    noisy = np.array([False] * 4 + [True] * 4)
    names = [t + ("+noise" if n else "") for t, n in zip(trajs, noisy, strict=True)]
    t = np.arange(1, int(seconds * 100) + 1) / 100.0
    terr = {k: np.full((t.size, 8), 1e-3) for k in steady_force}
    if "fxtsdo" in terr:
        terr["fxtsdo"][(t > 10.0) & (t < 10.2)] = spike * 1e-3
    arr = {k: np.asarray(v, dtype=float) for k, v in steady_force.items()}
    art = {k: np.asarray(v, dtype=float) for k, v in steady_torque.items()}
    z = np.zeros(8)
    return StudyResult(names, trajs, noisy, t, {k: terr[k] * 0 for k in terr}, terr, arr, art, arr, art, {}, z, z,
                       z, 1.0)


def test_seed000_claims() -> None:
    from fawtgym.eval.reproduce import seed000_sim as S

    good_f, good_t = [0.1] * 8, [0.01] * 8
    res = _seed000_result(
        {"ffts_eso": good_f, "leso": [0.2] * 8, "fxtsdo": [0.01] * 4 + [6.0] * 4},
        {"ffts_eso": good_t, "leso": [0.015, 0.015, 0.04, 1.3, 0.016, 0.016, 0.3, 1.3],
         "fxtsdo": [0.001, 0.001, 0.0013, 0.007, 0.6, 0.6, 0.6, 0.3]})
    claims = S.paper_claims(res)
    leso = by_statement(claims, "noise-free, the torque error of LESO diverges")
    assert leso.verdict == C.PARTLY and "FS: degrades" in leso.reason and "HP: diverges" in leso.reason
    assert by_statement(claims, "with noise, the torque error of LESO diverges").verdict == C.REPRODUCED
    fx = by_statement(claims, "noise-free, the torque error of FxTSDO diverges")
    assert fx.verdict == C.NOT and "stays converged" in fx.reason
    assert by_statement(claims, "With noise FxTSDO gives no meaningful estimate").verdict == C.REPRODUCED
    assert by_statement(claims, "FFTS-ESO's force and torque estimates converge").verdict == C.REPRODUCED
    assert by_statement(claims, "large pose changes and noisy").verdict == C.REPRODUCED
    robust = by_statement(claims, "unlike LESO and FxTSDO")
    assert robust.verdict == C.REPRODUCED and "FxTSDO fails in HV+noise" in robust.reason
    assert by_statement(claims, "high transient").verdict == C.REPRODUCED
    # the short run cannot see the step at 10 s; with only the noisy cases, noise-free claims are unchecked
    short = S.paper_claims(_seed000_result({"ffts_eso": good_f, "leso": good_f, "fxtsdo": good_f},
                                           {"ffts_eso": good_t, "leso": good_t, "fxtsdo": good_t}, seconds=8.0))
    assert by_statement(short, "high transient").verdict == C.UNCHECKED
    assert by_statement(short, "With noise FxTSDO").verdict == C.NOT  # accurate with noise: contradicted
    assert by_statement(short, "unlike LESO and FxTSDO").verdict == C.PARTLY  # they converge everywhere too
    # check_claims keeps its words for the study's own Markdown
    words = dict((c, v) for c, v, _ in S.check_claims(res))
    assert words["With noise FxTSDO gives no meaningful estimate (Remark 2)"] == "confirmed"


# ---- Shi, Wu and Chou 2018 ------------------------------------------------------------------------
def _geso_rows(att: dict[str, float], est: dict[str, float], case: int = 1) -> list[dict[str, object]]:
    return [{"variant": v, "case": case, "rms_att_deg": att[v], "rms_est_err": est.get(v, math.nan)}
            for v in ("none", "GESO-1", "GESO-2", "GESO-3")]


def test_geso_claims() -> None:
    from fawtgym.eval.reproduce import geso as G

    steady = _geso_rows({"none": 8.0, "GESO-1": 0.7, "GESO-2": 0.3, "GESO-3": 0.1},
                        {"GESO-1": 1.4, "GESO-2": 0.7, "GESO-3": 0.3})
    whole = _geso_rows({"none": 8.5, "GESO-1": 4.9, "GESO-2": 5.1, "GESO-3": 5.2},
                       {"GESO-1": 1.8, "GESO-2": 1.2, "GESO-3": 0.9})
    settle = {1.0: {("GESO-1", 2): math.inf, ("GESO-2", 2): 0.58, ("GESO-3", 2): 0.53}}
    claims = G.paper_claims(steady, whole, settle, 2.0, 6.0)
    track = by_statement(claims, "Case 1: tracking error falls")
    assert track.verdict == C.PARTLY and "whole run: not" in track.reason
    assert by_statement(claims, "Case 1: estimation error falls").verdict == C.REPRODUCED
    assert by_statement(claims, "Case 1: every GESO improves").verdict == C.REPRODUCED
    assert by_statement(claims, "speed of convergence").verdict == C.REPRODUCED
    for n in (1, 2, 3):
        assert by_statement(claims, f"GESO-{n} gains").verdict == C.REPRODUCED
    peak = by_statement(claims, "peak magnitudes")   # the statement after eq. 38 is false: flagged
    assert peak.verdict == C.NOT and "false as stated" in peak.reason and "1.155, 1.299, 1.431" in peak.our_value
    assert by_statement(claims, "falls as w_b rises").verdict == C.REPRODUCED
    # the study's yes/no table is the same rule, and lists the G(s) claims and the speed claim as well
    assert [ok for _, ok, _ in G.check_claims(whole, bode=False)] == [True, False, True]
    table = G.check_claims(whole, settle, 6.0)
    assert any("peak magnitudes" in c and not ok for c, ok, _ in table)
    assert any("Fig. 3" in c or "low frequency" in c for c, _, _ in table)
    assert any("speed of convergence" in c and ok for c, ok, _ in table)
    # speed over several bands (as measured: 2 and 5 deg are not monotone) -> partly
    bands = {1.0: settle[1.0], 2.0: {("GESO-1", 2): 0.405, ("GESO-2", 2): 0.455, ("GESO-3", 2): 0.423},
             5.0: {("GESO-1", 2): 0.233, ("GESO-2", 2): 0.287, ("GESO-3", 2): 0.28}}
    speed = G.speed_claim(bands, 6.0)
    assert speed.verdict == C.PARTLY and "not monotone" in speed.reason and "0.405 / 0.455 / 0.423" in speed.our_value
    bad = _geso_rows({"none": 1.0, "GESO-1": 2.0, "GESO-2": 3.0, "GESO-3": 4.0},
                     {"GESO-1": 1.0, "GESO-2": 2.0, "GESO-3": 3.0})
    claims = G.paper_claims(bad, bad, {1.0: {("GESO-1", 2): 0.5, ("GESO-2", 2): 0.6, ("GESO-3", 2): 0.7}}, 2.0, 6.0)
    assert {c.verdict for c in claims if c.where.startswith("Fig") and "Case" in c.statement} == {C.NOT}


# ---- Wang and Sanyal 2022 -------------------------------------------------------------------------
def _nb(att: float, om: float, sig: float, triv: tuple[float, float, float] | None = None) -> dict[str, float]:
    out = {"t_from": 15.0, "att_angle_deg_0": 180.0, "att_angle_deg_max": att, "omega_err_0": 1.5,
           "omega_err_max": om, "sigma_err_0": 6.0, "sigma_err_max": sig, "morse_max": 0.0}
    if triv is not None:
        out |= dict(zip(("triv_att_angle_deg_max", "triv_omega_err_max", "triv_sigma_err_max"), triv, strict=True))
    return out


def test_hc_eso_claims() -> None:
    from fawtgym.eval.reproduce import hc_eso as H

    # no trivial-estimator run: convergence alone does not decide
    claims = H.paper_claims(_nb(3.0, 0.3, 10.0), _nb(0.5, 0.01, 11.0))
    assert [c.verdict for c in claims] == [C.UNCHECKED, C.UNCHECKED, C.NOT, C.PARTLY]
    assert "20 % of the initial" in claims[1].reason and "critical point" in claims[0].reason
    assert "sigma_err" in claims[3].reason
    assert H.paper_claims(_nb(3.0, 0.05, 0.1))[-1].verdict == C.UNCHECKED
    # against the trivial estimator: 3 deg vs 10 -> reproduced; rate 0.06 vs 0.08 -> partly; sigma 0.08 vs 0.065 -> not
    claims = H.paper_claims(_nb(3.0, 0.06, 0.08, (10.0, 0.08, 0.065)))
    assert [c.verdict for c in claims[:3]] == [C.REPRODUCED, C.PARTLY, C.NOT]
    assert "no better than the trivial" in claims[2].reason and "not by 2x" in claims[1].reason
    # the median decides, the seeds' spread can only downgrade: overlapping ranges -> partly
    runs = [_nb(a, 0.01, 0.01, (t, 0.08, 0.065)) for a, t in ((3.0, 10.0), (3.2, 9.0), (9.5, 11.0))]
    agg = H.over_seeds(runs)
    assert agg["att_angle_deg_max"] == 3.2 and agg["att_angle_deg_max_hi"] == 9.5 and agg["n_seeds"] == 3
    fig1 = H.paper_claims(agg)[0]
    assert fig1.verdict == C.PARTLY and "overlap" in fig1.reason and "over 3 seeds" in fig1.our_value


# ---- Cayero et al. 2019 ---------------------------------------------------------------------------
def _qb_summary(**over: object) -> dict[str, object]:
    ok = {k: True for k in ("fig4_volume_grows_with_alpha_past_minimum", "fig4_interior_minimum",
                            "fig6_alpha_opt_nonincreasing_in_mu", "fig6_volume_opt_nonincreasing_in_mu",
                            "fig7_higher_mu_smaller_alpha", "fig7_higher_mu_smaller_volume",
                            "fig7_higher_mu_converges_slower", "fig7_higher_mu_smaller_error_region")}
    s: dict[str, object] = {
        "claims": ok, "anchors": SimpleNamespace(vol_star=0.007, alpha_nadir=0.15, vol_nadir=2e4, alpha_star=20.0),
        "sweep": SimpleNamespace(alphas=np.array([0.05, 0.15, 20.0])),
        "gains": {0.2: SimpleNamespace(alpha=20.0, log_volume=math.log(2e4)),
                  0.95: SimpleNamespace(alpha=2.8, log_volume=math.log(45.0))},
        "opt_interp": {0.0: (20.0, 2e4), 0.2: (20.0, 2e4), 0.5: (11.0, 4e3), 1.0: (0.15, 0.007)},
        "settle": {0.2: 0.14, 0.95: 1.2}, "region": {0.2: {"rms": 0.41}, 0.95: {"rms": 0.18}},
        "final_error": {0.2: 1e-5, 0.95: 0.02}, "peak_error": {0.2: 1.1, 0.95: 1.4},
        "max_decay_margin": -0.06, "max_rel_lmi7": 4e-9}
    s.update(over)
    return s


def test_qb_claims() -> None:
    from fawtgym.eval.reproduce import qb_observer as Q

    claims = Q.paper_claims(_qb_summary())
    assert len(claims) == 7 and all(c.verdict == C.REPRODUCED for c in claims)
    s = _qb_summary(final_error={0.2: 1e-5, 0.95: 0.3})
    s["claims"] = dict(s["claims"], fig4_interior_minimum=False, fig7_higher_mu_converges_slower=False)  # type: ignore[arg-type]
    claims = Q.paper_claims(s)
    assert by_statement(claims, "trades off").verdict == C.PARTLY
    assert by_statement(claims, "slower").verdict == C.NOT
    assert by_statement(claims, "error stability").verdict == C.NOT


def test_qb_observations_say_what_the_table_shows() -> None:
    from fawtgym.eval.reproduce import qb_observer as Q

    s = _qb_summary(ellipsoid_dx={0.2: 5.8, 0.95: 1.5}, trivial={"rms_d": 1.3, "max_d": 2.0},
                    region={0.2: {"rms": 0.41, "rms_lo": 0.40, "rms_hi": 0.43, "n_seeds": 5.0},
                            0.95: {"rms": 0.18, "rms_lo": 0.17, "rms_hi": 0.19, "n_seeds": 5.0}})
    text = "\n".join(Q.observations(s))
    assert "mu = 0.2 design has alpha = 20, at the upper edge of the sweep" in text   # alpha 20 = max of the grid
    assert "mu = 0.95 design" not in text                                              # 2.8: inside the sweep
    assert "2.90 x the 2 N peak" in text and "certifies nothing" in text               # 5.8 N above 2 N
    assert "0.75 x the 2 N peak of the Fig. 3 disturbance (below the signal)" in text
    assert "x the trivial estimate d_hat = 0" in text


# ---- Silva and Santos 2023 ------------------------------------------------------------------------
def _pdt(ts: float = 1e-4, fig7_settle: float = 2.07, fig8_dep: float = 5.0, sweep=None,
         fig6_w: float = 0.07) -> dict[str, object]:
    ex = dict(t1=0.206243, kappa2_min_ours=11.4267, kappa2_min_rounded_t1=11.4155, satisfies_30=1.0,
              fig3a_in_X=0.0, fig3a_x2_t1=2.65, fig3b_in_X=1.0, fig3b_t1=0.19, fig3b_x2_t1=3.3, fig3c_in_X=1.0,
              fig3c_t1=0.16, fig3c_x2_t1=2.3, analytic_vs_ivp_k8=1e-11, analytic_vs_ivp_k12=4e-12,
              noise_bound=0.034641, t_e=1.32679)
    # rates scaled by omega_scale = 0.47 rad/s: the thresholds are 0.2 (at zero) and 0.25 (bounded) of it
    good = dict(g_err_0=0.4, g_err_tc=1e-6, g_err_half_tc=1e-2, g_err_max_after_tc=3e-5, w_err_max_after_tc=0.07,
                g_err_max_late=5e-4, w_err_max_late=0.07, departure=0.7, settle_time=1.45, t_c=1.5, w_scale=0.47,
                g_scale=0.4, w_min=0.3, triv_g_late=1e-3, triv_w_forcing_late=0.035, triv_w_fd_late=30.0)
    mets = {n: dict(good) for n in ("fig5", "fig6", "fig7", "fig8", "fig9", "fig9_eq44", "fig8_exact")}
    mets["fig6"].update(t_c=0.5, settle_time=0.5, w_err_max_after_tc=fig6_w)
    if fig6_w > 0.2 * 0.47:
        mets["fig6"]["settle_time"] = 1.27
    mets["fig7"]["settle_time"] = fig7_settle
    mets["fig8"]["departure"] = fig8_dep
    mets["fig9_eq44"]["departure"] = 7.0
    return dict(example1=ex, sec5=mets, seed_sweep=sweep or {}, ts=ts, t_f=2.5)


def test_pdt_sta_claims() -> None:
    from fawtgym.eval.reproduce import pdt_sta as D

    claims = D.paper_claims(_pdt())
    assert by_statement(claims, "first zero crossing").verdict == C.REPRODUCED
    k2 = by_statement(claims, "kappa2 >= 11.4155")
    assert k2.verdict == C.PARTLY and "rounded" in k2.reason
    assert by_statement(claims, "early switching instant").verdict == C.REPRODUCED
    fig5 = by_statement(claims, "predefined t_c = 1.5 s")
    assert fig5.verdict == C.REPRODUCED and "omega_r" in fig5.reason   # the trivial estimators are shown
    assert "does no better than the forcing" in fig5.reason            # 0.07 >= 0.035
    assert by_statement(claims, "stricter t_c = 0.5 s").verdict == C.REPRODUCED
    # a rate error above 0.2 omega_scale after t_c (0.258 rad/s = 0.55 of 0.47): the attitude alone -> partly
    fig6 = by_statement(D.paper_claims(_pdt(fig6_w=0.258)), "stricter t_c = 0.5 s")
    assert fig6.verdict == C.PARTLY and "the rate is not" in fig6.reason
    assert by_statement(claims, "conventional STSMO").verdict == C.PARTLY
    assert by_statement(claims, "depart from the origin").verdict == C.REPRODUCED
    fig9 = by_statement(claims, "switching early")
    assert fig9.verdict == C.REPRODUCED and "eq. 44 as printed" in fig9.reason
    claims = D.paper_claims(_pdt(fig7_settle=1.65, fig8_dep=1.2))
    assert by_statement(claims, "conventional STSMO").verdict == C.REPRODUCED
    assert by_statement(claims, "depart from the origin").verdict == C.NOT
    # over seeds: the median decides, each seed counts
    base = _pdt()["sec5"]
    runs8 = [dict(base["fig8"], departure=d) for d in (1.5, 6.4, 1.0, 1.1, 5.5)]
    runs9 = [dict(base["fig9"], w_err_max_late=w) for w in (0.07, 0.08, 0.26, 0.27, 0.3)]
    claims = D.paper_claims(_pdt(fig8_dep=5.0, sweep={"fig8": runs8, "fig9": runs9}))
    dep = by_statement(claims, "depart from the origin")
    assert dep.verdict == C.PARTLY and "2 of 5 seeds" in dep.reason and "[1.00-6.40 over 5 seeds]" in dep.our_value
    fig9 = by_statement(claims, "switching early")
    assert fig9.verdict == C.PARTLY and "bounded in 2 of 5 seeds" in fig9.reason   # 0.26 / 0.47 > 0.25
    coarse = D.paper_claims(_pdt(ts=1e-3))
    sec5 = [c for c in coarse if c.where.startswith("Sec. 5, Fig.")]
    assert len(sec5) == 5 and all(c.verdict == C.UNCHECKED and "10x" in c.reason for c in sec5)
