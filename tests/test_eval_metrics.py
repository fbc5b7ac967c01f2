"""Leaderboard metrics against hand-computed trajectories, and the uncertainty helpers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fawtgym.eval.metrics import EpisodeRecorder, principal_angle, tilt_angle
from fawtgym.eval.stats import failure_rate, mean_ci, paired_difference

DT = 0.01


def rot(axis: str, angle: float) -> np.ndarray:
    return Rotation.from_euler(axis, angle).as_matrix()


def test_principal_angle_of_known_rotations() -> None:
    for axis, angle in (("x", 0.3), ("y", -1.2), ("z", 2.5), ("x", math.pi)):
        r_d = rot("z", 0.7)
        r = r_d @ rot(axis, angle)  # R_d^T R = rotation by |angle|
        assert principal_angle(r[None], r_d[None])[0] == pytest.approx(abs(angle), abs=1e-7)
    assert tilt_angle(rot("z", 1.0)[None])[0] == pytest.approx(0.0, abs=1e-12)  # heading is not tilt
    assert tilt_angle((rot("z", 1.0) @ rot("x", 0.4))[None])[0] == pytest.approx(0.4, abs=1e-12)
    assert tilt_angle(rot("y", -0.25)[None])[0] == pytest.approx(0.25, abs=1e-12)


def recorder(n: int = 2, steps: int = 10) -> EpisodeRecorder:
    return EpisodeRecorder(n, DT, steps, np.zeros((n, 3)), np.zeros(4), np.ones(4), np.full(4, 0.5), record_hz=50.0)


def truth(n: int, pos: np.ndarray, att: np.ndarray, wind: np.ndarray) -> dict:
    return {"position": pos, "attitude": att, "wind": wind, "force": np.zeros((n, 3)), "torque": np.zeros((n, 3))}


def test_time_averages_failure_timing_and_wind_axis() -> None:
    n, steps = 2, 10
    rec = recorder(n, steps)
    eye = np.broadcast_to(np.eye(3), (n, 3, 3))
    for k in range(steps):
        # row 0: error 0.1 k along east (the wind's direction); row 1: 0.2 north, fails after step 4
        pos = np.array([[0.0, 0.1 * k, 0.0], [0.2, 0.0, 0.0]])
        att = np.stack([rot("x", 0.1), np.eye(3)])
        wind = np.array([[0.0, 3.0, 0.0], [0.0, 0.0, 0.0]])
        action = np.array([[0.6, 0.6, 0.6, 0.6], [0.5, 0.5, 0.5, 1.0]])
        rec.step(truth(n, pos, att, wind), action, eye, (None, None), None)
        if k == 4:
            rec.end(np.array([False, True]), np.array(["", "out_of_bounds"], dtype=object))
    rows, traces = rec.finish()
    e = 0.1 * np.arange(steps)
    assert rows[0]["pos_err_mean"] == pytest.approx(e.mean())
    assert rows[0]["pos_err_rms"] == pytest.approx(math.sqrt((e * e).mean()))
    assert rows[0]["pos_err_max"] == pytest.approx(0.9)
    assert rows[0]["wind_excursion_max"] == pytest.approx(0.9)  # along +east, the wind axis
    assert rows[0]["att_err_mean"] == pytest.approx(0.1) and rows[0]["tilt_max"] == pytest.approx(0.1)
    assert rows[0]["failure"] == "" and rows[0]["failure_time"] is None
    assert rows[0]["time_flown"] == pytest.approx(steps * DT)
    assert rows[0]["control_effort"] == pytest.approx(0.1) and rows[0]["control_slew"] == pytest.approx(0.0)
    assert rows[0]["saturation"] == 0.0
    # row 1 ended after 5 steps: averages over those only; still air -> the axis is north
    assert rows[1]["failure"] == "out_of_bounds"
    assert rows[1]["failure_time"] == pytest.approx(5 * DT) and rows[1]["time_flown"] == pytest.approx(5 * DT)
    assert rows[1]["pos_err_mean"] == pytest.approx(0.2) and rows[1]["wind_excursion_max"] == pytest.approx(0.2)
    assert rows[1]["saturation"] == 1.0  # one motor at its upper bound every step
    assert rows[1]["control_effort"] == pytest.approx(math.sqrt(0.25 / 4))
    assert rows[0]["force_rmse"] is None and rows[0]["torque_rmse"] is None
    # traces every 2 steps (50 Hz at dt 0.01), NaN after row 1 ended
    assert traces["time"].tolist() == pytest.approx([0.02, 0.04, 0.06, 0.08, 0.1])
    assert np.isnan(traces["pos_err"][3:, 1]).all() and np.isfinite(traces["pos_err"][:2, 1]).all()


def test_slew_estimation_error_and_no_attitude_setpoint() -> None:
    n, steps = 1, 6
    rec = recorder(n, steps)
    for k in range(steps):
        a = np.full((1, 4), 0.5 + (0.01 if k % 2 else -0.01))
        f_true = np.array([[1.0, 0.0, 0.0]])
        rec.step(truth(n, np.zeros((1, 3)), np.eye(3)[None], np.zeros((1, 3))), a, None,
                 (f_true + [[0.0, 0.3, 0.4]], None), (f_true, np.zeros((1, 3))) if k else None)
    rows, _ = rec.finish()
    assert rows[0]["control_slew"] == pytest.approx(0.02 / DT)
    assert rows[0]["force_rmse"] == pytest.approx(0.5)  # |(0, 0.3, 0.4)|, steps 1..5 (no truth at step 0)
    assert rows[0]["torque_rmse"] is None
    assert rows[0]["att_err_mean"] is None and rows[0]["att_err_max"] is None


def test_mean_ci_and_degenerate_samples() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(1.0, 0.1, 30)
    e = mean_ci(x.tolist())
    assert e.low < e.value < e.high and e.value == pytest.approx(x.mean())
    assert e.high - e.low == pytest.approx(2 * 1.96 * 0.1 / math.sqrt(30), rel=0.35)
    assert mean_ci(x.tolist()) == e  # fixed resampling generator: same interval, bitwise
    assert mean_ci([0.5, None, float("nan")]) == mean_ci([0.5])
    single = mean_ci([0.5])
    assert single.value == 0.5 and single.low is None and single.n == 1
    flat = mean_ci([0.2, 0.2, 0.2])
    assert flat.low == flat.high == flat.value == pytest.approx(0.2)
    assert mean_ci([]).value is None


def test_paired_difference_uses_shared_seeds_only() -> None:
    agent = [1.0, 2.0, None, 4.0]
    base = [2.0, 3.5, 1.0, None]
    diff, rel = paired_difference(agent, base)
    assert diff.n == 2 and diff.value == pytest.approx(-1.25)
    assert rel == pytest.approx(1.5 / 2.75 - 1.0)
    with pytest.raises(ValueError, match="same seeds"):
        paired_difference([1.0], [1.0, 2.0])


def test_wilson_interval() -> None:
    z2 = 1.959963984540054**2
    e = failure_rate(0, 5)
    assert e.value == 0.0 and e.low == pytest.approx(0.0, abs=1e-12)
    assert e.high == pytest.approx(z2 / (5 + z2))  # Wilson upper bound at k = 0
    e = failure_rate(5, 5)
    assert e.low == pytest.approx(5 / (5 + z2)) and e.high == pytest.approx(1.0)
    assert failure_rate(0, 0).value is None
