"""Sensor presets: PSD -> per-sample sigma, sample-and-hold, biases; reward bounds."""

import math

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.so3 import log_so3
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.sensors import SensorModel, make_sensor_spec


def _noise(preset, control_dt, n=4000):
    model = SensorModel(make_sensor_spec(preset), control_dt)
    model.reset(np.random.default_rng(0))
    b, v, w, a = np.array([1.0, 2.0, -3.0]), np.array([0.1, 0.0, 0.2]), np.array([0.3, -0.1, 0.05]), np.zeros(3)
    r = np.eye(3)
    samples = [model.measure(k * control_dt, b, v, r, w, a) for k in range(n)]
    return {key: np.array([s[key] for s in samples]) for key in samples[0]}, (b, v, r, w)


@pytest.mark.parametrize("dt", [0.01, 0.002])
def test_seed000_table2_psd_gives_rate_independent_density(dt):
    m, (b, v, r, w) = _noise("seed000", dt)
    # per-sample sigma = sqrt(P / dt): the density (PSD) is what stays fixed, Table 2
    for key, truth, psd in (("position", b, 3e-8), ("velocity", v, 3e-7), ("angular_velocity", w, 3e-7)):
        sigma = np.std(m[key] - truth, axis=0)
        assert np.allclose(sigma, math.sqrt(psd / dt), rtol=0.06), (key, sigma)
    rot_noise = log_so3(np.swapaxes(np.eye(3), 0, 1) @ m["attitude"])
    assert np.allclose(np.std(rot_noise, axis=0), math.sqrt(3e-8 / dt), rtol=0.06)


def test_pose_rate_must_divide_control_rate():
    with pytest.raises(ValueError, match="divide"):
        SensorModel(make_sensor_spec("mocap_imu"), 1 / 250)


@pytest.mark.parametrize("physics_rate, allowed", [
    (1000.0, "100, 200, 500, 1000"), (2000.0, "100, 200, 400, 500, 1000, 2000"), (1500.0, "100, 300, 500, 1500")])
def test_pose_rate_error_names_the_preset_and_the_allowed_control_rates(physics_rate, allowed):
    """One line, one ValueError, the same for the single env and the batch env at any N: the preset, its pose
    rate, the rejected control rate and the control rates that work with this physics rate (each of which does)."""
    import gymnasium as gym

    import fawtgym  # noqa: F401  (registers the ids)
    from fawtgym.envs.hover_batch_env import HoverBatchEnv

    kw = dict(sensors="mocap_imu", control_rate=250.0, physics_rate=physics_rate)
    makers = [lambda: HoverEnv(**kw), lambda: gym.make("fawtgym/Hover-v0", **kw)]
    makers += [lambda n=n: HoverBatchEnv(n, **kw) for n in (1, 2, 5)]
    makers += [lambda: gym.make_vec("fawtgym/Hover-v0", num_envs=3, **kw)]
    messages = set()
    for make in makers:
        with pytest.raises(ValueError) as got:
            make()
        assert type(got.value) is ValueError
        messages.add(str(got.value))
    (msg,) = messages  # the same message everywhere
    assert "\n" not in msg and "'mocap_imu'" in msg and "100.0 Hz must divide the control rate 250 Hz" in msg
    assert msg.endswith(f"multiples of 100 Hz that divide the physics rate {physics_rate:g} Hz: {allowed}"), msg
    for rate in allowed.split(", "):  # ... and every control rate it offers works
        HoverEnv(sensors="mocap_imu", control_rate=float(rate), physics_rate=physics_rate).close()


def test_pose_rate_error_when_no_control_rate_fits_the_physics_rate():
    with pytest.raises(ValueError, match=r"'mocap_imu'.*allowed: none with physics_rate 750 Hz"):
        HoverEnv(sensors="mocap_imu", control_rate=250.0, physics_rate=750.0)


