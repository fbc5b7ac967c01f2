"""Every ``fawtgym reproduce`` study takes ``--no-progress``, shows a bar otherwise, and its bar only counts.

The progress callback of each simulation loop is called once per unit of work (the count is checked), and a
run with the callback gives bitwise the same numbers as one without (same code path, run twice: tests/_tolerance.py).
Short horizons keep the file at a few seconds.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fawtgym.cli import REPRODUCTIONS, main
from fawtgym.eval.reproduce import report


class Counter:
    """A progress callback that sums what it is told."""

    def __init__(self) -> None:
        self.n = 0

    def __call__(self, k: int = 1) -> None:
        self.n += k


def _same(a: Any, b: Any) -> None:
    """Bitwise equal nested results (arrays, dicts, lists, dataclasses, scalars)."""
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            _same(a[k], b[k])
    elif hasattr(a, "__dataclass_fields__"):
        _same(vars(a), vars(b))
    elif isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        np.testing.assert_array_equal(a, b)
    else:
        assert a == b


@pytest.mark.parametrize("name", [n for n in REPRODUCTIONS if n != "all"] + ["all"])
def test_every_study_accepts_no_progress(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``--no-progress`` parses (an unknown flag beside it is the only one refused)."""
    with pytest.raises(SystemExit) as exc:
        raise SystemExit(main(["reproduce", name, "--no-progress", "--bogus-flag"]))
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert "--bogus-flag" in err and "--no-progress" not in err, err


def test_geso_bar_shows_and_hides(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["reproduce", "geso", "--t-end", "0.05", "--steady-from", "0", "--no-figures"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    assert "geso" in capsys.readouterr().err
    assert main([*argv, "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    assert "geso" not in capsys.readouterr().err
    assert (tmp_path / "a" / "geso_rms.csv").read_text() == (tmp_path / "b" / "geso_rms.csv").read_text()


def test_geso_callback_counts_steps() -> None:
    from fawtgym.eval.reproduce.geso import simulate

    c = Counter()
    with_bar = simulate(t_end=0.05, dt=1e-3, progress=c)
    assert c.n == 51
    _same(with_bar, simulate(t_end=0.05, dt=1e-3))


def test_hc_eso_callback_counts_steps() -> None:
    from fawtgym.eval.reproduce.hc_eso import run

    c = Counter()
    with_bar = run(t_end=0.2, h=0.01, seed=1, progress=c)
    assert c.n == 21
    _same(with_bar, run(t_end=0.2, h=0.01, seed=1))


def test_pdt_sta_callback_counts_steps() -> None:
    from fawtgym.eval.reproduce.pdt_sta import CASES, run_case, seed_sweep

    case = next(c for c in CASES if c.noise)
    c = Counter()
    with_bar = run_case(case, ts=1e-3, t_f=0.1, seed=2, progress=c)
    assert c.n == 100
    _same(with_bar, run_case(case, ts=1e-3, t_f=0.1, seed=2))
    c = Counter()
    seed_sweep((0, 1), ts=1e-2, t_f=1.8, cases=("fig8", "fig9"), progress=c)
    assert c.n == 2 * 2 * 180


def test_table4_callback_counts_steps() -> None:
    from fawtgym.eval.reproduce.table4_flight import flight_steps, fly

    c = Counter()
    with_bar = fly("px4", [(50, 0)], 0.3, 0.1, 0.2, progress=c)
    assert c.n == flight_steps(0.3, 200.0) == 60
    _same(with_bar, fly("px4", [(50, 0)], 0.3, 0.1, 0.2))


def test_table4_sensitivity_bar_covers_every_flight(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The bar's total is what the flights tick, with and without ``--sensitivity``."""
    from fawtgym.eval.reproduce import table4

    seen: dict[str, int] = {}
    real_bar = table4.bar

    def spy_bar(total: int, desc: str, unit: str = "step", disable: bool = False) -> Any:
        seen["total"] = total
        return real_bar(total, desc, unit, disable)

    def fake_fly(column: str, rows: Any, hover: float, on: float, off: float, *a: Any, progress: Any = None,
                 **kw: Any) -> Any:
        progress(table4.flight_steps(hover, 200.0))
        seen["ticked"] = seen.get("ticked", 0) + table4.flight_steps(hover, 200.0)
        raise _Stop

    class _Stop(Exception):
        pass

    monkeypatch.setattr(table4, "bar", spy_bar)
    monkeypatch.setattr(table4, "fly", fake_fly)
    with pytest.raises(_Stop):
        table4.reproduce(["--quick", "--out", str(tmp_path), "--no-progress"])
    assert seen["total"] == 2 * table4.flight_steps(75.0, 200.0)
    with pytest.raises(_Stop):
        table4.reproduce(["--quick", "--out", str(tmp_path), "--no-progress", "--sensitivity"])
    n_sens = len(table4.sensitivity_cases(table4.Assumptions(), 200.0))
    assert n_sens >= 1 and seen["total"] == (2 + 2 * n_sens) * table4.flight_steps(75.0, 200.0)


def test_qb_callback_counts_alphas() -> None:
    pytest.importorskip("cvxpy")
    from fawtgym.observers.qb_design import sweep_alpha
    from fawtgym.observers.qb_uav_model import uav_model

    c = Counter()
    sweep = sweep_alpha(uav_model(), [0.5, 2.0], progress=c)
    assert c.n == 2 and sweep.alphas.size + len(sweep.failed) == 2


def test_reproduce_all_runs_studies_without_their_bar(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """``reproduce all`` passes ``--no-progress`` to each study (its stderr is the study's log) and records the
    command line without it."""
    got: list[list[str]] = []

    class Fake:
        @staticmethod
        def reproduce(argv: list[str]) -> None:
            got.append(argv)

    monkeypatch.setattr(report.importlib, "import_module", lambda name: Fake)
    run = report.run_study(report.STUDIES[0], tmp_path, quick=True)
    assert got and got[0][-1] == "--no-progress"
    assert "--no-progress" not in run.argv and run.error is None


def test_bench_all_bar_over_the_jobs(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """``bench all`` shows a bar over the benchmarks (off with ``--no-progress``); their lines still print."""
    import sys
    import types

    from fawtgym import cli

    fake = types.ModuleType("_fake_bench")
    fake.main = lambda argv: print("ratio 1.0") or 0  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "_fake_bench", fake)
    monkeypatch.setattr(cli, "BENCHMARKS", {"one": ("_fake_bench:main", ""), "two": ("_fake_bench:main", "")})
    assert main(["bench", "all"]) == 0
    out, err = capsys.readouterr()
    assert out.count("ratio 1.0") == 2 and "fawtgym bench two" in err
    assert main(["bench", "all", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert out.count("ratio 1.0") == 2 and "fawtgym bench" not in err
