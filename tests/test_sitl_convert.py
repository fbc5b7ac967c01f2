"""The SITL conversions (fawtgym.eval.sitl.convert) and the PX4 airframe preset (fawtgym.eval.sitl.airframe).

Reference values come from the MAVLink message definitions, PX4's airframe 10016_none_iris and textbook
formulas written here, not from the module under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from pymavlink.dialects.v20 import common as mavlink

from fawtgym.agents.spec import make_agent
from fawtgym.core.frames import euler_to_rot, rot_to_quat
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.motors import allocation_matrix
from fawtgym.eval.sitl import convert as C
from fawtgym.eval.sitl.airframe import PX4_MOTOR_TO_ROTOR, iris, motors_from_px4, motors_to_px4

#: PX4 v1.14 ROMFS/px4fmu_common/init.d-posix/airframes/10016_none_iris: CA_ROTORn_PX, _PY, _KM
NONE_IRIS = ((0.1515, 0.245, 0.05), (-0.1515, -0.1875, 0.05), (0.1515, -0.245, -0.05), (-0.1515, 0.1875, -0.05))


def roundtrip(msg):
    """Pack with pymavlink and parse back (the float32/int wire format)."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return mav.parse_buffer(msg.pack(mav))[0]


def test_px4_motor_mapping_is_pinned():
    """PX4 motor n+1 (HIL_ACTUATOR_CONTROLS controls[n]) sits where CA_ROTORn says and spins as CA_ROTORn_KM says."""
    p = iris()
    assert PX4_MOTOR_TO_ROTOR == (0, 1, 2, 3)
    for motor, (px, py, km) in enumerate(NONE_IRIS):
        rotor = PX4_MOTOR_TO_ROTOR[motor]
        np.testing.assert_allclose(p.rotor_positions[rotor], [px, py, 0.0], atol=1e-12)
        assert p.rotor_directions[rotor] == np.sign(km)  # +1: CCW seen from above (PX4: KM > 0)
    # the effectiveness PX4 computes from the CA table (torque = r x (-T e3), yaw = KM T) equals our physics'
    ca = np.array(NONE_IRIS)
    b_px4 = np.vstack([np.ones(4), -ca[:, 1], ca[:, 0], np.sign(ca[:, 2]) * p.k_moment])
    np.testing.assert_allclose(allocation_matrix(p)[:, list(PX4_MOTOR_TO_ROTOR)], b_px4, atol=1e-12)
    u = np.array([0.1, 0.2, 0.3, 0.4])
    np.testing.assert_array_equal(motors_to_px4(motors_from_px4(u)), u)


def test_iris_preset_matches_gazebo_iris():
    p = iris()
    assert p.mass == pytest.approx(1.5 + 4 * 0.005 + 0.015 + 0.01)
    np.testing.assert_allclose(np.diag(p.inertia_matrix), [0.029125, 0.029125, 0.055225])
    assert (p.k_thrust, p.k_moment, p.omega_min, p.omega_max) == (5.84e-6, 0.06, 100.0, 1100.0)
    # Gazebo's mavlink_interface: speed = 100 + 1000 u (armed); our command_to_omega is the same map
    from fawtgym.envs.motors import command_to_omega

    np.testing.assert_allclose(command_to_omega(p, [0.0, 0.5, 1.0]), [100.0, 600.0, 1100.0])


def test_motor_commands_from_actuator_controls():
    controls = [0.1, 0.2, 0.3, 0.4] + [0.0] * 12
    np.testing.assert_allclose(C.motor_commands(controls, 129, PX4_MOTOR_TO_ROTOR), [0.1, 0.2, 0.3, 0.4])
    np.testing.assert_array_equal(C.motor_commands(controls, 1, PX4_MOTOR_TO_ROTOR), np.zeros(4))  # disarmed
    np.testing.assert_allclose(C.motor_commands([1.5, -0.2, 0, 0], 129, PX4_MOTOR_TO_ROTOR), [1, 0, 0, 0])
    with pytest.raises(ValueError, match=r"controls\[1\] is nan"):
        C.motor_commands([0.1, math.nan, 0, 0], 129, PX4_MOTOR_TO_ROTOR)


