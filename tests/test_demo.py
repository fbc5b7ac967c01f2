"""``fawtgym demo``: flown by the evaluation runner, Table 4's metric beside the paper's only like for like."""

from __future__ import annotations

import re

import pytest

from fawtgym.eval import demo
from fawtgym.eval.runner import fly_cell
from fawtgym.eval.scenarios import get_scenario, scenario_from_mapping


def _row(text: str, label: str) -> list[str]:
    line = next(ln for ln in text.splitlines() if re.match(rf"\s*{re.escape(label)} \|", ln))
    return [c.strip() for c in line.split("|")]


def test_short_window_is_labelled_and_not_compared(capsys: pytest.CaptureFixture[str]) -> None:
    assert demo.main(["--seconds", "1.5", "--fan-on", "0.5", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "not Table 4's schedule" in out and "paper" not in _row(out, "controller")
    assert "Table 4 at" not in out
    # the printed number is the runner's metric for the same scenario and seed
    sc = scenario_from_mapping("demo", {"wind": {"name": "fawt-50", "on_time": 0.5}, "seconds": 1.5})
    cell, _ = fly_cell("px4", sc.to_dict(), [0])
    assert float(_row(out, "PX4")[1]) == pytest.approx(cell["episodes"][0]["pos_err_mean"], abs=6e-5)


def test_custom_duty_between_table_rows(capsys: pytest.CaptureFixture[str]) -> None:
    assert demo.main(["--duty", "45", "--seconds", "1", "--no-progress"]) == 0
    assert "FAWT 45 % duty" in capsys.readouterr().out


@pytest.mark.long
def test_table4_mode_prints_the_paper_schedule_metric_beside_the_paper(capsys: pytest.CaptureFixture[str]) -> None:
    from fawtgym.eval.reproduce.table4 import PAPER_TABLE4

    assert demo.main(["--duty", "50", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "re-weighted to the paper's 210 s schedule" in out
    row = _row(out, "PX4+FFTS-ESO")
    assert float(row[2]) == pytest.approx(PAPER_TABLE4[50][1])
    cell, _ = fly_cell("px4+ffts_eso", get_scenario("table4-50").to_dict(), [0])
    assert float(row[1]) == pytest.approx(cell["episodes"][0]["pos_err_paper_schedule"], abs=6e-5)
