"""seed-000 Sec. 6 study: setup (Tables 1-2, disturbances, Heun plant), Lee SE(3) controller, shortened study."""

import csv
import dataclasses
import re

import numpy as np
import pytest

from fawtgym.agents.lee_se3 import DesiredRateFilter, LeeSE3Controller
from fawtgym.core.so3 import orthogonality_error
from fawtgym.eval.reproduce import seed000_plant as plant
from fawtgym.eval.reproduce import seed000_sim as sim


def test_noise_sigma_from_psd_and_sampled_noise():
    """Table 2: PSD P sampled at h = 1 ms -> per-sample std sqrt(P/h)."""
    assert np.isclose(plant.noise_sigma(3e-8), np.sqrt(3e-5))
    assert np.isclose(plant.noise_sigma(3e-7), np.sqrt(3e-4))
    rng = np.random.default_rng(0)
    s = plant.initial_state(4000)
    m = plant.measure(s, np.ones(4000, bool), rng)
    assert np.isclose(np.std(m["position"] - s.b), np.sqrt(3e-5), rtol=0.03)
    assert np.isclose(np.std(m["angular_velocity"] - s.w), np.sqrt(3e-4), rtol=0.03)
    assert np.max(orthogonality_error(m["attitude"])) < 1e-13
    clean = plant.measure(s, np.zeros(4000, bool), rng)
    np.testing.assert_array_equal(clean["velocity"], s.v)


def test_disturbances_and_trajectories_as_in_sec6():
    np.testing.assert_allclose(plant.disturbance_force(3.0), [3 + 1.5, 4 - 1, -5 - 1])
    np.testing.assert_allclose(plant.disturbance_force(15.0), [5 + 1.5, -3 - 1, 4 - 1])
    np.testing.assert_allclose(plant.disturbance_torque(1.0), [-0.29, 0.22, 0.15])
    np.testing.assert_allclose(plant.disturbance_torque(21.0), [0.21, -0.28, -0.25])
    ref = plant.Reference(("HV", "SS", "FS", "HP"))
    b, v, a = ref(1.0)
    np.testing.assert_allclose(b[:, 2], -3.0)
    np.testing.assert_allclose(b[3], [10.0, 0.0, -3.0], atol=1e-12)
    np.testing.assert_allclose(v[3, 0], 0.0, atol=1e-12)
    h = 1e-6   # analytic derivatives
    for t in (0.3, 2.7):
        np.testing.assert_allclose((ref(t + h)[0] - ref(t - h)[0]) / (2 * h), ref(t)[1], atol=1e-6)
        np.testing.assert_allclose((ref(t + h)[1] - ref(t - h)[1]) / (2 * h), ref(t)[2], atol=1e-5)
    # HP: centripetal acceleration 10 (pi/2)^2 > g, as the paper says
    assert np.linalg.norm(ref(0.0)[2][3]) > plant.GRAVITY
    np.testing.assert_allclose(ref(0.0)[1][3], plant.V0)    # v(0) = 5 pi matches HP's v_d(0)
    with pytest.raises(ValueError, match="unknown trajectories"):
        plant.Reference(("XX",))


def test_heun_plant_conserves_energy_when_torque_free():
    """Torque- and disturbance-free rigid body: rotational energy conserved and R on SO(3) (Heun + exp map)."""
    s = plant.PlantState(np.zeros((1, 3)), np.zeros((1, 3)), np.eye(3)[None], np.array([[1.0, 0.2, -2.0]]))
    e0 = 0.5 * s.w[0] @ plant.INERTIA @ s.w[0]
    save = plant.disturbance_torque
    try:
        plant.disturbance_torque = lambda t: np.zeros(3)
        for k in range(2000):
            s = plant.heun_step(s, np.array([plant.MASS * plant.GRAVITY]), np.zeros((1, 3)), k * 1e-3)
    finally:
        plant.disturbance_torque = save
    assert abs(0.5 * s.w[0] @ plant.INERTIA @ s.w[0] - e0) < 1e-5 * e0
    assert orthogonality_error(s.R)[0] < 1e-12


def test_lee_controller_hovers_from_an_offset():
    ctrl = LeeSE3Controller(plant.MASS, plant.INERTIA)
    rates = DesiredRateFilter()
    s = plant.initial_state(2)
    s.v[:] = 0.0
    s.b[:] = [[0.5, 0.3, -2.0], [-1.0, 0.0, -3.5]]
    wd = wdd = np.zeros((2, 3))
    save_f, save_t = plant.disturbance_force, plant.disturbance_torque
    try:
        plant.disturbance_force = lambda t: np.zeros(3)
        plant.disturbance_torque = lambda t: np.zeros(3)
        for k in range(3000):
            f, tau, rd = ctrl.control(s.b, s.v, s.R, s.w, [0, 0, -3.0], [0, 0, 0], [0, 0, 0], w_d=wd, w_d_dot=wdd)
            wd, wdd = rates(rd, 1e-3)
            s = plant.heun_step(s, f, tau, k * 1e-3)
    finally:
        plant.disturbance_force, plant.disturbance_torque = save_f, save_t
    np.testing.assert_allclose(s.b, [[0, 0, -3.0]] * 2, atol=2e-3)
    np.testing.assert_allclose(f, plant.MASS * plant.GRAVITY, rtol=1e-3)
    with pytest.raises(ValueError, match="kx"):
        LeeSE3Controller(plant.MASS, plant.INERTIA, kx=-1.0)