def test_geodetic_matches_spherical_earth():
    home = C.Home()
    lat, lon, alt = C.ned_to_geodetic(home, [1000.0, 0.0, -20.0])
    assert lat == pytest.approx(home.lat + math.degrees(1000.0 / 6371000.0), abs=1e-9)  # a meridian arc
    assert lon == pytest.approx(home.lon, abs=1e-12) and alt == pytest.approx(508.0)
    lat, lon, _ = C.ned_to_geodetic(home, [0.0, 1000.0, 0.0])  # east: a great circle through home
    d = math.acos(math.sin(math.radians(home.lat)) * math.sin(math.radians(lat)) + math.cos(math.radians(home.lat))
                  * math.cos(math.radians(lat)) * math.cos(math.radians(lon - home.lon))) * 6371000.0
    assert d == pytest.approx(1000.0, abs=1e-4)  # acos near 1 keeps ~eps R / (d / R) ~ 1e-5 m
    for ned in ([12.3, -45.6, -7.8], [-300.0, 250.0, 1.0]):
        np.testing.assert_allclose(C.geodetic_to_ned(home, *C.ned_to_geodetic(home, ned)), ned, atol=1e-6)
    with pytest.raises(ValueError, match="home latitude"):
        C.parse_home("95,8,400")
    with pytest.raises(ValueError, match="lat,lon,alt"):
        C.parse_home("47.3,8.5")


def test_isa_barometer():
    for h in (0.0, 488.0, 2000.0):
        assert C.isa_pressure_hpa(h) == pytest.approx(1013.25 * (1 - 2.25577e-5 * h) ** 5.25588, abs=0.02)
        assert C.isa_altitude(C.isa_pressure_hpa(h)) == pytest.approx(h, abs=1e-6)
    assert C.isa_temperature_c(0.0) == pytest.approx(15.0)


def test_hil_messages_units_on_the_wire():
    home = C.Home()
    r = euler_to_rot(0.1, -0.2, 0.3)
    meas = {"specific_force": np.array([0.5, -0.4, -9.7]), "gyro": np.array([0.01, -0.02, 0.03]),
            "magnetometer": np.array([0.2, 0.0, 0.4])}
    sensor = roundtrip(mavlink.MAVLink_hil_sensor_message(**C.hil_sensor_fields(meas, [0.2, 0.01, 0.43], 500.0,
                                                                                  123456)))
    assert (sensor.zacc, sensor.ygyro, sensor.zmag) == pytest.approx((-9.7, -0.02, 0.43), rel=1e-6)
    assert sensor.fields_updated == 0x7 | 0x38 | 0x1C0 | 0x1A00 and sensor.time_usec == 123456
    assert sensor.pressure_alt == pytest.approx(500.0) and sensor.abs_pressure == pytest.approx(954.6, abs=0.1)
    gps = roundtrip(mavlink.MAVLink_hil_gps_message(**C.hil_gps_fields(home, [0, 0, -10], [3.0, 4.0, -1.0], 7)))
    assert (gps.fix_type, gps.alt, gps.eph, gps.epv) == (3, 498000, 30, 40)
    assert (gps.vel, gps.vn, gps.ve, gps.vd) == (500, 300, 400, -100)  # cm/s
    assert gps.cog == round(math.degrees(math.atan2(4, 3)) * 100) and gps.satellites_visible >= 10
    assert gps.lat == round(home.lat * 1e7) and gps.lon == round(home.lon * 1e7)
    state = roundtrip(mavlink.MAVLink_hil_state_quaternion_message(**C.hil_state_quaternion_fields(
        home, [0, 0, 0], [1.0, 0, 0], r, [0.1, 0.2, 0.3], [0.0, 0.0, -9.80665], 9)))
    q = np.array(state.attitude_quaternion)
    w, x, y, z = q  # textbook (w, x, y, z) -> R, body -> world
    r_q = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    np.testing.assert_allclose(r_q, r, atol=1e-6)
    assert (state.vx, state.zacc) == (100, -1000)  # cm/s, mG


