"""``fawtgym reproduce pdt-sta``: shortened in the fast suite, the full study marked long."""

from __future__ import annotations

import csv
import pathlib

import pytest

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


@pytest.mark.long
def test_full_reproduction(tmp_path: pathlib.Path) -> None:
    res = R.run_all(tmp_path, quick=False, figures=True)
    mets = res["sec5"]
    for name in ("fig5", "fig6", "fig8", "fig9", "fig9_eq44", "fig8_exact"):
        assert R.claim_holds(name, mets[name]), (name, mets[name])
    # the paper's "about 1.6 s" for the conventional STSMO is not reproduced (ours settles later):
    assert mets["fig7"]["settle_time"] > mets["fig5"]["settle_time"]
    # over noise realizations: Euler at t_c jumps (median > 3), early switching does not (all < 1.5),
    # the exact eq.-7 step jumps less than Euler
    sw = {k: sorted(v) for k, v in res["seed_sweep"].items()}
    assert sw["fig8"][2] > 3.0 and sw["fig9"][-1] < 1.5 and sw["fig8_exact"][2] < sw["fig8"][2]
