"""fawtgym replay against a PX4-like autopilot peer on loopback UDP (tests/_sitl_peers.py, pymavlink only).

Checks the OFFBOARD sequence (setpoints streamed > 1 s before the mode switch, mode before arming, LAND at the
end, disarmed), the SET_ATTITUDE_TARGET rate (>= 50 Hz) and fields, the abort on heartbeat loss and on
telemetry loss (stream stops, LAND commanded, one-line reason, within the timeout), malformed bytes, the CLI's
one-line errors, and the .tlog read back by pymavlink's mavlogdump.py.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from collections import Counter

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from _sitl_peers import running_peer

from fawtgym.eval.sitl.mavio import SitlError
from fawtgym.eval.sitl.replay import HEARTBEAT_PERIOD, Replay, resolve_agent

ORIGIN = [1.5, 0.0, -0.03]


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def make_replay(port: int, tlog=None, **kw) -> Replay:
    # telemetry_timeout 2 s instead of the 0.5 s default: the peer is a thread of this process, and on a loaded
    # 2-core CI one stall of 1.36 s (scheduling or a GC pass, not the link) once aborted a healthy replay
    opts = dict(hover_point=[1.5, 0.0, -0.25], origin=ORIGIN, rate=100.0, duration=1.0, prestream=1.1,
                climb_speed=1.0, settle=0.2, connect_timeout=3.0, command_timeout=3.0, land_timeout=5.0, tlog=tlog,
                telemetry_timeout=2.0)
    opts.update(kw)
    return Replay(f"udp:127.0.0.1:{port}", "px4+leso", **opts)


def test_offboard_sequence_rate_land_and_tlog(tmp_path):
    port = free_udp_port()
    tlog = tmp_path / "replay.tlog"
    replay = make_replay(port, tlog)
    with running_peer(port) as peer:
        summary = replay.run()
    cmds = [(t, name, p) for t, name, p in peer.events]
    first_sp = peer.setpoints[0][0]
    mode = [t for t, name, p in cmds if name == "cmd176"]
    arm = [t for t, name, p in cmds if name == "cmd400" and p[0] == 1]
    land = [t for t, name, p in cmds if name == "cmd21"]
    assert mode and arm and land
    assert mode[0] - first_sp >= 1.0, "OFFBOARD must be requested after more than 1 s of setpoints"
    assert arm[0] > mode[0] and land[0] > arm[0]
    assert not peer.armed, "the autopilot must be disarmed at the end"
    flying = [t for t, _ in peer.setpoints if arm[0] <= t <= land[0]]
    rate = (len(flying) - 1) / (flying[-1] - flying[0])
    assert rate >= 50.0, f"setpoint rate {rate:.1f} Hz"
    assert np.diff(flying).max() < 0.2
    assert not [t for t, _ in peer.setpoints if t > land[0] + 0.05], "streaming must stop at LAND"
    for _, sp in peer.setpoints:
        assert sp.type_mask == 7  # attitude + thrust (body rates ignored) for the PX4 cascade
        assert 0.0 <= sp.thrust <= 1.0
        assert np.linalg.norm(sp.q) == pytest.approx(1.0, abs=1e-6)
        assert (sp.target_system, sp.target_component) == (1, 1)
    hover = [sp.thrust for t, sp in peer.setpoints if arm[0] + 0.5 <= t <= land[0]]
    assert 0.3 < np.median(hover) < 0.95  # the agent is flying (the peer's vehicle never moves, so it climbs)
    assert summary["setpoints"] == len(peer.setpoints)
    assert summary["setpoint_rate_hz"] >= 50.0

    tool = shutil.which("mavlogdump.py") or os.path.join(os.path.dirname(sys.executable), "mavlogdump.py")
    env = {**os.environ, "MAVLINK20": "1", "MAVLINK_DIALECT": "common"}
    res = subprocess.run([sys.executable, tool, str(tlog)], capture_output=True, text=True, timeout=60, env=env)
    assert res.returncode == 0, res.stderr
    counts = Counter(line.split()[2] for line in res.stdout.splitlines() if len(line.split()) > 2)
    assert counts["SET_ATTITUDE_TARGET"] == len(peer.setpoints)
    assert counts["COMMAND_LONG"] >= 6 and counts["COMMAND_ACK"] >= 3  # intervals, mode, arm, land
    assert counts["HEARTBEAT"] >= 4 and counts["ATTITUDE_QUATERNION"] >= 200  # 1 Hz heartbeats, as PX4


def test_ardupilot_guided_nogps():
    port = free_udp_port()
    replay = make_replay(port, duration=0.5)
    with running_peer(port, ardupilot=True) as peer:
        replay.run()
    modes = [p for _, name, p in peer.events if name == "cmd176"]
    assert modes and all(p == (1.0, 20.0) for p in modes)  # custom mode GUIDED_NOGPS
    assert not peer.armed and [name for _, name, _ in peer.events].count("cmd21") >= 1


@pytest.mark.parametrize("loss, reason", [("heartbeat", "heartbeat lost"), ("telemetry", "telemetry timeout")])
def test_abort_on_link_loss(loss, reason):
    port = free_udp_port()
    replay = make_replay(port, duration=20.0)
    stop_after = 1.5 if loss == "heartbeat" else 0.3  # 1 Hz heartbeats: the replay sees "armed" within 1 s
    with running_peer(port, **{f"stop_{loss}_after_arm": stop_after}) as peer:
        t0 = time.monotonic()
        with pytest.raises(SitlError, match=reason) as info:
            replay.run()
    assert time.monotonic() - t0 < 10.0
    assert "\n" not in str(info.value) and "LAND commanded" in str(info.value)
    land = [t for t, name, _ in peer.events if name == "cmd21"]
    assert land, "an abort in the air must command LAND"
    assert not [t for t, _ in peer.setpoints if t > land[0] + 0.05], "streaming must stop on abort"
    lost_at = peer.arm_time + stop_after
    limit = HEARTBEAT_PERIOD + replay.heartbeat_timeout if loss == "heartbeat" else replay.telemetry_timeout
    assert land[0] - lost_at < limit + 1.0  # + heartbeat period, a tick and scheduling slack


def test_px4s_1hz_heartbeat_is_not_a_loss():
    """Found by the hand test against PX4 v1.14.0: PX4 sends HEARTBEAT at a fixed 1 Hz (gaps of 1.000-1.011 s
    seen) and refuses SET_MESSAGE_INTERVAL for it, so a bare 1 s limit aborted a healthy hover.  Against the
    peer's 1 Hz heartbeats a 4 s hover (several heartbeat periods) must fly to the end with the default 1 s."""
    port = free_udp_port()
    replay = make_replay(port, duration=4.0)
    assert replay.heartbeat_timeout == 1.0
    with running_peer(port) as peer:
        summary = replay.run()
    assert summary["final_position_error"] is not None, "the hover must end normally"
    assert not peer.armed and [name for _, name, _ in peer.events].count("cmd21") >= 1