def test_telemetry_to_measurement_units():
    att = roundtrip(mavlink.MAVLink_attitude_quaternion_message(5, 1.0, 0.0, 0.0, 0.0, 0.1, 0.2, 0.3))
    lpos = roundtrip(mavlink.MAVLink_local_position_ned_message(5, 1.0, 2.0, -3.0, 0.1, 0.2, 0.3))
    hi = roundtrip(mavlink.MAVLink_highres_imu_message(5000, 0.1, 0.2, -9.8, 0.01, 0.02, 0.03, 0.2, 0.0, 0.4,
                                                       950, 0, 0, 20, 0x1FFF))
    scaled = roundtrip(mavlink.MAVLink_scaled_imu_message(5, 10, 20, -999, 10, 20, 30, 200, 0, 400))
    m = C.measurement_from_telemetry(att, lpos, hi, [1.5, 0.0, -0.03], 2.0)
    np.testing.assert_allclose(m["position"], [2.5, 2.0, -3.03], atol=1e-6)
    np.testing.assert_allclose(m["angular_velocity"], [0.1, 0.2, 0.3], atol=1e-6)
    np.testing.assert_allclose(m["specific_force"], [0.1, 0.2, -9.8], atol=1e-6)
    np.testing.assert_allclose(m["attitude"], np.eye(3))
    s = C.measurement_from_telemetry(att, lpos, scaled, [0, 0, 0], 2.0)
    np.testing.assert_allclose(s["specific_force"], np.array([10, 20, -999]) * 9.80665e-3)
    np.testing.assert_allclose(s["gyro"], [0.01, 0.02, 0.03])
    np.testing.assert_allclose(s["magnetometer"], [0.2, 0.0, 0.4])
    with pytest.raises(ValueError, match="HIGHRES_IMU or SCALED_IMU"):
        C.measurement_from_telemetry(att, lpos, att, [0, 0, 0], 0.0)


def test_attitude_target_fields():
    r = euler_to_rot(0.0, 0.1, 0.0)
    f = C.attitude_target_fields(attitude=r, thrust=0.6, time_boot_ms=1, target_system=1, target_component=1)
    assert f["type_mask"] == 7 and f["q"] == pytest.approx([math.cos(0.05), 0.0, math.sin(0.05), 0.0])
    f = C.attitude_target_fields(body_rates=[0.1, 0, 0], thrust=0.5, time_boot_ms=1, target_system=1,
                                 target_component=1)
    assert f["type_mask"] == 128 and f["body_roll_rate"] == 0.1
    with pytest.raises(ValueError, match="thrust must be in"):
        C.attitude_target_fields(body_rates=[0, 0, 0], thrust=1.5, time_boot_ms=1, target_system=1,
                                 target_component=1)
    p = iris()
    assert C.px4_thrust(p, p.mass * 9.80665) == pytest.approx(
        (math.sqrt(p.mass * 9.80665 / (4 * 5.84e-6)) - 100) / 1000)  # the hover motor command


def test_agent_acts_the_same_on_telemetry_as_on_the_env():
    """The agent's observer and controller see the telemetry through the same code path: the env's measurement
    sent over MAVLink (float32 on the wire) and converted back gives the same actions, to float32 rounding."""
    env = HoverEnv(vehicle=iris(), wind="fawt-50", sensors="seed000", control_rate=100.0, init_noise=1.0)
    a_env, a_tel = make_agent("px4+leso", env), make_agent("px4+leso", env)
    _, info = env.reset(seed=3)
    origin = np.array([0.5, -0.2, -0.03])

    def over_mavlink(info):
        m = info["measurement"]
        q = rot_to_quat(m["attitude"])
        att = roundtrip(mavlink.MAVLink_attitude_quaternion_message(0, *q, *m["angular_velocity"]))
        lp = roundtrip(mavlink.MAVLink_local_position_ned_message(0, *(m["position"] - origin), *m["velocity"]))
        imu = roundtrip(mavlink.MAVLink_highres_imu_message(0, *m["specific_force"], *m["gyro"], *m["magnetometer"],
                                                            0, 0, 0, 0, 0x1FF))
        meas = C.measurement_from_telemetry(att, lp, imu, origin, float(m["time"]))
        return {**info, "measurement": meas}

    a_env.reset(info, seed=0)
    a_tel.reset(over_mavlink(info), seed=0)
    worst = 0.0
    for _ in range(200):
        u_env = a_env.act(None, info)
        u_tel = a_tel.act(None, over_mavlink(info))
        worst = max(worst, float(np.abs(u_env - u_tel).max()))
        _, _, term, _, info = env.step(u_env)
        assert not term
    assert worst < 1e-5, f"actions differ by {worst} (float32 telemetry; 1e-7 seen)"
