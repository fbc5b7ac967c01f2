"""Which PX4 topic gives which measurement or known input, in which PX4 versions, and what replaces it.

Two topic sets exist.  The older one (PX4 up to v1.13) logs the normalized controller output in
``actuator_controls_0`` (roll, pitch, yaw torque in [-1, 1], thrust in [0, 1]) and the mixed motor
outputs in ``actuator_outputs`` (PWM).  The newer one (control allocation: PX4 v1.13, default from v1.14)
logs ``vehicle_thrust_setpoint`` / ``vehicle_torque_setpoint`` (normalized, FRD) and per-motor commands
in ``actuator_motors`` ([0, 1]).  Measurements (position, velocity, attitude, body rates, specific force)
come from topics every version logs, with a fallback for body rates (``vehicle_angular_velocity``,
PX4 v1.10+, else the gyro of ``sensor_combined``) and the magnetometer.

:func:`require` turns an absent topic into one line naming the topic, the PX4 versions that log it and
the alternative.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.frames import quat_to_rot

from .errors import FlightLogError
from .logdata import FlightLog


@dataclasses.dataclass(frozen=True)
class TopicInfo:
    gives: str
    versions: str
    alternative: str


#: every topic the estimation reads, what it gives, the PX4 versions that log it, and the alternative
TOPICS: dict[str, TopicInfo] = {
    "vehicle_local_position": TopicInfo("position and velocity (NED)", "all PX4 versions (v1.5+)",
                                        "none: the log needs a position estimate (EKF2 with GPS/mocap/flow)"),
    "vehicle_attitude": TopicInfo("attitude quaternion", "all PX4 versions", "none: the estimator must run"),
    "vehicle_angular_velocity": TopicInfo("body rates", "PX4 v1.10 and later",
                                          "sensor_combined.gyro_rad (all versions), used automatically"),
    "sensor_combined": TopicInfo("gyro and accelerometer (specific force)", "all PX4 versions (v1.5+)",
                                 "none: enable the default logger profile (SDLOG_PROFILE bit 0)"),
    "vehicle_magnetometer": TopicInfo("magnetometer", "PX4 v1.11 and later",
                                      "sensor_combined.magnetometer_ga (PX4 v1.10 and earlier), used automatically"),
    "vehicle_status": TopicInfo("arming state and flight mode (nav_state)", "all PX4 versions",
                                "none: every PX4 log has it unless the file is cut"),
    "vehicle_land_detected": TopicInfo("landed / airborne", "PX4 v1.6 and later",
                                       "arming state plus height above the arming point (used automatically)"),
    "actuator_motors": TopicInfo("per-motor commands [0, 1]", "PX4 v1.13 and later (control allocation)",
                                 "--inputs setpoints (vehicle_thrust_setpoint + vehicle_torque_setpoint, v1.13+; "
                                 "actuator_controls_0, v1.13 and earlier) or --inputs outputs (actuator_outputs)"),
    "vehicle_thrust_setpoint": TopicInfo("normalized collective thrust", "PX4 v1.13 and later",
                                         "actuator_controls_0 (PX4 v1.13 and earlier), used automatically"),
    "vehicle_torque_setpoint": TopicInfo("normalized body torque", "PX4 v1.13 and later",
                                         "actuator_controls_0 (PX4 v1.13 and earlier), used automatically"),
    "actuator_controls_0": TopicInfo("normalized torque and thrust (old topic set)", "PX4 v1.13 and earlier",
                                     "vehicle_thrust_setpoint + vehicle_torque_setpoint (PX4 v1.13 and later)"),
    "actuator_outputs": TopicInfo("motor outputs (PWM)", "all PX4 versions",
                                  "--inputs motors (actuator_motors, v1.13+) or --inputs setpoints"),
    "hover_thrust_estimate": TopicInfo("hover thrust estimate", "PX4 v1.12 and later",
                                       "the parameter MPC_THR_HOVER (used automatically)"),
}

#: topics loaded from a ULog (everything else is skipped while parsing)
USED_TOPICS: tuple[str, ...] = (*TOPICS, "commander_state")


def missing_topic(topic: str, needed_for: str) -> FlightLogError:
    """The one-line error for an absent topic."""
    info = TOPICS[topic]
    return FlightLogError(f"log has no topic {topic!r} ({info.gives}; logged by {info.versions}), needed for "
                          f"{needed_for}; alternative: {info.alternative}")


def require(log: FlightLog, topic: str, needed_for: str) -> None:
    """Raise :func:`missing_topic` unless ``log`` holds samples of ``topic``."""
    if not log.has(topic):
        raise missing_topic(topic, needed_for)


@dataclasses.dataclass
class Signal:
    """A sampled signal before resampling: times (K,) [s] and values (K, ...), with where it came from."""

    t: NDArray[np.float64]
    values: NDArray[np.float64]
    source: str


def measurement_signals(log: FlightLog) -> dict[str, Signal]:
    """The measurement keys of :mod:`fawtgym.core.measurement` as signals from the log's topics.

    position, velocity: ``vehicle_local_position`` (x, y, z, vx, vy, vz; NED).  attitude:
    ``vehicle_attitude.q`` (w, x, y, z; FRD -> NED) as R.  angular_velocity: ``vehicle_angular_velocity.xyz``
    or else ``sensor_combined.gyro_rad``.  gyro, specific_force: ``sensor_combined`` (gyro_rad,
    accelerometer_m_s2).  magnetometer: ``vehicle_magnetometer`` or ``sensor_combined.magnetometer_ga``.
    """
    require(log, "vehicle_local_position", "position and velocity (every observer)")
    require(log, "vehicle_attitude", "attitude (every observer)")
    require(log, "sensor_combined", "gyro and specific force")
    lp = log.topics["vehicle_local_position"]
    att = log.topics["vehicle_attitude"]
    sc = log.topics["sensor_combined"]
    q = att.vector("q", 4)
    good = np.all(np.isfinite(q), axis=1) & (np.linalg.norm(q, axis=1) > 0.5)
    out = {
        "position": Signal(lp.t, lp.columns("x", "y", "z"), "vehicle_local_position.x/y/z"),
        "velocity": Signal(lp.t, lp.columns("vx", "vy", "vz"), "vehicle_local_position.vx/vy/vz"),
        "attitude": Signal(att.t[good], quat_to_rot(q[good]), "vehicle_attitude.q"),
        "gyro": Signal(sc.t, sc.vector("gyro_rad", 3), "sensor_combined.gyro_rad"),
        "specific_force": Signal(sc.t, sc.vector("accelerometer_m_s2", 3), "sensor_combined.accelerometer_m_s2"),
    }
    if log.has("vehicle_angular_velocity"):
        av = log.topics["vehicle_angular_velocity"]
        out["angular_velocity"] = Signal(av.t, av.vector("xyz", 3), "vehicle_angular_velocity.xyz")
    else:
        out["angular_velocity"] = Signal(sc.t, out["gyro"].values, "sensor_combined.gyro_rad")
    if log.has("vehicle_magnetometer"):
        mag = log.topics["vehicle_magnetometer"]
        out["magnetometer"] = Signal(mag.t, mag.vector("magnetometer_ga", 3), "vehicle_magnetometer.magnetometer_ga")
    elif sc.has("magnetometer_ga[0]"):
        out["magnetometer"] = Signal(sc.t, sc.vector("magnetometer_ga", 3), "sensor_combined.magnetometer_ga")
    return out