def test_shortened_study_ordering(tmp_path):
    """3.2 s of HV and HP with and without noise (the full 30 s run is the long test below).

    Asserted ordering (the paper's qualitative claims that hold already at this horizon):
    * with noise, FxTSDO's force error is > 10x FFTS-ESO's (Remark 2);
    * in HP, LESO's torque error is > 3x FFTS-ESO's and > 2x LESO's own HV error (Euler angles);
    * FFTS-ESO's errors are small in every case (force < 0.5 N, torque < 0.03 N m).
    """
    res = sim.run_study(seconds=3.2, trajectories=("HV", "HP"), observers=("ffts_eso", "leso", "fxtsdo"))
    i = {name: k for k, name in enumerate(res.names)}
    rf, rt = res.rms_force, res.rms_torque
    for case in ("HV+noise", "HP+noise"):
        assert rf["fxtsdo"][i[case]] > 10 * rf["ffts_eso"][i[case]]
    for case, hv in (("HP", "HV"), ("HP+noise", "HV+noise")):
        assert rt["leso"][i[case]] > 3 * rt["ffts_eso"][i[case]]
        assert rt["leso"][i[case]] > 2 * rt["leso"][i[hv]]
    assert np.all(rf["ffts_eso"] < 0.5) and np.all(rt["ffts_eso"] < 0.03)
    assert not res.diverged
    figs = sim.plot(res, tmp_path)
    sim.write_csv(res, tmp_path / "rms.csv")
    sim.write_markdown(res, tmp_path / "rms.md", figs, 3.2)
    assert len(figs) == 4 and all(p.stat().st_size > 0 for p in figs)
    text = (tmp_path / "rms.md").read_text()
    assert "claims vs our results" in text and "ffts_eso" in text
    assert len((tmp_path / "rms.csv").read_text().splitlines()) == 1 + 3 * 4


def test_quick_horizon_covers_a_disturbance_step_and_its_reconvergence():
    """``--quick`` flies past the force step at 10 s and its 2 s window, so its steady RMS includes re-convergence:
    FFTS-ESO in HV, noise-free, for the quick horizon (the error jumps at the step and comes back into the band)."""
    assert sim.QUICK_SECONDS >= sim.STEP_TIMES[0] + 2 * sim.TRANSIENT
    res = sim.run_study(seconds=sim.QUICK_SECONDS, trajectories=("HV",), noise_cases=(False,),
                        observers=("ffts_eso",))
    t, ef = res.t, res.force_err["ffts_eso"][:, 0]
    band = sim.CONVERGED * sim.PHI_NORM
    jump = ef[(t > 10.0) & (t <= 10.5)].max()
    after = ef[t > 12.0].max()
    assert jump > 5 * band          # the step is seen ...
    assert after < band             # ... and the estimate is back in the band after it
    assert res.steady_force["ffts_eso"][0] < band


def test_noisy_claims_are_decided_over_noise_seeds(tmp_path):
    """Extra noise seeds replace only the noisy cases; a claim that differs between seeds takes the median verdict
    and lists every seed's verdict; the Markdown shows the noisy RMS as median [min-max]."""
    kw = dict(seconds=2.5, trajectories=("HV",), observers=("ffts_eso", "fxtsdo"))
    base = sim.run_study(**kw)
    other = sim.run_study(noise_cases=(True,), seed=1, **kw)
    merged = sim.with_noisy_cases_of(base, other)
    i_clean, i_noisy = base.names.index("HV"), base.names.index("HV+noise")
    for name in base.steady_force:
        assert merged.steady_force[name][i_clean] == base.steady_force[name][i_clean]
        assert merged.steady_force[name][i_noisy] == other.steady_force[name][0]
        assert merged.steady_force[name][i_noisy] != base.steady_force[name][i_noisy]
    # make seed 1 and 2 disagree with seed 0 on Remark 2 (FxTSDO meaningful with noise): 2 of 3 -> the median
    good = dataclasses.replace(merged, steady_force={**merged.steady_force,
                                                     "fxtsdo": merged.steady_force["fxtsdo"] * 0 + 0.01},
                               steady_torque={**merged.steady_torque,
                                              "fxtsdo": merged.steady_torque["fxtsdo"] * 0 + 0.001})
    claims = sim.claims_over_seeds([base, good, good], [0, 1, 2])
    rem = next(c for c in claims if c.where == "Remark 2")
    assert rem.verdict == "not" and "verdict per noise seed 0, 1, 2: reproduced / not / not" in rem.reason
    assert "(noise seed 1)" in rem.our_value
    same = next(c for c in claims if c.where == "Fig. 3")   # noise-free: identical in every seed, kept as is
    assert same == next(c for c in sim.paper_claims(base) if c.where == "Fig. 3")
    table = "\n".join(sim.noisy_spread_table([base, merged], [0, 1]))
    assert "median [min-max]" in table and "HV+noise" in table
    with pytest.raises(ValueError, match="same noisy trajectories"):
        sim.with_noisy_cases_of(base, sim.run_study(seconds=2.2, noise_cases=(True,), trajectories=("HV",),
                                                    observers=("ffts_eso", "fxtsdo")))


