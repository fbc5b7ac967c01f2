"""The PX4 bridge (fawtgym sitl px4) against a PX4-side peer on a loopback TCP socket (tests/_sitl_peers.py).

The peer is written from the MAVLink spec and PX4's documented simulator interface, not from the bridge: it
checks units and frames (specific force -g on body z at rest, gyro 0), HIL_SENSOR field bits, lockstep (no new
sample before its actuator message), strictly increasing time, HIL_GPS fields; open-loop hover holds altitude
over 10 s of lockstep; PX4's motor numbering moves the vehicle the way PX4's airframe geometry says; malformed
bytes and a disconnect stop the bridge with a clear error within its timeout.  Every wait has a timeout.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import threading
from collections import Counter

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from _sitl_peers import NONE_IRIS_CA, G, Px4SimPeer, iris_hover_control

from fawtgym.eval.sitl.bridge import Px4Bridge
from fawtgym.eval.sitl.mavio import SitlError
from fawtgym.eval.sitl.plant import SitlVehicle

HOME_LAT, HOME_LON, HOME_ALT = 47.397742, 8.545594, 488.0  # PX4's default SITL home


def start(bridge: Px4Bridge, duration: float | None):
    out: dict = {}

    def target() -> None:
        try:
            out["summary"] = bridge.serve(duration)
        except Exception as exc:  # handed to the test
            out["error"] = exc

    th = threading.Thread(target=target, daemon=True)
    th.start()
    return th, out


def finish(th: threading.Thread, out: dict, timeout: float = 20.0) -> dict:
    th.join(timeout)
    assert not th.is_alive(), "the bridge did not return within its timeout"
    return out


def isa_pressure_hpa(h: float) -> float:
    """ISA troposphere, the textbook form (not the bridge's)."""
    return 1013.25 * (1.0 - 2.25577e-5 * h) ** 5.25588


def test_units_frames_bits_lockstep_time_gps():
    vehicle = SitlVehicle(sensors="none", seed=1)  # exact sensors: the numbers below are physics, not noise
    bridge = Px4Bridge(vehicle, port=0, accept_timeout=10, actuator_timeout=5, boot_wait=2.0, baro_noise=0.0)
    th, out = start(bridge, duration=1.2)
    peer = Px4SimPeer(bridge.port)
    peer.hello(interval_us=5000)
    times, sensors = [], []
    try:
        for k in range(300):
            s = peer.next_sensor()
            times.append(s.time_usec)
            sensors.append(s)
            if 150 <= k < 153:  # lockstep: while we hold the answer, no new sample may come
                late = peer.quiet_for(0.05)
                assert not [m for m in late if m.get_type() == "HIL_SENSOR"], f"sample {k}: sensor before actuator"
            peer.answer(s)  # disarmed: motors off
    finally:
        result = finish(th, out)
        peer.close()
    assert "error" not in result, result.get("error")
    assert bridge.lockstep
    assert np.all(np.diff(times) == 4000), "time_usec must advance by exactly one 250 Hz period"
    assert times[0] > 0
    rest = sensors[150:]  # settled on the ground
    for s in rest:
        assert s.fields_updated & 0x7 == 0x7 and s.fields_updated & 0x38 == 0x38
        assert s.fields_updated & 0x1C0 == 0x1C0 and s.fields_updated & 0x1A00 == 0x1A00
        assert not s.fields_updated & 0x400  # no airspeed sensor on a quad
        assert s.zacc == pytest.approx(-G, abs=0.02) and abs(s.xacc) < 0.02 and abs(s.yacc) < 0.02
        assert max(abs(s.xgyro), abs(s.ygyro), abs(s.zgyro)) < 1e-3
        mag = np.array([s.xmag, s.ymag, s.zmag])
        assert np.linalg.norm(mag) == pytest.approx(0.483, abs=0.005)  # gauss, WMM at Zurich
        assert math.degrees(math.atan2(mag[2], math.hypot(mag[0], mag[1]))) == pytest.approx(63.7, abs=0.5)
        assert math.degrees(math.atan2(mag[1], mag[0])) == pytest.approx(3.0, abs=0.5)  # level, heading north
        assert s.pressure_alt == pytest.approx(HOME_ALT + 0.03, abs=0.05)  # CoM 3 cm above the ground
        assert s.abs_pressure == pytest.approx(isa_pressure_hpa(s.pressure_alt), abs=0.02)
        assert s.temperature == pytest.approx(15.0 - 6.5e-3 * s.pressure_alt, abs=0.01)
    gps = [m for m in peer.seen if m.get_type() == "HIL_GPS"]
    assert 10 <= len(gps) <= 13  # 10 Hz over 1.2 s
    assert np.all(np.diff([g.time_usec for g in gps]) == 100000)
    assert set(g.time_usec for g in gps) <= set(times) | {times[-1] + 4000}
    north = 1.5 / 6371000.0  # the vehicle stands 1.5 m north of home
    for g in gps:
        assert g.fix_type == 3 and g.satellites_visible >= 10
        assert g.lat == pytest.approx((HOME_LAT + math.degrees(north)) * 1e7, abs=2)
        assert g.lon == pytest.approx(HOME_LON * 1e7, abs=2)
        assert g.alt == pytest.approx((HOME_ALT + 0.03) * 1000, abs=20)  # mm
        assert 0 < g.eph <= 500 and 0 < g.epv <= 500  # cm
        assert g.vn == 0 and g.ve == 0 and abs(g.vd) <= 1  # cm/s
    acks = [m for m in peer.seen if m.get_type() == "COMMAND_ACK"]
    assert acks and acks[0].command == 511 and acks[0].result == 0
    truth = [m for m in peer.seen if m.get_type() == "HIL_STATE_QUATERNION"]
    assert len(truth) > 100
    assert np.all(np.diff([m.time_usec for m in truth]) >= 5000)
    assert truth[-1].attitude_quaternion[0] == pytest.approx(1.0, abs=1e-6)


def test_barometer_is_noisy_by_default_so_px4_does_not_flag_it_stale():
    """Found by the hand test against PX4 v1.14.0: an exact (constant) pressure at rest made PX4's sensor
    validator report "BARO #0 failed: STALE!" (more than 100 equal values in a row) and EKF2 fly on GPS height.
    By default the bridge adds Gazebo-classic's 1 Pa RMS white noise to the pressure."""
    vehicle = SitlVehicle(sensors="none", seed=3)
    bridge = Px4Bridge(vehicle, port=0, accept_timeout=10, actuator_timeout=5, boot_wait=2.0)
    th, out = start(bridge, duration=1.2)
    peer = Px4SimPeer(bridge.port)
    peer.hello()
    sensors = []
    try:
        for _ in range(300):
            s = peer.next_sensor()
            sensors.append(s)
            peer.answer(s)
    finally:
        result = finish(th, out)
        peer.close()
    assert "error" not in result, result.get("error")
    rest = sensors[150:]  # on the ground: the true altitude is constant
    pa = np.array([s.abs_pressure for s in rest]) * 100.0  # hPa -> Pa
    alt = np.array([s.pressure_alt for s in rest])
    longest, run = 1, 1
    for a, b in zip(pa[:-1], pa[1:], strict=True):
        run = run + 1 if abs(a - b) < 1e-6 else 1
        longest = max(longest, run)
    assert longest < 100, f"{longest} equal pressures in a row: PX4 flags the barometer STALE after 100"
    assert 0.7 < pa.std() < 1.3, f"pressure noise {pa.std():.2f} Pa RMS, expected 1 Pa"
    truth = isa_pressure_hpa(HOME_ALT + 0.03) * 100.0
    assert abs(pa.mean() - truth) < 4 * 1.0 / math.sqrt(pa.size) + 0.5, "noise must be zero-mean around ISA"
    # pressure_alt is the ISA altitude of the noisy pressure: dh/dp = -1/(rho g) ~ -0.09 m/Pa near 500 m
    slope = np.polyfit(pa, alt, 1)[0]
    assert slope == pytest.approx(-0.09, rel=0.1)


def test_hover_holds_altitude_10s_and_px4_motor_order():
    vehicle = SitlVehicle(sensors="none", start=[0.0, 0.0, -10.0])
    bridge = Px4Bridge(vehicle, port=0, accept_timeout=10, actuator_timeout=5, boot_wait=2.0, baro_noise=0.0)
    th, out = start(bridge, duration=2560 * 0.004)  # the 2560 samples answered below
    peer = Px4SimPeer(bridge.port)
    peer.hello()
    u = iris_hover_control()
    try:
        first = peer.next_sensor()
        peer.answer(first, [u] * 4, armed=True)
        s = first
        for _ in range(2499):  # 10 s of lockstep at 250 Hz
            s = peer.next_sensor()
            peer.answer(s, [u] * 4, armed=True)
        assert (s.time_usec - first.time_usec) == 2499 * 4000
        assert s.pressure_alt == pytest.approx(first.pressure_alt, abs=0.02), "open-loop hover must hold altitude"
        assert s.zacc == pytest.approx(-G, abs=0.01)
        # PX4's motor numbering: from the none_iris CA table, rotors at +y (right) speeding up roll the vehicle
        # left (negative roll rate), CCW rotors (KM > 0) speeding up yaw it clockwise seen from above (+z FRD)
        du = 0.05
        roll_cmd = [u + (du if py > 0 else -du) for _, py, _ in NONE_IRIS_CA]
        yaw_cmd = [u + du * km for _, _, km in NONE_IRIS_CA]
        axes = ("xgyro", "ygyro", "zgyro")
        for cmd, axis, sign in ((roll_cmd, 0, -1.0), (yaw_cmd, 2, 1.0)):
            before = np.array([getattr(s, a) for a in axes])
            for _ in range(25):
                s = peer.next_sensor()
                peer.answer(s, cmd, armed=True)
            delta = np.array([getattr(s, a) for a in axes]) - before
            assert sign * delta[axis] > 0.05, f"{axes[axis]} changed by {delta[axis]} in 0.1 s of PX4 command {cmd}"
            if axis == 0:  # from a steady hover, the roll command moves roll alone (the asymmetric Iris's yaw
                # command also rolls it: its CCW rotors sit at y = +0.245 and -0.1875)
                assert np.abs(np.delete(delta, axis)).max() < 0.1 * abs(delta[axis]), delta
            for _ in range(5):
                s = peer.next_sensor()
                peer.answer(s, [u] * 4, armed=True)
    finally:
        result = finish(th, out)
        peer.close()
    assert "error" not in result, result.get("error")


def test_malformed_bytes_give_a_clear_error_before_lockstep():
    bridge = Px4Bridge(SitlVehicle(sensors="none"), port=0, accept_timeout=5, boot_timeout=1.0)
    th, out = start(bridge, None)
    peer = Px4SimPeer(bridge.port)
    try:
        peer.sock.sendall(bytes([0xFD, 9, 0, 0, 1, 1, 1, 0, 0, 0] + [7] * 11) * 20 + bytes(range(200)))
        result = finish(th, out, timeout=10)
    finally:
        peer.close()
    err = result.get("error")
    assert isinstance(err, SitlError), result
    assert "no HIL_ACTUATOR_CONTROLS within 1 s" in str(err) and "not valid MAVLink" in str(err)


def test_malformed_bytes_in_lockstep_and_disconnect():
    bridge = Px4Bridge(SitlVehicle(sensors="none"), port=0, accept_timeout=5, actuator_timeout=0.5, boot_wait=2.0)
    th, out = start(bridge, None)
    peer = Px4SimPeer(bridge.port)
    try:
        for _ in range(10):
            peer.answer(peer.next_sensor())
        peer.next_sensor()
        peer.sock.sendall(b"\xfe\x05garbage-not-mavlink" * 10)
        result = finish(th, out, timeout=10)
    finally:
        peer.close()
    err = result.get("error")
    assert isinstance(err, SitlError), result
    assert "no HIL_ACTUATOR_CONTROLS from PX4 within 0.5 s" in str(err) and "not valid MAVLink" in str(err)

    bridge = Px4Bridge(SitlVehicle(sensors="none"), port=0, accept_timeout=5, actuator_timeout=5, boot_wait=2.0)
    th, out = start(bridge, None)
    peer = Px4SimPeer(bridge.port)
    for _ in range(20):
        peer.answer(peer.next_sensor())
    peer.close()
    err = finish(th, out, timeout=10).get("error")
    # the peer closes with the bridge's 21st HIL_SENSOR possibly unread: TCP then resets instead of a clean FIN
    # (a race of the two processes' timing), so either report is right; both must name the step count
    assert isinstance(err, SitlError), err
    assert ("PX4 closed the connection after 20 steps" in str(err)
            or "the PX4 connection broke (Connection reset by peer) after 20 steps" in str(err)), err


def test_no_px4_times_out():
    bridge = Px4Bridge(SitlVehicle(sensors="none"), port=0, accept_timeout=0.3)
    with pytest.raises(SitlError, match=r"no PX4 connected to 127\.0\.0\.1:\d+ within 0\.3 s"):
        bridge.serve(1.0)


def test_bridge_tlog_read_by_mavlogdump(tmp_path):
    tlog = tmp_path / "bridge.tlog"
    bridge = Px4Bridge(SitlVehicle(sensors="none"), port=0, accept_timeout=5, boot_wait=2.0, tlog=tlog,
                       log_dir=tmp_path / "log")
    th, out = start(bridge, duration=0.2)
    peer = Px4SimPeer(bridge.port)
    peer.hello()
    try:
        for _ in range(50):
            peer.answer(peer.next_sensor())
    finally:
        finish(th, out)
        peer.close()
    tool = shutil.which("mavlogdump.py") or os.path.join(os.path.dirname(sys.executable), "mavlogdump.py")
    env = {**os.environ, "MAVLINK20": "1", "MAVLINK_DIALECT": "common"}
    res = subprocess.run([sys.executable, tool, str(tlog)], capture_output=True, text=True, timeout=60, env=env)
    assert res.returncode == 0, res.stderr
    counts = Counter(line.split()[2] for line in res.stdout.splitlines() if len(line.split()) > 2)
    counts = {k: counts[k] for k in ("HIL_SENSOR", "HIL_ACTUATOR_CONTROLS", "HIL_GPS")}
    assert counts == {"HIL_SENSOR": 50, "HIL_ACTUATOR_CONTROLS": 50, "HIL_GPS": 2}
    assert (tmp_path / "log" / "truth.csv").read_text().count("\n") == 51


def test_truth_log_carries_the_envs_wind_wrench_which_balances_the_ground_at_rest(tmp_path):
    """truth.csv's fa_*/ta_* columns are the env's aerodynamic wrench and fg_*/tg_* the ground's.  Standing
    disarmed in a 6 m/s mean wind, the vehicle is at rest, so (Newton) aero + ground + weight + idle thrust = 0
    and aero torque + ground torque = 0; the aero force must point downwind (north) with a size of a newton."""
    vehicle = SitlVehicle(wind={"name": "dryden-light", "mean_wind": 6.0}, sensors="none", seed=2)
    bridge = Px4Bridge(vehicle, port=0, accept_timeout=10, boot_wait=2.0, baro_noise=0.0, log_dir=tmp_path)
    th, out = start(bridge, duration=2.0)
    peer = Px4SimPeer(bridge.port)
    peer.hello()
    try:
        for _ in range(500):
            peer.answer(peer.next_sensor())  # disarmed: motors at idle
    finally:
        finish(th, out)
        peer.close()
    from fawtgym.eval.sitl.bridge import TRUTH_WRENCH_COLUMNS

    log = np.genfromtxt(tmp_path / "truth.csv", delimiter=",", names=True)
    assert list(log.dtype.names[-12:]) == list(TRUTH_WRENCH_COLUMNS) and log.size == 500
    cols = lambda *names, rows=slice(None): np.column_stack([log[n][rows] for n in names])
    rest = log["t"] > 1.0
    p = vehicle.preset
    idle_thrust = 4 * p.k_thrust * p.omega_min**2
    fa, fg = cols("fa_n", "fa_e", "fa_d", rows=rest), cols("fg_n", "fg_e", "fg_d", rows=rest)
    ta, tg = cols("ta_x", "ta_y", "ta_z", rows=rest), cols("tg_x", "tg_y", "tg_z", rows=rest)
    weight = p.mass * G
    balance = (fa + fg).mean(axis=0) + np.array([0.0, 0.0, weight - idle_thrust])
    assert np.all(np.abs(balance) < 0.01 * weight), balance
    assert np.all(np.abs((ta + tg).mean(axis=0)) < 1e-3), (ta + tg).mean(axis=0)
    assert 0.3 < fa[:, 0].mean() < 5.0 and abs(fa[:, 1].mean()) < 0.5 * fa[:, 0].mean(), fa.mean(axis=0)
    assert np.all(np.abs(cols("fg_d")) > 0), "the vehicle stands on the ground"