def test_malformed_bytes_and_silence_give_clear_errors():
    port = free_udp_port()
    with running_peer(port, garbage_only=True):
        t0 = time.monotonic()
        with pytest.raises(SitlError, match=r"no heartbeat from an autopilot on udp:127\.0\.0\.1:\d+ within 1 s "
                                            r"\(\d+ bytes received were not valid MAVLink\)"):
            make_replay(port, connect_timeout=1.0).run()
    assert time.monotonic() - t0 < 4.0
    with pytest.raises(SitlError, match="nothing was armed"):
        make_replay(free_udp_port(), connect_timeout=0.3).run()


def test_bad_arguments():
    with pytest.raises(ValueError, match=r"rate \(--rate\) must be a finite real number in \[50, 100000\] Hz"):
        make_replay(free_udp_port(), rate=20.0)
    with pytest.raises(ValueError, match=r"prestream must be a finite real number in \(1, 1e\+09\] s"):
        make_replay(free_udp_port(), prestream=0.5)
    with pytest.raises(ValueError, match="--agent best needs --results"):
        resolve_agent("best")
    with pytest.raises(ValueError, match="unknown agent"):
        Replay("udp:127.0.0.1:1", "nope")


def test_cli_errors_are_one_line(capsys):
    from fawtgym.cli import main

    for argv, text in ((["replay", "--agent", "px4", "--rate", "10"], "rate (--rate) must be a finite real number"),
                       (["replay", "--agent", "best"], "--results"),
                       (["sitl", "px4", "--wind", "gale"], "unknown --wind 'gale'"),
                       (["sitl", "px4", "--start", "1,2"], "--start must be three numbers")):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        err = capsys.readouterr().err
        assert exc.value.code == 2, argv
        assert err.count("\n") == 1 and text in err, err


def test_thrust_sent_is_the_cascade_set_point_even_when_its_own_rate_loop_saturates():
    """Found by the hand test against PX4 v1.14.0: the replay derived the thrust from the cascade's motor commands;
    the observer's torque estimate (PX4 flies the rates, so our rate loop's torque never acts) saturated our
    allocator, which cut the collective: the thrust sent stayed at 0.68 while the vehicle sank 1.3 m and the
    cascade's set point asked for full thrust.  The thrust sent must be the cascade's collective set point, and it
    is the observer's known thrust input of the next tick.  Driven through ``Replay.command``, the step the flight
    loop runs on every telemetry tick."""
    from fawtgym.eval.sitl import convert as C

    replay = Replay("udp:127.0.0.1:9", "px4+ffts_eso", hover_point=[1.5, 0.0, -1.5], origin=ORIGIN)
    hover_collective = replay.preset.mass * 9.80665
    hover = C.px4_thrust(replay.preset, hover_collective)
    replay.begin_flight()
    known = replay.known_inputs
    assert known["thrust"] == hover_collective and np.array_equal(known["torque"], np.zeros(3))
    sent = []
    for k in range(100):  # 1 s at 100 Hz: 1 m below the set point, sinking, spinning hard in roll
        meas = {"position": np.array([1.5, 0.0, -0.5 + 0.008 * k]), "velocity": np.array([0.0, 0.0, 0.8]),
                "attitude": np.eye(3), "angular_velocity": np.array([4.0, 0.0, 0.0]),
                "specific_force": np.array([0.0, 0.0, -9.0]), "gyro": np.array([4.0, 0.0, 0.0]),
                "magnetometer": np.array([0.21, 0.01, 0.43]), "time": np.asarray(0.01 * k)}
        cmd = replay.command(meas, replay.hover_point)
        assert cmd.body_rates is None and cmd.attitude is not None and cmd.attitude.shape == (3, 3)
        collective = float(replay.agent.collective_thrust[0])
        assert cmd.thrust == pytest.approx(C.px4_thrust(replay.preset, collective), abs=1e-12)
        assert replay.known_inputs["thrust"] == pytest.approx(collective)  # the observer's known thrust input
        sent.append(cmd.thrust)
    assert np.mean(sent[50:]) > hover + 0.1, f"sinking 1 m low: thrust {np.mean(sent[50:]):.3f}, hover {hover:.3f}"
