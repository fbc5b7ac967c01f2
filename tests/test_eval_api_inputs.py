"""The eval package's Python API: the same errors at every worker count, scenarios and baselines named in one line
(fuzz findings: a bad agent aborted a one-worker run but was a summary error with two; KeyError and IndexError)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fawtgym.eval.leaderboard import build
from fawtgym.eval.runner import CellError, fly_cell, run_cells
from fawtgym.eval.scenarios import Scenario, scenario_from_mapping

CALM = Scenario("calm-short", "calm", seconds=0.02)


@pytest.mark.parametrize("workers", [1, 2])
def test_run_cells_refuses_bad_names_before_flying_at_every_worker_count(tmp_path: Path, workers: int) -> None:
    with pytest.raises(ValueError, match=r"^unknown agent 'nope'"):
        run_cells(tmp_path, ["nope", "px4"], [CALM], [1], workers=workers, progress=False)
    with pytest.raises(ValueError, match=r"^agents must be a list of agent names, got 'px4'$"):
        run_cells(tmp_path, "px4", [CALM], [1], workers=workers, progress=False)  # it said "unknown agent 'p'"
    with pytest.raises(ValueError, match=r"^scenarios must be a list of Scenario objects"):
        run_cells(tmp_path, ["px4"], ["calm"], [1], workers=workers, progress=False)  # type: ignore[list-item]
    with pytest.raises(ValueError, match=r"^workers must be an int in \[1, 4096\], got True \(bool\)$"):
        run_cells(tmp_path, ["px4"], [CALM], [1], workers=True, progress=False)
    (tmp_path / "a_file").write_text("not a folder\n")
    with pytest.raises(ValueError, match=r"^out '.*a_file' is a file, not a results folder$"):  # NotADirectoryError
        run_cells(tmp_path / "a_file", ["px4"], [CALM], [1], workers=workers, progress=False)
    assert not (tmp_path / "cells").exists()


def test_a_cell_that_cannot_be_flown_is_a_summary_error_at_every_worker_count(tmp_path: Path) -> None:
    """px4(FOO=1) parses but cannot be built: a CellError in the summary; the other cell flies."""
    summaries = [run_cells(tmp_path / str(w), ["px4(FOO=1)", "px4"], [CALM], [1], workers=w, progress=False)
                 for w in (1, 2)]
    for summary in summaries:
        assert summary["done"] == [("px4", "calm-short")]
        assert list(summary["errors"]) == [("px4(FOO=1)", "calm-short")]
        assert "unknown" in summary["errors"][("px4(FOO=1)", "calm-short")]
    assert summaries[0]["errors"] == summaries[1]["errors"]


def test_fly_cell_inputs(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"^scenario must be a mapping of a scenario's fields with its name"):
        fly_cell("px4", {"wind": "calm", "seconds": 0.05}, [1])  # KeyError: 'name'
    with pytest.raises(ValueError, match=r"^scenario must be a mapping"):
        fly_cell("px4", "calm", [1])  # type: ignore[arg-type]
    with pytest.raises(CellError, match=r"^unknown agent 'nope'"):  # as an agent that parses but cannot be built
        fly_cell("nope", CALM.to_dict(), [1])
    low = {**CALM.to_dict(), "name": "low", "setpoint": [0.0, 0.0, 5.0]}
    with pytest.raises(ValueError, match=r"^scenario 'low': setpoint"):  # the env's error, named as the scenario's
        fly_cell("px4", low, [1])
    sc = scenario_from_mapping("arr", {"wind": "calm", "seconds": 0.02, "setpoint": np.array([1.0, 0.0, -2.0])})
    assert sc.setpoint == (1.0, 0.0, -2.0)  # an array set point, as the env takes


def test_leaderboard_baseline_is_an_agent_of_the_run_or_refused() -> None:
    run = {"agents": ["px4", "px4+geso(order=3)"], "scenarios": [{"name": "s"}], "seeds": [1]}
    with pytest.raises(ValueError, match=r"^--baseline 'nope' is not an agent of this run; agents: px4, "):
        build(run, {}, None, "nope")  # it dropped the baseline silently
    with pytest.raises(ValueError, match=r"^this run has no scenario yet"):
        build({**run, "scenarios": []}, {}, None, None)  # IndexError
    with pytest.raises(ValueError, match=r"^no finished cell for scenario 's' yet$"):  # the spelling was accepted
        build(run, {}, None, "px4+geso( order = 3 )")
