"""fawtgym replay flies trained policies (``sb3:RUN``) through a PX4-like autopilot peer on loopback UDP.

A ctbr and a residual (on ``px4+ffts_eso``) policy, each trained a few hundred steps in a tmp folder, stream
SET_ATTITUDE_TARGET at >= 50 Hz with finite values; the observation the replay builds from MAVLink telemetry
equals the env's observation of the same state; a run trained for another vehicle is refused in one line.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")
pytest.importorskip("stable_baselines3")

from _sitl_peers import AutopilotPeer, running_peer
from _tolerance import EPS, assert_same_law
from test_sitl_replay import ORIGIN, free_udp_port

from fawtgym.core.frames import rot_to_quat
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.eval.sitl import convert as C
from fawtgym.eval.sitl.replay import Replay
from fawtgym.train.cli import make_config
from fawtgym.train.config import load_hyperparams
from fawtgym.train.run import train

TINY = {"n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 1}
HOVER_POINT = [1.5, 0.0, -0.25]
#: MAVLink telemetry fields are float32: the replay's inputs carry a relative rounding of eps32 = 2^29 eps
#: (eps: the policy's float64 epsilon), which the observation law passes on unamplified (differences, copies
#: and the quaternion -> rotation map of a unit quaternion), so cond = eps32 / eps
FLOAT32_TRANSPORT = float(np.finfo(np.float32).eps) / EPS
LOG: list[str] = []


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two tiny runs of the table4-50 scenario (vehicle s500): ctbr on the state, residual on the state."""
    root = tmp_path_factory.mktemp("policies")
    out = {}
    for action in ("ctbr", "residual"):
        cfg = make_config(hyperparams=load_hyperparams("ppo", TINY), algo="ppo", steps=128, obs="state",
                          action=action, episode_seconds=0.5, eval_scenarios=())
        train(cfg, root / action, checkpoint_every=128, progress=False)
        out[action] = root / action
    return out


def fly(agent: str, port: int, **kw) -> tuple[dict, AutopilotPeer]:
    # telemetry_timeout 2 s (the default 0.5 s): the peer is a thread of this process; on a loaded 2-core CI a
    # scheduling or GC stall of over a second, not the link, can starve it (tests/test_sitl_replay.py)
    replay = Replay(f"udp:127.0.0.1:{port}", agent, vehicle="s500", hover_point=HOVER_POINT, origin=ORIGIN,
                    rate=100.0, duration=0.8, prestream=1.1, climb_speed=1.0, settle=0.1, connect_timeout=3.0,
                    command_timeout=3.0, land_timeout=5.0, log=LOG.append, **{"telemetry_timeout": 2.0, **kw})
    with running_peer(port) as peer:
        summary = replay.run()
    return summary, peer


@pytest.mark.parametrize("action, type_mask", [("ctbr", 128), ("residual", 7)])
def test_policy_streams_setpoints_through_the_autopilot(runs, action, type_mask):
    LOG.clear()
    summary, peer = fly(f"sb3:{runs[action]}", free_udp_port())
    assert "note: the policy was trained at 200 Hz and flies at 100 Hz (--rate)" in LOG
    arm = [t for t, name, p in peer.events if name == "cmd400" and p[0] == 1]
    land = [t for t, name, _ in peer.events if name == "cmd21"]
    assert arm and land and not peer.armed
    flying = [(t, sp) for t, sp in peer.setpoints if arm[0] <= t <= land[0]]
    times = [t for t, _ in flying]
    assert (len(times) - 1) / (times[-1] - times[0]) >= 50.0 and summary["setpoint_rate_hz"] >= 50.0
    assert np.diff(times).max() < 0.5  # PX4 leaves OFFBOARD after COM_OF_LOSS_T (1 s by default) without set points
    for _, sp in flying:
        values = [*sp.q, sp.body_roll_rate, sp.body_pitch_rate, sp.body_yaw_rate, sp.thrust]
        assert np.all(np.isfinite(values)) and 0.0 <= sp.thrust <= 1.0
        assert np.linalg.norm(sp.q) == pytest.approx(1.0, abs=1e-6)
    # the policy's own set points once the armed heartbeat is in (before: the neutral stream): ctbr sends body
    # rates (attitude ignored, type_mask 128), the residual policy its PX4 base's attitude (rates ignored, 7); the
    # peer, like PX4, heartbeats at 1 Hz, so when the policy takes over depends on the phase of that heartbeat
    first = next(i for i, (_, sp) in enumerate(flying) if sp.type_mask == type_mask)
    flying = flying[first:]
    assert {sp.type_mask for _, sp in flying} == {type_mask}
    assert np.ptp([sp.thrust for _, sp in flying]) > 0.0, "the policy's thrust must vary with the telemetry"


