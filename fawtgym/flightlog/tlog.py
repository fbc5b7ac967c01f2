"""Read a MAVLink telemetry log (``.tlog``: 8-byte big-endian UNIX-time microseconds + one MAVLink packet,
repeated) with pymavlink, and map its messages onto the PX4 topic names the rest of :mod:`fawtgym.flightlog` reads:

===================== =================================================================================
MAVLink message       PX4 topic.fields
===================== =================================================================================
ATTITUDE_QUATERNION   vehicle_attitude.q[0..3] (q1..q4 = w, x, y, z); vehicle_angular_velocity.xyz
LOCAL_POSITION_NED    vehicle_local_position.x, y, z, vx, vy, vz
HIGHRES_IMU           sensor_combined.accelerometer_m_s2, gyro_rad, magnetometer_ga
SERVO_OUTPUT_RAW      actuator_outputs.output[0..15] (PWM us)
ACTUATOR_OUTPUT_STATUS actuator_motors.control[0..3] (when its values lie in [0, 1])
HEARTBEAT             vehicle_status.arming_state (2 when MAV_MODE_FLAG_SAFETY_ARMED), nav_state (PX4 custom mode)
EXTENDED_SYS_STATE    vehicle_land_detected.landed (landed_state ON_GROUND)
PARAM_VALUE           parameters (MPC_THR_HOVER, THR_MDL_FAC, PWM_MAIN_MIN/MAX ...)
===================== =================================================================================

Times: a message's own boot time (``time_boot_ms`` / ``time_usec``, unwrapped where it is 32-bit) when it
has one; otherwise (HEARTBEAT, EXTENDED_SYS_STATE) the log's receive time shifted by the median offset
between receive and boot times of the messages that have both.  Only the first system id that sends a
HEARTBEAT from an autopilot is read.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from .errors import FlightLogError
from .logdata import FlightLog, Topic

ARMED_FLAG = 128  #: MAV_MODE_FLAG_SAFETY_ARMED
ON_GROUND = 1  #: MAV_LANDED_STATE_ON_GROUND

#: PX4 custom mode (main_mode, sub_mode) -> vehicle_status.nav_state (px4_custom_mode.h)
PX4_MODES = {(1, 0): 0, (2, 0): 1, (3, 0): 2, (3, 1): 2, (5, 0): 10, (6, 0): 14, (7, 0): 15,
             (4, 2): 17, (4, 3): 4, (4, 4): 3, (4, 5): 5, (4, 6): 18, (4, 8): 19, (4, 9): 20}

_WANTED = ["ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "HIGHRES_IMU", "SERVO_OUTPUT_RAW", "ACTUATOR_OUTPUT_STATUS",
           "HEARTBEAT", "EXTENDED_SYS_STATE", "PARAM_VALUE"]


def read_tlog(path: Path) -> FlightLog:
    try:
        from pymavlink import mavutil
    except ImportError:  # pragma: no cover - depends on the install
        raise FlightLogError("reading .tlog files needs pymavlink: pip install 'fawtgym[logs]'") from None
    rows: dict[str, list[tuple[float, object]]] = defaultdict(list)
    params: dict[str, float] = {}
    sysid = None
    try:
        conn = mavutil.mavlink_connection(str(path), dialect="common", robust_parsing=True)
        while True:
            msg = conn.recv_match(type=_WANTED)
            if msg is None:
                break
            kind = msg.get_type()
            if kind == "HEARTBEAT" and sysid is None and msg.autopilot != 8:  # 8: MAV_AUTOPILOT_INVALID (a GCS)
                sysid = msg.get_srcSystem()
            if sysid is not None and msg.get_srcSystem() != sysid:
                continue
            if kind == "PARAM_VALUE":
                params.setdefault(str(msg.param_id).rstrip("\x00"), float(msg.param_value))
                continue
            rows[kind].append((float(msg._timestamp), msg))
    except Exception as exc:  # pymavlink raises assorted errors on garbage
        raise FlightLogError(f"{path.name} is not a readable MAVLink .tlog ({' '.join(str(exc).split())})") from None
    if not rows or sysid is None:
        raise FlightLogError(f"{path.name} holds no MAVLink messages from an autopilot (not a .tlog, or truncated "
                             f"before the first HEARTBEAT); needed: {', '.join(_WANTED[:3])}, HEARTBEAT")
    topics = _topics(rows)
    t0 = min(float(t.t.min()) for t in topics.values() if len(t))
    for tp in topics.values():
        tp.t = tp.t - t0
    duration = max(float(t.t.max()) for t in topics.values() if len(t))
    return FlightLog(str(path), "tlog", topics, params, duration, "", [], start=t0)


def _unwrap32(x: np.ndarray, period: float) -> np.ndarray:
    jumps = np.concatenate([[0], np.cumsum(np.diff(x) < -period / 2)])
    return x + jumps * period


def _topics(rows: dict[str, list[tuple[float, Any]]]) -> dict[str, Topic]:
    """PX4 topics from MAVLink messages (pymavlink messages are untyped: ``Any``) by kind, with their receive times."""
    boot: dict[str, np.ndarray] = {}
    recv: dict[str, np.ndarray] = {}
    for kind, items in rows.items():
        recv[kind] = np.array([r for r, _ in items])
        msgs = [m for _, m in items]
        if hasattr(msgs[0], "time_boot_ms"):
            boot[kind] = _unwrap32(np.array([m.time_boot_ms for m in msgs], dtype=float), 2.0**32) * 1e-3
        elif hasattr(msgs[0], "time_usec"):
            boot[kind] = _unwrap32(np.array([m.time_usec for m in msgs], dtype=float), 2.0**32) * 1e-6
    offsets = np.concatenate([recv[k] - boot[k] for k in boot]) if boot else np.zeros(1)
    offset = float(np.median(offsets))

    def times(kind: str) -> np.ndarray:
        return boot[kind] if kind in boot else recv[kind] - offset

    def field(kind: str, name: str) -> np.ndarray:
        return np.array([getattr(m, name) for _, m in rows[kind]], dtype=float)

    out: dict[str, Topic] = {}
    if "ATTITUDE_QUATERNION" in rows:
        k = "ATTITUDE_QUATERNION"
        out["vehicle_attitude"] = Topic("vehicle_attitude", times(k),
                                        {f"q[{i}]": field(k, f"q{i + 1}") for i in range(4)})
        out["vehicle_angular_velocity"] = Topic("vehicle_angular_velocity", times(k), {
            f"xyz[{i}]": field(k, n) for i, n in enumerate(("rollspeed", "pitchspeed", "yawspeed"))})
    if "LOCAL_POSITION_NED" in rows:
        k = "LOCAL_POSITION_NED"
        out["vehicle_local_position"] = Topic("vehicle_local_position", times(k),
                                              {n: field(k, n) for n in ("x", "y", "z", "vx", "vy", "vz")})
    if "HIGHRES_IMU" in rows:
        k = "HIGHRES_IMU"
        f = {}
        for base, prefix, suffix in (("accelerometer_m_s2", "", "acc"), ("gyro_rad", "", "gyro"),
                                     ("magnetometer_ga", "", "mag")):
            for i, ax in enumerate("xyz"):
                f[f"{base}[{i}]"] = field(k, f"{prefix}{ax}{suffix}")
        out["sensor_combined"] = Topic("sensor_combined", times(k), f)
    if "SERVO_OUTPUT_RAW" in rows:
        k = "SERVO_OUTPUT_RAW"
        out["actuator_outputs"] = Topic("actuator_outputs", times(k),
                                        {f"output[{i}]": field(k, f"servo{i + 1}_raw") for i in range(8)})
    if "ACTUATOR_OUTPUT_STATUS" in rows:
        k = "ACTUATOR_OUTPUT_STATUS"
        act = np.array([m.actuator[:4] for _, m in rows[k]], dtype=float)
        if np.all((act >= 0) & (act <= 1)):
            out["actuator_motors"] = Topic("actuator_motors", times(k), {f"control[{i}]": act[:, i] for i in range(4)})
    if "HEARTBEAT" in rows:
        k = "HEARTBEAT"
        base_mode = field(k, "base_mode").astype(int)
        custom = field(k, "custom_mode").astype(np.int64)
        nav = [PX4_MODES.get((int(c >> 16) & 0xFF, int(c >> 24) & 0xFF), -1) for c in custom]
        out["vehicle_status"] = Topic("vehicle_status", times(k), {
            "arming_state": np.where(base_mode & ARMED_FLAG, 2, 1), "nav_state": np.array(nav, dtype=np.int64)})
    if "EXTENDED_SYS_STATE" in rows:
        k = "EXTENDED_SYS_STATE"
        out["vehicle_land_detected"] = Topic("vehicle_land_detected", times(k),
                                             {"landed": (field(k, "landed_state") == ON_GROUND).astype(np.int8)})
    return out
