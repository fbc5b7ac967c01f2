"""``fawtgym observe``: observers on real PX4 logs (tests/data/flight_logs, from pyulog's test data, BSD-3)
and on a tlog flown in our own env with known truth (:mod:`fawtgym.flightlog.synth_tlog`)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyulog")
pytest.importorskip("pymavlink")

from fawtgym.envs.vehicles import GRAVITY, make_vehicle
from fawtgym.flightlog import FlightLogError, read_log
from fawtgym.flightlog.phases import PHASES
from fawtgym.flightlog.runner import observe
from fawtgym.flightlog.timebase import hold, make_grid

DATA = Path(__file__).parent / "data" / "flight_logs"
HW = DATA / "sample.ulg"  # real hardware, PX4 ~v1.6, older topic set, on the ground, disarmed
SITL = DATA / "sample_px4_events.ulg"  # PX4 v1.15 dev SITL (jMAVSim), newer topic set, climbs to ~2.2 m
GROUND = DATA / "sample_logging_tagged_and_default_params.ulg"  # PX4 v1.13 SITL, on the ground, armed
JMAVSIM = DATA / "jmavsim_quad.yaml"
TLOG = DATA / "env_s500_fawt50.tlog"
TRUTH = DATA / "env_s500_fawt50_truth.csv"
# a real PX4 v1.14 SITL flight (none_iris) flying our env through `fawtgym sitl px4` in FAWT-50 wind, trimmed,
# with the bridge's truth (the env's disturbance wrench) beside it; see data/flight_logs/README.md
IRIS_ULOG = DATA / "sitl_iris_fawt50.ulg"
IRIS_TLOG = DATA / "sitl_iris_fawt50_replay.tlog"
IRIS_TRUTH = DATA / "sitl_iris_fawt50_truth.csv"
HOVER = PHASES.index("hover")


@pytest.mark.parametrize("path, topic_set", [(HW, "actuator_controls_0"), (SITL, "actuator_motors"),
                                             (GROUND, "actuator_controls_0"), (TLOG, "actuator_outputs")])
def test_each_log_parses_with_the_topics_the_observers_need(path: Path, topic_set: str) -> None:
    log = read_log(path)
    assert log.duration > 5
    for topic in ("vehicle_local_position", "vehicle_attitude", "sensor_combined", "vehicle_status", topic_set):
        assert log.has(topic), topic
        assert np.all(np.diff(log.topics[topic].t) >= 0)


def test_sitl_hover_estimate_is_finite_and_physically_sized() -> None:
    """The jMAVSim flight has no wind: the true disturbance is jMAVSim's drag (0.01 v^2 N, < 0.05 N at the
    flight's speeds) plus model mismatch.  Bound: in hover the mean estimated force is below 0.25 m g per axis
    (the thrust model is pinned by PX4's own hover-thrust estimate; 0.25 is the contradiction threshold of
    that scale), its spread below 0.25 m g, and the mean torque below 5 % of the largest roll torque the
    rotors make (2 l T_max / sqrt(2) ~ 0.93 N m).  A wrong frame, sign or thrust scale (a factor 2) breaks these."""
    vehicle = make_vehicle(JMAVSIM)
    r = observe(SITL, ["ffts_eso", "leso"], JMAVSIM)
    assert r.report["inputs"]["used"] == "motors" and r.report["thrust_scale"]["from"] == "estimate"
    assert abs(r.report["thrust_scale"]["used"] - 1.0) < 0.05  # PX4's hover thrust 0.487 vs jMAVSim 0.8 kg / 16 N
    # two independent routes to the thrust scale agree: PX4's hover-thrust estimator and our accelerometer check
    assert r.report["thrust_scale"]["candidates"]["hover"] == pytest.approx(r.report["thrust_scale"]["used"], rel=0.05)
    assert not r.warnings
    hover = r.settled & (r.phases.label == HOVER)
    assert hover.sum() >= 50  # at least a second of settled hover at 50 Hz
    weight = vehicle.mass * GRAVITY
    tau_max = 2 * vehicle.arm_length * vehicle.max_thrust_per_rotor / np.sqrt(2)
    for name, (force, torque) in r.estimates.items():
        f, t = force[hover], torque[hover]
        assert np.all(np.isfinite(f)) and np.all(np.isfinite(t)), name
        assert np.all(np.abs(f.mean(0)) < 0.25 * weight), (name, f.mean(0))
        assert np.all(f.std(0) < 0.25 * weight), (name, f.std(0))
        assert np.all(np.abs(t.mean(0)) < 0.05 * tau_max), (name, t.mean(0))
        assert np.any(np.abs(f.mean(0)) > 1e-4)  # something was estimated, not zeros


def test_contradicting_preset_warns_and_reports_the_scale() -> None:
    heavy = make_vehicle(JMAVSIM).replace(mass=1.6)  # twice jMAVSim's 0.8 kg: PX4 hovered at 0.49 of 4 x 4 N
    r = observe(SITL, ["leso"], heavy)
    scale = r.report["thrust_scale"]["candidates"]["estimate"]
    assert scale == pytest.approx(2.0, rel=0.05) and r.report["thrust_scale"]["used"] == scale
    assert any("contradicts vehicle 'jmavsim_quad'" in w and "2.01" in w for w in r.warnings)


@pytest.mark.parametrize("path", [HW, GROUND])
def test_on_ground_logs_are_not_estimated(path: Path) -> None:
    r = observe(path, ["ffts_eso"], "s500")
    assert not r.estimated.any() and not r.phases.airborne.any()
    force, torque = r.estimates["ffts_eso"]
    assert np.all(np.isnan(force)) and np.all(np.isnan(torque))
    assert any("nothing was estimated" in w for w in r.warnings)


def test_sitl_ground_phases_before_takeoff_and_after_landing_are_not_estimated() -> None:
    r = observe(SITL, ["ffts_eso"], JMAVSIM)
    ground = r.phases.label == PHASES.index("ground")
    assert ground[0] and ground[-1] and ground.sum() > 0.5 * ground.size  # 15 s on the ground, then ~12 s flight
    assert not np.any(r.estimated & ground)
    assert np.all(np.isnan(r.estimates["ffts_eso"][0][ground]))
    assert {"climb", "hover", "descend"} <= set(r.phases.names()[r.estimated])


def test_tlog_from_our_env_matches_the_truth() -> None:
    """End to end on a tlog flown in our env (FAWT-50 wind): with the preset's own thrust model the mean of each
    force component over the settled flight is within 10 % of the truth's mean + 0.1 N, and each torque
    component within 0.005 N m (the observers' lag and the 50 Hz log leave an rms error of ~0.4 N, ~0.01 N m)."""
    truth = np.loadtxt(TRUTH, delimiter=",", skiprows=1)
    r = observe(TLOG, ["ffts_eso", "leso", "fxtsdo"], "s500", thrust_scale="preset")
    assert r.report["inputs"]["used"] == "outputs"
    held, ok = hold(truth[:, 0] - 1e-9, truth[:, 1:], r.t)
    m = r.settled & ok
    assert m.sum() > 200 and not np.any(r.estimated[: int(0.9 * 50)])  # the first second is on the ground
    want = held[m].mean(0)
    assert abs(want[0]) > 2.0  # the fan pushes north: a real signal to find
    for name, (force, torque) in r.estimates.items():
        got = np.concatenate([force, torque], axis=1)[m].mean(0)
        assert np.all(np.abs(got[:3] - want[:3]) < 0.1 * np.abs(want[:3]) + 0.1), (name, got, want)
        assert np.all(np.abs(got[3:] - want[3:]) < 0.005), (name, got, want)


@pytest.mark.parametrize("path, options, torque_bound", [
    (IRIS_ULOG, {}, 0.02),
    (IRIS_ULOG, {"thrust_curve": "preset", "thrust_scale": "preset"}, 0.005),
    (IRIS_TLOG, {}, 0.005),
], ids=["ulog-auto", "ulog-env-rotor-model", "replay-tlog-auto"])
def test_real_px4_sitl_log_matches_the_bridges_truth(path: Path, options: dict, torque_bound: float) -> None:
    """End to end through a real flight controller: PX4 v1.14 flew our env (bridge) in 8 m/s FAWT wind, and
    observe on PX4's own log (or the replay's tlog) recovers the env's true disturbance.  Time base: log time +
    the log's start = PX4 time = the bridge's simulated time (docs/sitl.md).  Compared: the settled hover points
    where the truth has no ground contact (observe's "hover" also holds the ~2 s between touchdown and PX4's
    land detector firing, when the ground pushes up; those are left out).

    Bound: each axis of the mean estimated force is within 10 % of the mean true force's magnitude (5.7 N:
    5.6 N north from the fan, 1.2 N up) of the truth.  Measured (ffts_eso, leso): north -0.03/-0.10 N,
    east 0.02/0.03 N, down -0.47/-0.45 N with the default ``auto`` (PX4's linear thrust curve, THR_MDL_FAC = 0,
    scaled by the hover's accelerometer, which books the mean body-z disturbance into the rotor model); within
    0.14 N on every axis with our env's rotor model (``preset``; the tlog's ``auto`` picks it: a tlog has no
    THR_MDL_FAC).  Torque: within 0.005 N m with our rotor model (measured <= 0.0012 N m); 0.02 N m with PX4's
    linear curve, which misstates the differential thrust of our rotors (T ~ omega^2) and leaves 0.011 N m of
    the -0.024 N m pitch torque (measured).  A frame or sign error or a lost wind (11 N) breaks these."""
    from fawtgym.eval.sitl.airframe import iris

    r = observe(path, ["ffts_eso", "leso"], iris(), **options)
    truth = np.loadtxt(IRIS_TRUTH, delimiter=",", skiprows=1)  # t, wind, f_n/e/d, t_x/y/z, contact (20 ms means)
    held, ok = hold(truth[:, 0] - r.log.start, truth[:, 4:11], r.t)
    hover = r.settled & (r.phases.label == HOVER) & ok & (held[:, 6] == 0.0)
    assert hover.sum() >= 20 * r.report["rate_hz"]
    want = held[hover, :6].mean(0)
    magnitude = float(np.linalg.norm(want[:3]))
    assert 4.0 < want[0] < 7.0 and magnitude > 5.0  # the fan pushes north: a real signal to find
    for name, (force, torque) in r.estimates.items():
        got = np.concatenate([force, torque], axis=1)[hover].mean(0)
        assert np.all(np.abs(got[:3] - want[:3]) < 0.1 * magnitude), (name, got, want)
        assert np.all(np.abs(got[3:] - want[3:]) < torque_bound), (name, got, want)


def test_log_start_is_px4_time_in_both_log_kinds() -> None:
    """The ULog and the replay's tlog of one SITL flight start within 0.1 s of each other on PX4's clock, and
    their hover phases line up (the same land detector seen through two paths)."""
    ulog, tlog = read_log(IRIS_ULOG), read_log(IRIS_TLOG)
    assert 0.0 < ulog.start < 1.0 and abs(ulog.start - tlog.start) < 0.1
    t_u = ulog.topics["vehicle_local_position"].t + ulog.start
    t_t = tlog.topics["vehicle_local_position"].t + tlog.start
    z_u = np.interp(20.0, t_u, ulog.topics["vehicle_local_position"].fields["z"])
    z_t = np.interp(20.0, t_t, tlog.topics["vehicle_local_position"].fields["z"])
    assert z_u == pytest.approx(z_t, abs=0.05) and z_u < -1.0  # at PX4 time 20 s both say: hovering at 1.5 m


def test_sample_and_hold_never_looks_ahead() -> None:
    t = np.array([0.0, 1.0, 2.0])
    v = np.array([[10.0], [20.0], [30.0]])
    grid = make_grid(-0.5, 2.5, 2.0)
    held, ok = hold(t, v, grid)
    np.testing.assert_array_equal(ok, grid >= 0)
    np.testing.assert_array_equal(held[ok, 0], [10, 10, 20, 20, 30, 30])


def _one_line(exc: pytest.ExceptionInfo) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_missing_topic_is_one_line_naming_versions_and_alternative() -> None:
    log = read_log(SITL)
    del log.topics["vehicle_local_position"]
    with pytest.raises(FlightLogError) as exc:
        observe(log, ["leso"], JMAVSIM)
    assert "'vehicle_local_position'" in _one_line(exc) and "all PX4 versions" in str(exc.value)
    with pytest.raises(FlightLogError) as exc:
        observe(HW, ["leso"], "s500", inputs="motors")
    msg = _one_line(exc)
    assert "'actuator_motors'" in msg and "v1.13 and later" in msg and "actuator_controls_0" in msg


def test_truncated_and_non_ulog_files_are_one_line_errors(tmp_path: Path) -> None:
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(SITL.read_bytes()[:3000])
    with pytest.raises(FlightLogError) as exc:
        read_log(cut)
    assert "truncated" in _one_line(exc)
    text = tmp_path / "notes.ulg"
    text.write_text("this is not a flight log\n")
    with pytest.raises(FlightLogError) as exc:
        read_log(text)
    assert "not a readable PX4 ULog" in _one_line(exc)
    with pytest.raises(FlightLogError) as exc:
        read_log(tmp_path / "flight.bin")
    assert "does not exist" in _one_line(exc)


def test_wrong_topics_directory_and_rates_are_named(tmp_path: Path) -> None:
    """A topic the log lacks was reported as a truncated log; a folder as missing; rates of 0, NaN, 1e300, a str
    raised ZeroDivisionError, numpy's size or ufunc errors, or ran and estimated nothing."""
    with pytest.raises(FlightLogError, match=r"holds no sample of the topic\(s\) \['nope'\]"):
        read_log(SITL, ("nope",))
    with pytest.raises(FlightLogError, match=r"topics must be a sequence of PX4 topic names"):
        read_log(SITL, "vehicle_attitude")  # type: ignore[arg-type]
    assert "vehicle_attitude" in read_log(SITL, ("vehicle_attitude",)).topics
    with pytest.raises(FlightLogError, match=r"is a directory"):
        read_log(tmp_path)
    for rate in (0.5, float("nan"), 1e300, "50", 10**5000):
        with pytest.raises(FlightLogError, match=r"^observer rate \(--rate\) must be a finite real number in "
                                                 r"\[1, 10000\] Hz, got "):
            observe(SITL, ["leso"], JMAVSIM, rate=rate)  # type: ignore[arg-type]
        with pytest.raises(FlightLogError, match=r"^observer rate"):
            make_grid(0.0, 1.0, rate)  # type: ignore[arg-type]
    for bad in (None, 5):
        with pytest.raises(FlightLogError, match=r"^log file must be a path \(a str or os.PathLike\), got "):
            read_log(bad)  # type: ignore[arg-type]
    with pytest.raises(FlightLogError, match=r"^the log's usable time span: t_start must be a finite real number"):
        make_grid("0", 1.0, 50.0)  # type: ignore[arg-type]
    for scale in ("1e400", 10**5000, "-1", True):
        with pytest.raises(FlightLogError, match=r"^--thrust-scale must be one of \['auto'"):
            observe(SITL, ["leso"], JMAVSIM, thrust_scale=scale)  # type: ignore[arg-type]


def test_trim_rates_are_checked(tmp_path: Path) -> None:
    from fawtgym.flightlog.trim import trim_ulog

    for rate in (0, float("nan"), -1):
        with pytest.raises(ValueError, match=r"^max_rate \(--max-rate\) must be a finite real number in \(0, "):
            trim_ulog(SITL, tmp_path / "x.ulg", rate)
    assert not (tmp_path / "x.ulg").exists()


def test_cli_errors_exit_2_with_one_line_and_no_traceback(tmp_path: Path) -> None:
    bad = tmp_path / "bad.ulg"
    bad.write_text("garbage")
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(SITL.read_bytes()[:3000])
    cases = [[str(bad), "--observer", "leso", "--vehicle", "s500"],
             [str(cut), "--observer", "leso", "--vehicle", "s500"],
             [str(HW), "--observer", "leso", "--vehicle", "s500", "--inputs", "motors"],
             [str(SITL), "--observer", "nope", "--vehicle", "s500"],
             [str(SITL), "--observer", "leso", "--vehicle", "s500", "--thrust-scale", "-1"],
             [str(SITL), "--observer", "leso", "--vehicle", str(JMAVSIM), "--rate", "10"]]  # LESO diverges at 10 Hz
    for args in cases:
        p = subprocess.run([sys.executable, "-m", "fawtgym.cli", "observe", *args, "--out", str(tmp_path / "o")],
                           capture_output=True, text=True, cwd=Path(__file__).parents[1])
        assert p.returncode == 2, (args, p.stderr)
        assert p.stdout == "" and len(p.stderr.strip().splitlines()) == 1, (args, p.stderr)
        assert "Traceback" not in p.stderr and p.stderr.startswith("fawtgym observe: error:")


def test_cli_writes_table_summary_and_figures(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from fawtgym.cli import main

    out = tmp_path / "out"
    assert main(["observe", str(SITL), "--observer", "ffts_eso,leso", "--vehicle", str(JMAVSIM), "--out", str(out),
                 "--format", "csv"]) == 0
    lines = (out / "estimates.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert "ffts_eso_force_n_N" in header and "leso_torque_z_Nm" in header and "mode" in header
    rows = [dict(zip(header, line.split(","), strict=True)) for line in lines[1:]]
    assert all((r["estimated"] == "1") == (r["ffts_eso_force_d_N"] != "") for r in rows)
    assert any(r["phase"] == "hover" and r["estimated"] == "1" for r in rows)
    summary = (out / "summary.txt").read_text()
    assert "ground   shown, not estimated" in summary and "thrust scale" in summary
    for fig in ("force.png", "torque.png"):
        assert (out / fig).stat().st_size > 10_000


def test_license_is_committed_beside_the_logs() -> None:
    assert "Redistribution and use in source and binary forms" in (DATA / "LICENSE-pyulog.md").read_text()
    assert shutil.disk_usage(DATA)  # the folder exists in a fresh clone (committed, not ../shared)


def test_bench_flightlog_prints_time_memory_and_target(capsys: pytest.CaptureFixture[str]) -> None:
    from fawtgym.flightlog.bench import main

    assert main(["--minutes", "0.6"]) == 0  # two tiles of the 31 s SITL log: the pipeline, not the timing
    out = capsys.readouterr().out
    assert "s wall" in out and "target < 10 s" in out and "peak memory" in out


def test_parquet_table_has_nulls_where_not_estimated(tmp_path: Path) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    from fawtgym.flightlog.outputs import write_table

    r = observe(TLOG, ["ffts_eso"], "s500")
    path = write_table(r, tmp_path, "parquet")
    table = pq.read_table(path)
    assert table.num_rows == r.t.size
    assert table.column("ffts_eso_force_n_N").null_count == int((~r.estimated).sum()) > 0


def test_bad_tlogs_are_one_line_errors(tmp_path: Path) -> None:
    junk = tmp_path / "junk.tlog"
    junk.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(FlightLogError) as exc:
        read_log(junk)
    assert "no MAVLink messages from an autopilot" in _one_line(exc)
    cut = tmp_path / "cut.tlog"
    cut.write_bytes(TLOG.read_bytes()[:20])  # inside the first record
    with pytest.raises(FlightLogError) as exc:
        read_log(cut)
    _one_line(exc)
    half = tmp_path / "half.tlog"
    half.write_bytes(TLOG.read_bytes()[: TLOG.stat().st_size // 2])  # cut mid-flight: read up to the cut
    assert 3.0 < read_log(half).duration < 6.0


def test_channels_an_observer_does_not_estimate_are_empty_not_zero() -> None:
    from fawtgym.flightlog.outputs import summary

    r = observe(SITL, ["hc_eso"], JMAVSIM)  # torque only (Wang & Sanyal 2022)
    force, torque = r.estimates["hc_eso"]
    assert np.all(np.isnan(force)) and np.all(np.isfinite(torque[r.estimated]))
    hover = summary(r)["hc_eso"]["hover"]
    assert "force_mean_N" not in hover and len(hover["torque_mean_Nm"]) == 3
    with pytest.raises(FlightLogError) as exc:
        observe(SITL, ["pdt_sta"], JMAVSIM)  # attitude and rates only
    assert "estimates no disturbance" in _one_line(exc) and "ffts_eso" in str(exc.value)


def test_trim_keeps_a_readable_log_and_exact_block_means(tmp_path: Path) -> None:
    """The test-data trimmer: a thinned ULog still reads with every topic observe needs, under the rate asked;
    the truth's block means and contact fraction are those of the rows (a hand-made 10-row truth.csv)."""
    from fawtgym.eval.sitl.bridge import TRUTH_WRENCH_COLUMNS
    from fawtgym.flightlog.trim import trim_truth, trim_ulog

    kept = trim_ulog(IRIS_ULOG, tmp_path / "small.ulg", max_rate=30.0)
    log = read_log(tmp_path / "small.ulg")
    for name, n in kept.items():
        t = log.topics[name].t
        assert len(t) == n and (n < 2 or (n - 1) / (t[-1] - t[0]) < 30.0 * 1.05), name
    head = ["t", "wind_n", "wind_e", "wind_d", *TRUTH_WRENCH_COLUMNS]
    rows = np.zeros((10, len(head)))
    rows[:, 0] = 0.004 * np.arange(1, 11)
    rows[:, head.index("fa_n")] = np.arange(10.0)
    rows[:3, head.index("fg_d")] = -15.0  # on the ground for the first 3 steps
    np.savetxt(tmp_path / "truth.csv", rows, delimiter=",", header=",".join(head), comments="")
    assert trim_truth(tmp_path / "truth.csv", tmp_path / "small.csv", block=5) == 2
    out = np.loadtxt(tmp_path / "small.csv", delimiter=",", skiprows=1)
    assert out[:, 0] == pytest.approx([0.02, 0.04])
    assert out[:, 4] == pytest.approx([2.0, 7.0]) and out[:, 6] == pytest.approx([-9.0, 0.0])
    assert out[:, 10] == pytest.approx([0.6, 0.0])