def _telemetry(meas: dict, origin: np.ndarray, mav) -> tuple:
    """MAVLink ATTITUDE_QUATERNION, LOCAL_POSITION_NED and HIGHRES_IMU of an env measurement, packed and parsed
    back (float32 fields, as on the wire)."""
    from pymavlink.dialects.v20 import common as mavlink

    q = rot_to_quat(meas["attitude"])
    w, p, v = meas["angular_velocity"], meas["position"] - origin, meas["velocity"]
    f, g = meas["specific_force"], meas["gyro"]
    msgs = [mavlink.MAVLink_attitude_quaternion_message(10, *q, *w),
            mavlink.MAVLink_local_position_ned_message(10, *p, *v),
            mavlink.MAVLink_highres_imu_message(10000, *f, *g, 0.2, 0.0, 0.4, 1000.0, 0.0, 0.0, 20.0, 0x1FFF)]
    return tuple(mav.parse_buffer(m.pack(mav))[0] for m in msgs)


def test_observation_from_telemetry_is_the_envs(runs):
    from pymavlink.dialects.v20 import common as mavlink

    os.environ.setdefault("MAVLINK20", "1")
    replay = Replay("udp:127.0.0.1:1", f"sb3:{runs['ctbr']}", vehicle="s500", hover_point=HOVER_POINT,
                    origin=ORIGIN)
    env = HoverEnv(vehicle="s500", action_type="ctbr", control_rate=100.0, setpoint=HOVER_POINT,
                   sensors="mocap_imu", init_noise=0.5)
    obs, info = env.reset(seed=3)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    origin = np.asarray(ORIGIN, dtype=float)
    action = np.array([0.55, 0.3, -0.2, 0.1])
    for k in range(6):
        last = action if k else env.hover_action()  # before the first step: the hover action, as at reset
        meas = C.measurement_from_telemetry(*_telemetry(info["measurement"], origin, mav), origin, 0.0)
        mine = replay.observation(meas, HOVER_POINT, last)
        assert mine.dtype == np.float32 and mine.shape == (19,)
        assert_same_law(mine, obs, cond=FLOAT32_TRANSPORT, what=f"observation from telemetry, step {k}")
        assert np.abs(obs[0:3]).max() > 0.01 and np.abs(obs[[7, 8, 9, 11]]).max() > 1e-3  # off the set point, tilted
        action = np.array([0.55, 0.3, -0.2, 1.7 if k == 2 else 0.1])  # 1.7: clipped to 1 by both
        obs, _, term, trunc, info = env.step(action)
        assert not (term or trunc)
    env.close()


def test_policy_for_another_vehicle_is_refused(runs, capsys):
    from fawtgym.cli import main

    with pytest.raises(ValueError, match=r"trained for vehicle 's500'; this replay flies 'iris' "
                                         r"\(--vehicle s500 ") as info:
        Replay("udp:127.0.0.1:1", f"sb3:{runs['ctbr']}", hover_point=HOVER_POINT, origin=ORIGIN)
    assert "\n" not in str(info.value)
    with pytest.raises(SystemExit) as exc:
        main(["replay", "--agent", f"sb3:{runs['ctbr']}", "--vehicle", "x500"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and "trained for vehicle 's500'" in err, err
    with pytest.raises(SystemExit) as exc:
        main(["replay", "--agent", "px4", "--vehicle", "zeppelin"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and "unknown vehicle 'zeppelin'" in err, err