def test_mocap_hold_and_bias():
    m, (b, v, r, w) = _noise("mocap_imu", 1 / 500, n=2000)
    pos = m["position"]
    changes = np.flatnonzero(np.any(np.diff(pos, axis=0) != 0, axis=1))
    assert np.all(np.diff(changes) == 5)  # 100 Hz pose in a 500 Hz loop: new sample every 5th step
    gyro_mean = np.mean(m["gyro"] - w, axis=0)
    assert np.linalg.norm(gyro_mean) > 1e-4  # turn-on bias present
    assert np.allclose(np.mean(m["angular_velocity"] - w, axis=0), 0, atol=3e-3)  # estimator rate: no bias


def test_unknown_sensor_preset_and_bad_field():
    with pytest.raises(ValueError, match="valid"):
        make_sensor_spec("lidar")
    with pytest.raises(ValueError, match="position_sigma"):
        make_sensor_spec({"base": "none", "position_sigma": -1.0})
    with pytest.raises(ValueError,
                       match=r"'gyro_density' must be a finite real number in \[0, 10\] \(rad/s\)/sqrt\(Hz\), got 'a'"):
        make_sensor_spec({"base": "mocap_imu", "gyro_density": "a"})
    with pytest.raises(ValueError, match=r"unknown sensor field\(s\) \['lidar_rate'\]; valid: \['base', 'name'"):
        make_sensor_spec({"base": "none", "lidar_rate": 10.0})
    with pytest.raises(ValueError, match="pose_rate"):
        make_sensor_spec({"base": "none", "pose_rate": True})


def _measure_errors(n):
    from fawtgym.envs.sensors_batch import BatchSensorModel

    model = BatchSensorModel("mocap_imu", 0.01, n)
    good = [np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)),
            np.zeros((n, 3))]
    out = []
    nan = np.zeros((n, 3))
    nan[-1, 1] = np.nan
    for k, bad in ((1, np.zeros((n, 2))), (3, np.zeros((n, 3))), (5, np.full((n, 3), "a")), (2, np.ones((n, 3)) * 1j),
                   (4, nan)):
        args = list(good)
        args[k] = bad
        with pytest.raises(ValueError) as err:
            model.measure(*args)
        out.append(str(err.value).replace(f"N = {n}", "N").replace(f"({n}, ", "(N, "))
    return out


def test_bad_sensor_input_gives_the_same_error_at_every_n():
    one = _measure_errors(1)
    assert one == _measure_errors(3)
    assert "rotation (N, 3, 3)" in one[0] and "acceleration must be an array of real numbers" in one[2]
    assert "sensor measurement is not finite" in one[4]


def test_batch_row_equals_the_single_model():
    """The single model is the batch law at N = 1: same generator, same numbers, bit for bit."""
    from fawtgym.envs.sensors_batch import BatchSensorModel

    single, batch = SensorModel(make_sensor_spec("mocap_imu"), 0.002), BatchSensorModel("mocap_imu", 0.002, 1)
    single.reset(np.random.default_rng(4))
    rng = np.random.default_rng(4)
    batch.set_noise_rng(rng)
    batch.reset_rows(np.zeros(1, dtype=np.intp), [rng])
    state = np.random.default_rng(0)
    for k in range(12):
        b, v, w, a = (state.normal(size=3) for _ in range(4))
        r = np.eye(3)
        m1 = single.measure(k * 0.002, b, v, r, w, a)
        mb = batch.measure(np.array([k * 0.002]), b[None], v[None], r[None], w[None], a[None])
        for key in m1:
            if key != "time":
                np.testing.assert_array_equal(m1[key], mb[key][0])


def test_reward_bounded_and_decreasing_with_error():
    env = HoverEnv(init_noise=0.0)
    env.reset(seed=0)
    r0 = env.step(env.hover_action())[1]
    env.reset(seed=0, options={"setpoint": env.setpoint + np.array([0.5, 0.0, 0.0])})
    env.setpoint = env.setpoint - np.array([0.5, 0.0, 0.0])  # now 0.5 m off
    r1 = env.step(env.hover_action())[1]
    assert 0 < r1 < r0 <= 1


