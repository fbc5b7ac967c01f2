"""Write a test ``.tlog`` from our own env: a short PX4-style hover in FAWT wind, with the truth beside it.

This stands in for a tlog written by the MAVLink replay hook (SITL) until that exists; then the test
data should be swapped for a tlog the replay writes (same messages, a real autopilot's timing).

The flight: ``ground_seconds`` on the ground first (HEARTBEAT disarmed, EXTENDED_SYS_STATE on ground,
the vehicle at rest at the set point with outputs at 900 us -- written by this module, not flown), then
:class:`~fawtgym.envs.hover_env.HoverEnv` (s500, FAWT wind switched on at ``wind_on`` s, seed-000 sensors)
flown by :class:`~fawtgym.agents.px4_agent.PX4Agent`, logged at ``log_rate`` Hz: ATTITUDE_QUATERNION,
LOCAL_POSITION_NED, HIGHRES_IMU (the env's measurement), SERVO_OUTPUT_RAW (motor commands as PWM
1000 + 1000 c), HEARTBEAT (armed, PX4 Position mode) and EXTENDED_SYS_STATE (in air) at 2 Hz.  The
truth CSV holds the env's disturbance force (world NED) and torque (body FRD) at every logged time.
"""

from __future__ import annotations

import argparse
import struct
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fawtgym.core.constants import GRAVITY
from fawtgym.core.frames import rot_to_quat

BOOT_UNIX = 1.7e9  #: UNIX time of the simulated boot [s] (the tlog's receive stamps)


def write_test_tlog(path: str | Path, truth_csv: str | Path, *, seconds: float = 8.0, ground_seconds: float = 1.0,
                    wind_on: float = 2.0, log_rate: float = 50.0, seed: int = 0) -> None:
    """Fly the env and write the ``.tlog`` and its truth CSV (see the module docstring)."""
    from pymavlink.dialects.v20 import common as mavlink

    from fawtgym.agents.px4_agent import PX4Agent
    from fawtgym.envs.hover_env import HoverEnv

    env = HoverEnv("s500", wind={"name": "fawt-50", "on_time": wind_on}, sensors="seed000",
                   episode_seconds=seconds, init_noise=0.0)
    agent = PX4Agent.for_env(env)
    obs, info = env.reset(seed=seed)
    agent.reset(info)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    every = max(1, round(1.0 / (log_rate * env.dt)))
    out = Path(path).open("wb")
    truth_rows = []

    def send(t: float, msg: object) -> None:
        out.write(struct.pack(">Q", int((BOOT_UNIX + t) * 1e6)) + msg.pack(mav))  # type: ignore[attr-defined]

    def state(t: float, meas: dict, pwm: list[int], armed: bool, heartbeat: bool) -> None:
        ms, us = int(round(t * 1e3)), int(round(t * 1e6))
        if heartbeat:
            send(t, mav.heartbeat_encode(2, 12, 1 | (128 if armed else 0), 3 << 16, 4 if armed else 3))
            send(t, mav.extended_sys_state_encode(0, 2 if armed else 1))
        q = rot_to_quat(meas["attitude"])
        w = meas["angular_velocity"]
        send(t, mav.attitude_quaternion_encode(ms, *q.tolist(), *w.tolist()))
        send(t, mav.local_position_ned_encode(ms, *meas["position"].tolist(), *meas["velocity"].tolist()))
        sf, g, m = meas["specific_force"], meas["gyro"], meas["magnetometer"]
        send(t, mav.highres_imu_encode(us, *sf.tolist(), *g.tolist(), *m.tolist(), 1013.0, 0.0, 0.0, 20.0, 0x1FF))
        send(t, mav.servo_output_raw_encode(us % 2**32, 0, *pwm, 0, 0, 0, 0))

    rest = dict(info["measurement"])
    rest.update(velocity=np.zeros(3), angular_velocity=np.zeros(3), gyro=np.zeros(3), attitude=np.eye(3),
                specific_force=np.array([0.0, 0.0, -GRAVITY]))
    n_ground = int(round(ground_seconds * log_rate))
    for k in range(n_ground):
        state(k / log_rate, rest, [900] * 4, False, k % int(log_rate / 2) == 0)
    step = 0
    while True:
        action = agent.act(obs, info)
        obs, _, term, trunc, info = env.step(action)
        step += 1
        if step % every == 0:
            t = ground_seconds + info["time"]
            pwm = [int(round(1000 + 1000 * float(c))) for c in np.clip(action, 0, 1)]
            state(t, info["measurement"], pwm, True, (step // every) % int(log_rate / 2) == 1)  # 1st: armed
            truth_rows.append([t, *info["truth"]["force"].tolist(), *info["truth"]["torque"].tolist()])
        if term or trunc:
            break
    out.close()
    np.savetxt(truth_csv, np.array(truth_rows), delimiter=",", fmt="%.6g",
               header="time_s,force_n_N,force_e_N,force_d_N,torque_x_Nm,torque_y_Nm,torque_z_Nm", comments="")


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("tlog")
    p.add_argument("truth_csv")
    p.add_argument("--seconds", type=float, default=8.0)
    args = p.parse_args(list(sys.argv[1:] if argv is None else argv))
    write_test_tlog(args.tlog, args.truth_csv, seconds=args.seconds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
