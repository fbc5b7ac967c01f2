"""MAVLink fields <-> our frames and units: the one place the SITL hook converts (tested in tests/test_sitl_convert.py).

Our side (:mod:`fawtgym.core.measurement`): world NED [m, m/s], body FRD, attitude R (body -> world), SI units,
magnetic field in gauss.  MAVLink's side, per the message definitions of ``common.xml``:

=====================  ==================================================================================
message                fields and units
=====================  ==================================================================================
HIL_SENSOR (107)       time_usec [us]; x/y/zacc [m/s^2] (specific force, FRD: -9.81 on z at rest);
                       x/y/zgyro [rad/s]; x/y/zmag [gauss]; abs_pressure, diff_pressure [hPa];
                       pressure_alt [m]; temperature [degC]; fields_updated (bits of
                       :data:`HIL_SENSOR_BITS`); id
HIL_GPS (113)          lat, lon [degE7]; alt [mm] (MSL); eph, epv [cm]; vel [cm/s]; vn, ve, vd [cm/s];
                       cog [cdeg] (65535 unknown); fix_type (3 = 3D); satellites_visible
HIL_STATE_QUATERNION   attitude_quaternion (w, x, y, z); roll/pitch/yawspeed [rad/s]; lat, lon [degE7];
                       alt [mm]; vx, vy, vz [cm/s]; x/y/zacc [mG]
ATTITUDE_QUATERNION    q1..q4 = (w, x, y, z) body FRD -> local NED; roll/pitch/yawspeed [rad/s]
LOCAL_POSITION_NED     x, y, z [m]; vx, vy, vz [m/s] (the autopilot's local origin)
HIGHRES_IMU            x/y/zacc [m/s^2]; x/y/zgyro [rad/s]; x/y/zmag [gauss]
SCALED_IMU             x/y/zacc [mG]; x/y/zgyro [mrad/s]; x/y/zmag [mgauss]
SET_ATTITUDE_TARGET    q (w, x, y, z); body rates [rad/s]; thrust [0, 1]; type_mask (ignore bits)
=====================  ==================================================================================

Geodetic positions use PX4's map projection (``lib/geo``: azimuthal equidistant about the reference point,
Earth radius 6 371 000 m), so PX4 maps our NED back onto the same metres.  The barometer follows the ISA
troposphere that PX4 inverts to get altitude (``sensors/vehicle_air_data``: T0 = 288.15 K, lapse
-6.5 K/km, R = 287.05 J/(kg K), g = 9.80665, QNH 1013.25 hPa).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M
from fawtgym.core.checks import shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.frames import quat_to_rot, rot_to_quat
from fawtgym.envs.motors import command_to_thrust, rotor_wrench, thrust_to_command
from fawtgym.envs.vehicles import VehiclePreset

EARTH_RADIUS = 6371000.0  #: [m], PX4 CONSTANTS_RADIUS_OF_EARTH
ISA_T0 = 288.15  #: sea-level temperature [K]
ISA_LAPSE = -6.5e-3  #: temperature lapse rate [K/m]
ISA_R = 287.05  #: specific gas constant of air [J/(kg K)]
QNH_HPA = 1013.25  #: sea-level pressure [hPa] (PX4 SENS_BARO_QNH default)

#: HIL_SENSOR ``fields_updated`` bits (MAVLink HIL_SENSOR_UPDATED_FLAGS; PX4 SimulatorMavlink's SensorSource)
HIL_SENSOR_BITS = {"accel": 0x7, "gyro": 0x38, "mag": 0x1C0, "baro": 0x1A00, "diff_pressure": 0x400}
#: what the bridge sends each step: accelerometer, gyroscope, magnetometer, barometer (no airspeed sensor)
FIELDS_IMU_MAG_BARO = HIL_SENSOR_BITS["accel"] | HIL_SENSOR_BITS["gyro"] | HIL_SENSOR_BITS["mag"] | \
    HIL_SENSOR_BITS["baro"]

GPS_FIX_3D = 3
GPS_EPH_M = 0.3  #: horizontal accuracy the bridge reports [m] (well inside PX4's EKF2_REQ_EPH 3 m)
GPS_EPV_M = 0.4  #: vertical accuracy the bridge reports [m] (EKF2_REQ_EPV 5 m)
GPS_SATELLITES = 12
#: barometer white noise [Pa RMS], as PX4-SITL_gazebo-classic's barometer plugin (``abs_pressure_noise = 1 Pa
#: RMS``).  The env's sensor model has no barometer; without noise PX4 v1.14 flags the barometer STALE (its
#: DataValidator: more than 100 equal values in a row) and EKF2 falls back to GPS height (seen in the hand test).
BARO_NOISE_PA = 1.0

#: SET_ATTITUDE_TARGET type_mask bits (ATTITUDE_TARGET_TYPEMASK)
IGNORE_BODY_RATES = 0x7
IGNORE_ATTITUDE = 0x80
MG = GRAVITY / 1000.0  #: one milli-g [m/s^2]


@dataclasses.dataclass(frozen=True)
class Home:
    """Where our NED origin sits on Earth, and the Earth magnetic field there.

    Default: PX4's default SITL home (Zurich, 47.397742 N 8.545594 E, 488 m MSL, the PX4_HOME_LAT/LON/ALT
    defaults of its Gazebo worlds) with the World Magnetic Model field there (declination +3.0 deg,
    inclination 63.7 deg, 0.483 gauss; rounded WMM2020 values for 2024), in NED [gauss].  PX4 compares the
    measured field with its own WMM table (strength within EKF2_MAG_CHK_STR 0.2 gauss, inclination within
    EKF2_MAG_CHK_INC 20 deg), so another home needs its own field (``mag_ned``).
    """

    lat: float = 47.397742  #: [deg]
    lon: float = 8.545594  #: [deg]
    alt: float = 488.0  #: [m] MSL
    mag_ned: tuple[float, float, float] = (0.2137, 0.0112, 0.4330)  #: [gauss]

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lat) and -90.0 < self.lat < 90.0):
            raise ValueError(f"home latitude must be in (-90, 90) deg, got {shown(self.lat)}")
        if not (math.isfinite(self.lon) and -180.0 <= self.lon <= 180.0):
            raise ValueError(f"home longitude must be in [-180, 180] deg, got {shown(self.lon)}")
        if not (math.isfinite(self.alt) and -500.0 < self.alt < 9000.0):
            raise ValueError(f"home altitude must be in (-500, 9000) m MSL, got {shown(self.alt)}")
        mag = np.asarray(self.mag_ned, dtype=float)
        if mag.shape != (3,) or not np.all(np.isfinite(mag)) or not 0.1 < np.linalg.norm(mag) < 1.0:
            raise ValueError(f"home mag_ned must be 3 finite numbers with a norm of 0.1-1 gauss, got "
                             f"{shown(self.mag_ned)}")
        object.__setattr__(self, "mag_ned", tuple(float(x) for x in mag))


def parse_home(text: str) -> Home:
    """``"lat,lon,alt"`` (degrees, degrees, metres MSL) -> :class:`Home` (field at PX4's default home)."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"home must be 'lat,lon,alt' (deg, deg, m MSL), got {shown(text)}") from None
    return Home(lat, lon, alt)


# ---- positions -----------------------------------------------------------------------------------------------
def ned_to_geodetic(home: Home, ned: ArrayLike) -> tuple[float, float, float]:
    """NED [m] (3,) from the home point -> (lat [deg], lon [deg], alt [m MSL]); PX4 MapProjection::reproject."""
    x, y, z = (float(v) for v in np.ravel(ned))
    lat0, lon0 = math.radians(home.lat), math.radians(home.lon)
    xr, yr = x / EARTH_RADIUS, y / EARTH_RADIUS
    c = math.hypot(xr, yr)
    if c > 0.0:
        sin_c, cos_c = math.sin(c), math.cos(c)
        lat = math.asin(cos_c * math.sin(lat0) + xr * sin_c * math.cos(lat0) / c)
        lon = lon0 + math.atan2(yr * sin_c, c * math.cos(lat0) * cos_c - xr * math.sin(lat0) * sin_c)
    else:
        lat, lon = lat0, lon0
    return math.degrees(lat), math.degrees(lon), home.alt - z


def geodetic_to_ned(home: Home, lat: float, lon: float, alt: float) -> NDArray[np.float64]:
    """(lat [deg], lon [deg], alt [m MSL]) -> NED [m] from the home point; PX4 MapProjection::project."""
    lat0, lon0 = math.radians(home.lat), math.radians(home.lon)
    la, lo = math.radians(lat), math.radians(lon)
    cos_d_lon = math.cos(lo - lon0)
    arg = min(1.0, max(-1.0, math.sin(lat0) * math.sin(la) + math.cos(lat0) * math.cos(la) * cos_d_lon))
    c = math.acos(arg)
    k = c / math.sin(c) if abs(c) > 0.0 else 1.0
    x = k * (math.cos(lat0) * math.sin(la) - math.sin(lat0) * math.cos(la) * cos_d_lon) * EARTH_RADIUS
    y = k * math.cos(la) * math.sin(lo - lon0) * EARTH_RADIUS
    return np.array([x, y, home.alt - alt])


# ---- barometer -----------------------------------------------------------------------------------------------
def isa_pressure_hpa(alt_msl: float) -> float:
    """ISA static pressure [hPa] at ``alt_msl`` [m]: p = QNH (T / T0)^(-g / (a R)), T = T0 + a h."""
    t = ISA_T0 + ISA_LAPSE * alt_msl
    return QNH_HPA * (t / ISA_T0) ** (-GRAVITY / (ISA_LAPSE * ISA_R))


def isa_altitude(pressure_hpa: float) -> float:
    """Inverse of :func:`isa_pressure_hpa` (PX4's baro altitude) [m]."""
    return ((pressure_hpa / QNH_HPA) ** (-(ISA_LAPSE * ISA_R) / GRAVITY) * ISA_T0 - ISA_T0) / ISA_LAPSE


def isa_temperature_c(alt_msl: float) -> float:
    """ISA temperature [degC] at ``alt_msl`` [m]."""
    return ISA_T0 + ISA_LAPSE * alt_msl - 273.15


# ---- simulator -> PX4 ----------------------------------------------------------------------------------------
def home_magnetometer(meas: Mapping[str, Any], attitude_true: ArrayLike, home: Home) -> NDArray[np.float64]:
    """The magnetometer [gauss] (3,) at the home field: the env's measurement (field
    :data:`fawtgym.core.measurement.EARTH_FIELD_NED`, with its noise) plus ``R^T (m_home - m_env)``."""
    r = np.asarray(attitude_true, dtype=float).reshape(3, 3)
    delta = np.asarray(home.mag_ned) - M.EARTH_FIELD_NED
    return np.ravel(meas[M.MAGNETOMETER]) + r.T @ delta


def hil_sensor_fields(meas: Mapping[str, Any], mag: ArrayLike, alt_msl: float, time_usec: int,
                      fields_updated: int = FIELDS_IMU_MAG_BARO, pressure_noise_pa: float = 0.0) -> dict[str, Any]:
    """HIL_SENSOR fields from a measurement (specific force, gyro), a magnetometer [gauss] and the altitude.

    ``pressure_noise_pa`` is this sample's barometer error [Pa] (the bridge draws it, :data:`BARO_NOISE_PA`
    RMS); ``pressure_alt`` is the ISA altitude of the noisy pressure, as a barometer reports it.
    """
    if not math.isfinite(pressure_noise_pa):
        raise ValueError(f"pressure_noise_pa must be finite, got {shown(pressure_noise_pa)}")
    f, g, m = np.ravel(meas[M.SPECIFIC_FORCE]), np.ravel(meas[M.GYRO]), np.ravel(mag)
    pressure = isa_pressure_hpa(alt_msl) + float(pressure_noise_pa) / 100.0
    baro_alt = float(alt_msl) if pressure_noise_pa == 0.0 else isa_altitude(pressure)
    return dict(time_usec=int(time_usec), xacc=float(f[0]), yacc=float(f[1]), zacc=float(f[2]),
                xgyro=float(g[0]), ygyro=float(g[1]), zgyro=float(g[2]),
                xmag=float(m[0]), ymag=float(m[1]), zmag=float(m[2]),
                abs_pressure=pressure, diff_pressure=0.0, pressure_alt=baro_alt,
                temperature=isa_temperature_c(alt_msl), fields_updated=int(fields_updated), id=0)


def _i16(x: float) -> int:
    return int(max(-32767, min(32767, round(x))))


def hil_gps_fields(home: Home, position: ArrayLike, velocity: ArrayLike, time_usec: int) -> dict[str, Any]:
    """HIL_GPS fields from a NED position [m] and velocity [m/s] (3D fix, :data:`GPS_SATELLITES` satellites)."""
    lat, lon, alt = ned_to_geodetic(home, position)
    vn, ve, vd = (float(v) for v in np.ravel(velocity))
    ground = math.hypot(vn, ve)
    cog = round(math.degrees(math.atan2(ve, vn)) % 360.0 * 100.0) % 36000 if ground > 0.05 else 65535
    return dict(time_usec=int(time_usec), fix_type=GPS_FIX_3D, lat=int(round(lat * 1e7)), lon=int(round(lon * 1e7)),
                alt=int(round(alt * 1000.0)), eph=int(round(GPS_EPH_M * 100)), epv=int(round(GPS_EPV_M * 100)),
                vel=int(min(65534, round(ground * 100.0))), vn=_i16(vn * 100.0), ve=_i16(ve * 100.0),
                vd=_i16(vd * 100.0), cog=int(cog), satellites_visible=GPS_SATELLITES, id=0, yaw=0)


def hil_state_quaternion_fields(home: Home, position: ArrayLike, velocity: ArrayLike, attitude: ArrayLike,
                                angular_velocity: ArrayLike, acceleration: ArrayLike,
                                time_usec: int) -> dict[str, Any]:
    """HIL_STATE_QUATERNION (ground truth) fields; ``acceleration`` is the NED acceleration [m/s^2]."""
    lat, lon, alt = ned_to_geodetic(home, position)
    q = rot_to_quat(np.asarray(attitude, dtype=float).reshape(3, 3))
    v, w, a = (np.ravel(x).astype(float) for x in (velocity, angular_velocity, acceleration))
    speed = float(np.linalg.norm(v))
    return dict(time_usec=int(time_usec), attitude_quaternion=[float(x) for x in q], rollspeed=float(w[0]),
                pitchspeed=float(w[1]), yawspeed=float(w[2]), lat=int(round(lat * 1e7)), lon=int(round(lon * 1e7)),
                alt=int(round(alt * 1000.0)), vx=_i16(v[0] * 100), vy=_i16(v[1] * 100), vz=_i16(v[2] * 100),
                ind_airspeed=int(min(65535, round(speed * 100))), true_airspeed=int(min(65535, round(speed * 100))),
                xacc=_i16(a[0] / MG), yacc=_i16(a[1] / MG), zacc=_i16(a[2] / MG))


def motor_commands(controls: ArrayLike, mode: int, motor_to_rotor: tuple[int, ...]) -> NDArray[np.float64]:
    """Our motor commands (4,) in [0, 1] from HIL_ACTUATOR_CONTROLS ``controls`` and ``mode``.

    PX4 fills ``controls[0..3]`` with motors 1-4 in [0, 1] and sets ``mode`` bit 128 (MAV_MODE_FLAG_SAFETY_ARMED)
    when armed; disarmed, the motors get 0 (idle), as Gazebo's ``mavlink_interface`` does.  Non-finite values
    raise ValueError naming the control.
    """
    c = np.asarray(controls, dtype=float).ravel()
    if c.size < 4:
        raise ValueError(f"HIL_ACTUATOR_CONTROLS needs at least 4 controls, got {c.size}")
    out = np.zeros(4)
    if not int(mode) & 128:
        return out
    for motor, rotor in enumerate(motor_to_rotor):
        if not math.isfinite(c[motor]):
            raise ValueError(f"HIL_ACTUATOR_CONTROLS controls[{motor}] is {c[motor]}; motor controls must be finite")
        out[rotor] = min(1.0, max(0.0, c[motor]))
    return out


# ---- autopilot telemetry -> our measurement ------------------------------------------------------------------
def measurement_from_telemetry(attitude: Any, local_position: Any, imu: Any, origin: ArrayLike,
                               time: float) -> dict[str, NDArray[np.float64]]:
    """Our measurement mapping (single vehicle, no batch axis) from MAVLink telemetry messages.

    ``attitude``: ATTITUDE_QUATERNION; ``local_position``: LOCAL_POSITION_NED (``origin``: our NED coordinates of
    the autopilot's local origin [m]); ``imu``: HIGHRES_IMU (SI) or SCALED_IMU (mG, mrad/s, mgauss).  Messages are
    pymavlink message objects (attribute access).  The attitude rates become ``angular_velocity`` (the
    autopilot's estimator-grade rates), the IMU gyro ``gyro``.
    """
    q = np.array([attitude.q1, attitude.q2, attitude.q3, attitude.q4], dtype=float)
    r = quat_to_rot(q)
    lp = local_position
    pos = np.asarray(origin, dtype=float) + np.array([lp.x, lp.y, lp.z], dtype=float)
    vel = np.array([lp.vx, lp.vy, lp.vz], dtype=float)
    rates = np.array([attitude.rollspeed, attitude.pitchspeed, attitude.yawspeed], dtype=float)
    kind = imu.get_type()
    if kind == "HIGHRES_IMU":
        acc_s, gyro_s, mag_s = 1.0, 1.0, 1.0
    elif kind.startswith("SCALED_IMU"):
        acc_s, gyro_s, mag_s = MG, 1e-3, 1e-3
    else:
        raise ValueError(f"IMU telemetry must be HIGHRES_IMU or SCALED_IMU, got {kind}")
    acc = np.array([imu.xacc, imu.yacc, imu.zacc], dtype=float) * acc_s
    gyro = np.array([imu.xgyro, imu.ygyro, imu.zgyro], dtype=float) * gyro_s
    mag = np.array([imu.xmag, imu.ymag, imu.zmag], dtype=float) * mag_s
    meas = {M.POSITION: pos, M.VELOCITY: vel, M.ATTITUDE: r, M.ANGULAR_VELOCITY: rates, M.SPECIFIC_FORCE: acc,
            M.GYRO: gyro, M.MAGNETOMETER: mag, M.TIME: np.asarray(float(time))}
    for key, value in meas.items():
        if not np.all(np.isfinite(value)):
            raise ValueError(f"telemetry gives a non-finite {key} {value.tolist()} (from {kind}, "
                             "ATTITUDE_QUATERNION, LOCAL_POSITION_NED)")
    return meas


# ---- our commands -> SET_ATTITUDE_TARGET ---------------------------------------------------------------------
def px4_thrust(preset: VehiclePreset, collective: float) -> float:
    """PX4's normalized collective thrust in [0, 1] for a collective rotor thrust [N].

    PX4 hands its normalized thrust to the allocator, whose motor command with ``THR_MDL_FAC = 0`` (none_iris)
    is linear in it; our motor model maps a command to thrust, so the normalized thrust is the command that
    makes each rotor produce a quarter of ``collective`` (:func:`fawtgym.envs.motors.thrust_to_command`).
    """
    return float(thrust_to_command(preset, max(0.0, float(collective)) / 4.0))


def applied_from_motors(preset: VehiclePreset, motors: ArrayLike) -> tuple[float, NDArray[np.float64]]:
    """Known inputs of an observer from commanded motors: collective thrust [N] and body torque [N m] (3,),
    through the preset's steady-state thrust model (no motor lag)."""
    f, tau = rotor_wrench(preset, command_to_thrust(preset, np.clip(np.asarray(motors, dtype=float), 0.0, 1.0)))
    return float(f), np.asarray(tau, dtype=float).reshape(3)


def attitude_target_fields(*, attitude: ArrayLike | None = None, body_rates: ArrayLike | None = None,
                           thrust: float, time_boot_ms: int, target_system: int,
                           target_component: int) -> dict[str, Any]:
    """SET_ATTITUDE_TARGET fields: either an attitude R (body FRD -> NED) or body rates [rad/s], plus PX4's
    normalized thrust in [0, 1].  Exactly one of ``attitude`` and ``body_rates`` is given."""
    if (attitude is None) == (body_rates is None):
        raise ValueError("give exactly one of attitude and body_rates")
    if not (math.isfinite(thrust) and 0.0 <= thrust <= 1.0):
        raise ValueError(f"thrust must be in [0, 1], got {shown(thrust)}")
    if attitude is not None:
        q = rot_to_quat(np.asarray(attitude, dtype=float).reshape(3, 3))
        rates, mask = np.zeros(3), IGNORE_BODY_RATES
    else:
        q = np.array([1.0, 0.0, 0.0, 0.0])
        rates, mask = np.asarray(body_rates, dtype=float).reshape(3), IGNORE_ATTITUDE
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(rates))):
        raise ValueError(f"attitude target must be finite, got q={q.tolist()} rates={rates.tolist()}")
    return dict(time_boot_ms=int(time_boot_ms) & 0xFFFFFFFF, target_system=int(target_system),
                target_component=int(target_component), type_mask=mask, q=[float(x) for x in q],
                body_roll_rate=float(rates[0]), body_pitch_rate=float(rates[1]), body_yaw_rate=float(rates[2]),
                thrust=float(thrust))
