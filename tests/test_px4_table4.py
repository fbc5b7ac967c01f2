"""Table 4 study plumbing: schedule averages, paper values, acceptance evaluation, CLI errors, demo smoke run."""

from __future__ import annotations

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.eval.reproduce import table4


def _square(hover: float, on: float, off: float, dt: float = 0.01) -> np.ndarray:
    t = (np.arange(int(round(hover / dt))) + 1) * dt
    return np.where((t > on) & (t <= off), 0.05, 0.01)[:, None] * np.array([1.0, 2.0])


def test_schedule_averages_paper_equivalent_is_schedule_independent() -> None:
    dt = 0.01
    paper = table4.schedule_averages(_square(210, 20, 170), dt, 210, 20, 170)
    np.testing.assert_allclose(paper["paper"], paper["whole"], rtol=1e-9)  # on the paper's schedule: identical
    np.testing.assert_allclose(paper["whole"], [(0.01 * 60 + 0.05 * 150) / 210 * k for k in (1, 2)], rtol=1e-9)
    short = table4.schedule_averages(_square(75, 5, 50), dt, 75, 5, 50)
    np.testing.assert_allclose(short["paper"], paper["paper"], rtol=1e-9)
    # the mean of a constant: exact up to the rounding of a sum over the run's 7500 samples (tests/_tolerance.py)
    assert_same_law(short["steady"], [0.05, 0.10], steps=7500, what="steady mean")
    assert not np.allclose(short["whole"], paper["whole"])  # the raw average does depend on the schedule
    # too short to hold a transient window: no extrapolation
    assert "paper" not in table4.schedule_averages(_square(20, 2, 15), dt, 20, 2, 15)


def test_paper_table4_values_and_reductions() -> None:
    # the paper's stated reductions (55, 57, 49 %) follow from its Table 4 to the rounding of the text
    for duty, stated in ((40, 0.55), (50, 0.57), (60, 0.49)):
        base, eso = table4.PAPER_TABLE4[duty][:2]
        assert 1 - eso / base == pytest.approx(stated, abs=0.006)
    assert table4.PAPER_TABLE4[70][0] is None and table4.PAPER_TABLE4[70][2] is None


def _cell(values, failures=None):
    v = np.asarray(values, dtype=float)
    return {"mean_position_error": v, "failures": failures or [""] * len(v)}


def test_evaluate_reports_the_table4_flight_goals_with_margins() -> None:
    good = {("px4", 50): _cell([0.06, 0.06]), ("px4+ffts_eso", 50): _cell([0.025, 0.026]),
            ("px4", 60): _cell([0.08]), ("px4+ffts_eso", 60): _cell([0.04]),
            ("px4", 70): _cell([0.5], ["upstream_wall"]), ("px4+ffts_eso", 70): _cell([0.05])}
    lines, ok = table4.evaluate(good, [50, 60, 70], "px4+ffts_eso")
    assert ok, lines
    text = "\n".join(lines)
    assert "PX4 fails at 70 % (paper: Failed!): failed in 1 of 1 seeds" in text and "**met**" in text
    bad = dict(good)
    bad[("px4", 60)] = _cell([0.5])  # 6.3x the paper's baseline, and the reduction 92 % (paper 49 %)
    bad[("px4+ffts_eso", 50)] = _cell([0.05])  # 2.0x the paper's, only 17 % lower than PX4
    bad[("px4", 70)] = _cell([0.3, 0.4], ["", "ground_contact"])  # holds in one seed of two
    lines, ok = table4.evaluate(bad, [50, 60, 70], "px4+ffts_eso")
    assert not ok
    text = "\n".join(lines)
    assert "PX4 at 60 % within 1.5x of Table 4 (0.0792 m): ours 0.5000 m = 6.31x: **NOT met**" in text
    assert "reduction at 50 % within 20 points of Table 4's 57 %: ours 17 % (-40 points): **NOT met**" in text
    assert "reduction at 60 % within 20 points of Table 4's 49 %: ours 92 % (+43 points): **NOT met**" in text
    assert "PX4 fails at 70 % (paper: Failed!): failed in 1 of 2 seeds (50 %, 95 % CI 9-91 %): **NOT met**" in text


def test_seed_and_duty_parsing() -> None:
    assert table4.parse_seeds("3") == [0, 1, 2]
    assert table4.parse_seeds("1000-1004") == [1000, 1001, 1002, 1003, 1004]
    assert table4.parse_seeds("0,7,1000-1001") == [0, 7, 1000, 1001]
    for bad, msg in (("1000", "for the single seed 1000 write 1000-1000"), ("5-3", "empty"), ("a", "a count"),
                     ("1,1", "twice")):
        with pytest.raises(ValueError, match=msg):
            table4.parse_seeds(bad)
    assert table4.parse_duties("30,45,62.5,70") == [30, 45, 62.5, 70]
    for bad in ("120", "29.9", "nan", "x"):
        with pytest.raises(ValueError, match="--duties"):
            table4.parse_duties(bad)


