"""``fawtgym reproduce pdt-sta``: shortened in the fast suite, the full study marked long."""

from __future__ import annotations

import csv
import pathlib

import numpy as np
import pytest

from fawtgym.eval.reproduce import claims as C
from fawtgym.eval.reproduce import pdt_sta as R


def test_quick_reproduction_writes_outputs(tmp_path: pathlib.Path) -> None:
    """Example 1 exactly, Figs. 5-9 at T_s = 1e-3 s (coarse: only robust properties are checked)."""
    assert R.main(["--out", str(tmp_path), "--quick"]) == 0
    for name in ("example1.csv", "sec5.csv", "summary.md", "fig3_ptc.png", "fig5.png"):
        assert (tmp_path / name).stat().st_size > 0
    rows = {r[0]: r for r in csv.reader(open(tmp_path / "example1.csv"))}
    assert abs(float(rows["t1 [s]"][2]) - 0.2062) < 5e-5
    assert abs(float(rows["kappa2 lower bound (36), t1 rounded to 0.2062"][2]) - 11.4155) < 5e-5
    assert abs(float(rows["t_e (43) [s], ell = sqrt(3)*0.02"][2]) - 1.3268) < 5e-5
    sec5 = {r["case"]: r for r in csv.DictReader(open(tmp_path / "sec5.csv"))}
    for case in ("fig5", "fig6"):  # the attitude error collapses at t_c even at the coarse step
        assert float(sec5[case]["g_err_tc"]) < 1e-3 * float(sec5[case]["g_err_0"])
        assert float(sec5[case]["g_err_half_tc"]) > 30 * float(sec5[case]["g_err_tc"])
    for case in sec5:  # everything stays bounded
        assert float(sec5[case]["g_err_max_late"]) < 2e-2


def test_noise_does_not_depend_on_run_length() -> None:
    """The same seed gives the same noise at step k in a short and a long run (the report's two "seed 0"
    results once disagreed, 3.69 vs 1.51, because the magnetometer's draws started after all the accelerometer's)."""
    t = np.arange(0.0, 0.3, 1e-3)
    g = np.tile(R.G0, (t.size, 1))
    long_ = R.quest_measurements(g, True, seed=4)
    short = R.quest_measurements(g[:100], True, seed=4)
    np.testing.assert_array_equal(short, long_[:100])
    assert not np.array_equal(R.quest_measurements(g[:100], True, seed=5), short)


def test_thresholds_are_relative_to_the_signal() -> None:
    """omega_hat = 0 (error = ||omega||, 0.64-1.0 omega_scale) fails every rate threshold of the verdicts."""
    assert max(R.W_ZERO_REL, R.W_BOUNDED_REL) < 0.5
    t = np.arange(0.0, 3.0, 1e-3)
    w = np.linalg.norm(R.omega_ref(t), axis=1)
    assert w.min() / w.max() > 2 * max(R.W_ZERO_REL, R.W_BOUNDED_REL)


@pytest.mark.long
def test_full_reproduction(tmp_path: pathlib.Path) -> None:
    res = R.run_all(tmp_path, quick=False, figures=True)
    mets = res["sec5"]
    verdicts = {c.where: c.verdict for c in res["claims"]}
    # every claim, as measured at the paper's step over seeds 0-4 (docs/reproductions.md)
    assert verdicts == {
        "Example 1, eq. 23": C.REPRODUCED, "Example 1, eq. 36": C.PARTLY, "Example 1, Fig. 3a": C.REPRODUCED,
        "Example 1, Fig. 3b": C.REPRODUCED, "Example 1, Fig. 3c": C.REPRODUCED, "Fig. 2, eqs. 23-25": C.REPRODUCED,
        "Sec. 5, eqs. 83-84": C.REPRODUCED, "Sec. 5, eq. 43": C.REPRODUCED,
        "Sec. 5, Fig. 5": C.REPRODUCED,       # attitude at zero by t_c, rate within 0.15 omega_scale from 1.45 s
        "Sec. 5, Fig. 6": C.PARTLY,           # attitude at t_c = 0.5 s, rate only from 1.27 s (0.54 omega_scale)
        "Sec. 5, Fig. 7": C.PARTLY,           # settles at 2.05 s, not about 1.6 s
        "Sec. 5, Fig. 8": C.REPRODUCED,       # every seed departs (> 3x)
        "Sec. 5, Fig. 9, eq. 43": C.PARTLY,   # no departure, but a late rate band of ~0.5 omega_scale
    }
    # the rate error of Fig. 5 after t_c is below 0.2 omega_scale (omega_hat = 0 would be >= 0.64) and Fig. 6's not
    assert mets["fig5"]["w_err_max_after_tc"] < 0.2 * mets["fig5"]["w_scale"]
    assert mets["fig6"]["w_err_max_after_tc"] > 0.4 * mets["fig6"]["w_scale"]
    # over noise seeds: Euler at t_c jumps in every seed, early switching in none, the exact eq.-7 step less
    sw = res["seed_sweep"]
    dep = {k: sorted(r["departure"] for r in v) for k, v in sw.items()}
    assert dep["fig8"][0] > 3.0 and dep["fig9"][-1] < 1.5 and dep["fig8_exact"][2] < dep["fig8"][2]