@pytest.mark.parametrize("preset", ["none", "seed000", "mocap_imu"])
def test_measurement_equals_the_sensor_equations(preset):
    """measure() (the compiled law at N = 1) against the sensor equations written with numpy, same random draws."""
    from fawtgym.core.measurement import EARTH_FIELD_NED
    from fawtgym.core.so3 import exp_so3

    dt = 0.01
    model = SensorModel(make_sensor_spec(preset), dt)
    model.reset(np.random.default_rng(3))
    twin = np.random.default_rng(3)
    spec = model.spec
    gb = twin.normal(0.0, spec.gyro_bias_sigma, 3) if spec.gyro_bias_sigma else np.zeros(3)
    ab = twin.normal(0.0, spec.accel_bias_sigma, 3) if spec.accel_bias_sigma else np.zeros(3)
    rng = np.random.default_rng(7)
    pose = None
    for k in range(6):
        b, v, w, a = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        r = exp_so3(rng.normal(size=3))
        m = model.measure(k * dt, b, v, r, w, a)
        f_sp = r.T @ (a - np.array([0.0, 0.0, 9.80665]))
        mag = r.T @ EARTH_FIELD_NED
        if not model.noisy:
            want = {"position": b, "velocity": v, "attitude": r, "angular_velocity": w, "gyro": w,
                    "specific_force": f_sp, "magnetometer": mag}
        else:
            n = twin.normal(size=18)
            if pose is None or k % model.pose_every == 0:
                pose = (b + model.sig_pos * n[0:3], v + model.sig_vel * n[3:6], r @ exp_so3(model.sig_att * n[6:9]))
            want = {"position": pose[0], "velocity": pose[1], "attitude": pose[2],
                    "angular_velocity": w + model.sig_rate * n[9:12],
                    "specific_force": f_sp + ab + model.sig_acc * n[12:15],
                    "gyro": w + gb + model.sig_gyro * n[15:18],
                    "magnetometer": mag + spec.mag_sigma * twin.normal(size=3)}
        for key, value in want.items():  # two implementations of one law (tests/_tolerance.py)
            assert_same_law(m[key], value, what=key)
        assert float(m["time"]) == pytest.approx(k * dt)


def test_measure_rows_is_the_law_on_those_rows_with_their_own_noise():
    """measure_rows (the first sample of restarted rows) gives each row what a one-row model with that row's
    generators gives, bit for bit, and leaves the other rows alone (their next full step is unchanged)."""
    from fawtgym.envs.sensors_batch import BatchSensorModel

    def model(n, first_seed=10):
        m = BatchSensorModel("mocap_imu", 0.002, n)
        m.set_noise_rng(np.random.default_rng(99))
        m.reset_rows(np.arange(n), [np.random.default_rng(first_seed + i) for i in range(n)])
        return m

    state = np.random.default_rng(1)
    t = np.zeros(3)
    b, v, w, a = (state.normal(size=(3, 3)) for _ in range(4))
    r = np.tile(np.eye(3), (3, 1, 1))
    batch, ref = model(3), model(3)
    rows = np.array([2, 0])
    got = batch.measure_rows(rows, [np.random.default_rng(7), np.random.default_rng(8)], t[rows], b[rows], v[rows],
                             r[rows], w[rows], a[rows])
    for j, row in enumerate(rows.tolist()):
        one = model(1, first_seed=10 + row)  # the row's turn-on biases
        one.set_noise_rng(np.random.default_rng(7 + j))
        want = one.measure(t[:1], b[row:row + 1], v[row:row + 1], r[row:row + 1], w[row:row + 1], a[row:row + 1])
        for key in want:
            np.testing.assert_array_equal(got[key][j], want[key][0], err_msg=f"{key} row {row}")
    m1, m2 = batch.measure(t, b, v, r, w, a), ref.measure(t, b, v, r, w, a)
    for key in m1:
        np.testing.assert_array_equal(m1[key][1], m2[key][1], err_msg=key)