def test_defaults_fly_the_paper_schedule_and_explicit_flags_win_over_quick() -> None:
    """The command line as ``fawtgym reproduce table4`` resolves it (:func:`table4.parse_args`)."""
    args = table4.parse_args([])
    assert args.columns == ["px4", "px4+ffts_eso"] and args.argv == []
    assert (args.hover_seconds, args.fan_on, args.fan_off) == table4.PAPER_SCHEDULE
    assert args.duties == [30, 40, 50, 60, 70] and args.seeds == [0, 1, 2, 3, 4]
    assert args.assumptions.observer_inputs == "commanded" and args.assumptions.pose_latency > 0
    quick = table4.parse_args(["--quick"])
    assert (quick.hover_seconds, quick.fan_on, quick.fan_off) == table4.QUICK_SCHEDULE
    assert quick.duties == [50] and quick.seeds == [0, 1]
    mixed = table4.parse_args(["--quick", "--duties", "45,65", "--seeds", "1000-1002", "--hover-seconds", "90"])
    assert mixed.duties == [45, 65] and mixed.seeds == [1000, 1001, 1002] and mixed.hover_seconds == 90.0
    assert mixed.fan_on == 5.0  # the flag not given keeps the quick value
    assert table4.parse_args(["--quick", "--paper-schedule"]).hover_seconds == 210.0
    ideal = table4.parse_args(["--applied-inputs"]).assumptions
    assert (ideal.observer_inputs, ideal.pose_latency, ideal.thrust_model_error) == ("applied", 0.0, 0.0)


@pytest.mark.parametrize("argv, msg", [
    (["--duties", "120"], "--duties 120: each duty must be a percentage in [30, 70]"),
    (["--duties", "35,x"], "is not a number"),
    (["--sensors", "foo"], "--sensors foo: unknown sensor preset; valid: none, seed000, mocap_imu"),
    (["--control-rate", "333"], "--control-rate 333: must be one of 100, 200, 500, 1000 Hz"),
    (["--seeds", "1000"], "for the single seed 1000 write 1000-1000"),
    (["--observers", "nope"], "unknown observer"),
    (["--fan-on", "60", "--fan-off", "50"], "need 0 <= --fan-on < --fan-off"),
    (["--paper-schedule", "--fan-on", "3"], "--paper-schedule fixes the schedule"),
])
def test_cli_errors_are_one_line_exit_2(argv, msg, capsys, tmp_path) -> None:
    with pytest.raises(SystemExit) as exc:
        table4.main([*argv, "--out", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1 and "Traceback" not in err


def test_physical_limit_counts_the_upstream_wall_and_records_excursions() -> None:
    """PX4 at 70 % is blown downstream at switch-on and overshoots into the array at switch-off."""
    from fawtgym.eval.reproduce.table4_flight import Assumptions, fly

    flown = fly("px4", [(70, 0)], 14.0, 1.0, 7.0, Assumptions())
    crash = flown["crash_upstream"]
    assert crash == pytest.approx(1.5 - (0.24 + 0.127))
    assert flown["downstream"][0] > 1.0  # far downstream after switch-on, with no box to end it
    if flown["failure"][0]:
        assert flown["failure"][0] == "upstream_wall" and flown["upstream"][0] >= crash
        assert np.isnan(flown["pos"][-1, 0])  # nothing recorded after the crash
    else:
        assert flown["upstream"][0] < crash


def test_demo_smoke(capsys) -> None:
    from fawtgym.eval import demo

    assert demo.main(["--seconds", "1.0", "--fan-on", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "PX4+FFTS-ESO" in out and "held hover" in out


def test_sensitivity_varies_each_assumption_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    from fawtgym.eval.reproduce.table4_flight import SENSITIVITY_RANGES, Assumptions

    seen = []

    def fake(columns, duties, seeds, hover, on, off, a, sensors, rate, box, progress=False, tick=None):
        seen.append(a)
        return {(c, d): {"mean_position_error": np.array([0.1 if c == "px4" else 0.04]),
                         "paper_position_error": np.array([0.1 if c == "px4" else 0.04]), "failures": [""]}
                for c in columns for d in duties}

    monkeypatch.setattr(table4, "fly_study", fake)
    base = Assumptions()
    rows = table4.run_sensitivity(["px4", "px4+ffts_eso"], [50], [0], 75.0, 5.0, 50.0, base, "mocap_imu", 200.0,
                                  False)
    assert len(rows) == sum(len(v) for v in SENSITIVITY_RANGES.values())
    for a, row in zip(seen, rows, strict=True):
        changed = {f for f in vars(base) if getattr(a, f) != getattr(base, f)}
        assert changed == {row["name"]} and getattr(a, row["name"]) == row["value"]
    text = "\n".join(table4.sensitivity_lines(rows, ["px4", "px4+ffts_eso"]))
    assert "| linear_drag_per_kg | 0.26 | 50 % | 0.1000 | 0.0400 | 60 % | 0/1 | 0/1 |" in text