#: every verdict of the full run (30 s, four trajectories, both noise cases), in the order of paper_claims
EXPECTED_VERDICTS = [
    ("Fig. 3", "noise-free, the force estimates of FxTSDO, LESO an", "reproduced"),
    ("Fig. 4", "noise-free, FxTSDO's torque error shows a high tra", "partly"),        # HP 3.82x < 5x
    ("Fig. 4 (a)-(b)", "noise-free, the torque estimates of all three sche", "reproduced"),
    ("Fig. 4 (c)-(d)", "noise-free, the torque error of LESO diverges in F", "partly"),   # HP yes, FS 1.99x HV
    ("Fig. 4 (c)-(d)", "noise-free, the torque error of FxTSDO diverges in", "not"),      # 0.0054 / 0.0075 N m
    ("Fig. 6 (c)-(d)", "with noise, the torque error of LESO diverges in F", "partly"),
    ("Remark 2", "With noise FxTSDO gives no meaningful estimate", "reproduced"),
    ("Figs. 3-6, Sec. 8", "FFTS-ESO's force and torque estimates converge in ", "reproduced"),
    ("Sec. 6 (summary)", "FFTS-ESO outperforms LESO and FxTSDO when the vehi", "reproduced"),
    ("Sec. 8", "FFTS-ESO, unlike LESO and FxTSDO, converges in eve", "reproduced"),
]


@pytest.mark.long
def test_full_seed000_study(tmp_path):
    """The full Sec. 6 run (30 s, four trajectories, both noise cases) through the CLI entry point; every verdict."""
    outcome = sim.reproduce(["--out", str(tmp_path), "--no-progress"])  # the CLI's own path: 3 noise seeds
    claims = outcome.claims
    assert outcome.summary == tmp_path / "seed000_rms.md"
    with (tmp_path / "seed000_rms.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4 * 8
    res_md = outcome.summary.read_text()
    assert "With noise FxTSDO gives no meaningful estimate (Remark 2) | confirmed" in res_md
    assert [(c.where, c.statement[:50], c.verdict) for c in claims] == EXPECTED_VERDICTS
    assert "Noisy cases over noise seeds 0, 1, 2" in res_md
    # the paper's "FxTSDO's torque diverges noise-free in FS and HP" is listed, contradicted, with the reason
    fx = next(c for c in claims if "torque error of FxTSDO diverges" in c.statement)
    assert "most accurate torque estimate of the paper's 3 observers" in fx.reason
    # margins to two decimals: LESO's FS torque falls on 1.99x its HV value against the 2x "degrades" threshold
    leso = next(c for c in claims if c.statement.startswith("noise-free, the torque error of LESO"))
    assert "x its HV value (degrades above 2x)" in leso.reason
    # the NOTES block is computed: the FFTS-ESO's growth with noise, recomputed here from the CSV's steady RMS
    # (the mean over the trajectories of noisy / noise-free - 1), is the one printed (whole percent; the CSV's 6
    # significant digits move it by far less than the 0.5 % of the printed rounding)
    steady = {(r["trajectory"], r["noise"]): r for r in rows if r["observer"] == "ffts_eso"}
    trajectories = sorted({t for t, _ in steady})
    assert len(trajectories) == 4
    printed = re.search(r"with noise: force ([+-]\d+) %, torque ([+-]\d+) %", res_md)
    assert printed is not None and "barely grow" not in res_md, res_md
    for k, column in enumerate(("steady_rms_force_N", "steady_rms_torque_Nm")):
        growth = np.mean([float(steady[(t, "1")][column]) / float(steady[(t, "0")][column]) - 1.0
                          for t in trajectories])
        assert abs(int(printed.group(k + 1)) - 100 * growth) <= 0.5 + 1e-3, (column, growth, printed.group(0))
