"""Aerodynamic wrench (envs/aero.py): signs, zeros, frames, calibration, a loop reference, bad input."""

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.frames import FAWT_HOVER_POINT_NED, euler_to_rot
from fawtgym.envs.aero import AeroModel, calibrated_rotor_drag, hover_drag, hover_tilt_deg
from fawtgym.envs.vehicles import VEHICLE_NAMES, make_vehicle
from fawtgym.envs.wind import FawtWind

S500 = make_vehicle("s500")


def _args(n=1, wind=(0.0, 0.0, 0.0), yaw=0.0, omega=None, v=(0.0, 0.0, 0.0), rate=(0.0, 0.0, 0.0)):
    r = np.broadcast_to(euler_to_rot(0.0, 0.0, yaw), (n, 3, 3)).copy()
    w = np.broadcast_to(np.asarray(wind, dtype=float), (n, 5, 3)).copy()
    om = np.full((n, 4), S500.hover_omega if omega is None else omega)
    return r, np.tile(v, (n, 1)).astype(float), np.tile(rate, (n, 1)).astype(float), om, w


def _reference(preset, r, v, rate, omega, wind):
    """Straightforward per-vehicle, per-rotor loop of the model in the aero module docstring."""
    e3 = np.array([0.0, 0.0, 1.0])
    forces, torques = [], []
    for n in range(v.shape[0]):
        f_b, tau = np.zeros(3), np.zeros(3)
        for i, ri in enumerate(preset.rotor_positions):
            a = r[n].T @ (wind[n, i + 1] - v[n]) - np.cross(rate[n], ri)
            fi = preset.rotor_drag * omega[n, i] * np.array([a[0], a[1], 0.0])
            f_b += fi
            tau += np.cross(ri, fi) + preset.rolling_moment * omega[n, i] * np.cross(a, e3)
        c = np.asarray(preset.cop_offset)
        a0 = r[n].T @ (wind[n, 0] - v[n]) - np.cross(rate[n], c)
        fb = np.asarray(preset.body_drag) * a0 * np.linalg.norm(a0)
        forces.append(r[n] @ (f_b + fb))
        torques.append(tau + np.cross(c, fb))
    return np.array(forces), np.array(torques)


@pytest.mark.parametrize("name", VEHICLE_NAMES)
def test_matches_loop_reference_on_random_inputs(name):
    preset = make_vehicle(name)
    rng = np.random.default_rng(0)
    n = 7
    r = euler_to_rot(*rng.uniform(-0.5, 0.5, (3, n)))
    v, rate = rng.normal(0, 2, (n, 3)), rng.normal(0, 1, (n, 3))
    omega, wind = rng.uniform(100, 800, (n, 4)), rng.normal(0, 5, (n, 5, 3))
    model = AeroModel(preset)
    f, t = model.wrench(r, v, rate, omega, wind)
    fr, tr = _reference(preset, r, v, rate, omega, wind)
    # the compiled kernel and the numpy per-rotor loop above (BLAS matrix products, numpy.cross, another order of
    # the sums): two implementations of one law (tests/_tolerance.py, case 2)
    assert_same_law(f, fr, what="force")
    assert_same_law(t, tr, what="torque")
    # N = 1 is a batch of one (one kernel, rows never interact): each row of the 7-row call is bitwise the
    # one-row call on that row (tests/_tolerance.py, case 1)
    for i in range(n):
        f1, t1 = model.wrench(r[i:i + 1], v[i:i + 1], rate[i:i + 1], omega[i:i + 1], wind[i:i + 1])
        np.testing.assert_array_equal(f[i:i + 1], f1, err_msg=f"force of row {i}")
        np.testing.assert_array_equal(t[i:i + 1], t1, err_msg=f"torque of row {i}")


def test_zero_wind_zero_motion_gives_zero_wrench():
    f, t = AeroModel(S500).wrench(*_args(3, yaw=0.7))
    assert np.all(f == 0.0) and np.all(t == 0.0)


@pytest.mark.parametrize("yaw", [0.0, 0.9, np.pi / 2, np.pi])
def test_wind_along_x_pushes_along_x(yaw):
    f, _ = AeroModel(S500).wrench(*_args(wind=(8.0, 0.0, 0.0), yaw=yaw))
    assert f[0, 0] > 1.0
    assert abs(f[0, 1]) < 1e-9 * f[0, 0] + 1e-12 and abs(f[0, 2]) < 1e-9


def test_galilean_invariance():
    m = AeroModel(S500)
    f1, t1 = m.wrench(*_args(wind=(5.0, -2.0, 1.0), v=(1.0, 1.0, 0.5)))
    f2, t2 = m.wrench(*_args(wind=(4.0, -3.0, 0.5)))
    np.testing.assert_allclose(f1, f2, atol=1e-12)
    np.testing.assert_allclose(t1, t2, atol=1e-12)


def test_force_grows_with_duty_and_is_a_few_newtons():
    """FAWT mean wind at the hover point, level s500 at hover speed: monotone in duty, 2-8 N at 50-70 %."""
    m = AeroModel(S500)
    drags = []
    for duty in (0.3, 0.4, 0.5, 0.6, 0.7):
        w = FawtWind(duty).mean_wind_at(FAWT_HOVER_POINT_NED)
        f, _ = m.wrench(*_args(wind=w))
        drags.append(f[0, 0])
    assert np.all(np.diff(drags) > 0)
    assert 2.0 < drags[2] < drags[4] < 8.0


def test_calibration_numbers_of_docs():
    """docs/wind.md: s500 2.0 N at 4.2 m/s (Neural-Fly 2-3 N), 4.7 N at 8.5 m/s (6-8 N), 33 deg tilt at FAWT 70 %."""
    d = hover_drag(S500, [4.2, 8.5, 8.213, 10.92])
    np.testing.assert_allclose(d, [2.0, 4.7, 4.5, 6.5], atol=0.1)
    assert hover_tilt_deg(S500, 10.92) == pytest.approx(33.4, abs=0.5)
    assert S500.rotor_drag == pytest.approx(calibrated_rotor_drag(S500), rel=0.02)
    for name in ("pounds_x4", "shi_geso"):
        p = make_vehicle(name)
        assert p.rotor_drag == pytest.approx(calibrated_rotor_drag(p), rel=0.02)


def test_tailwind_pitches_nose_down_headwind_nose_up():
    """Air moving forward past the body (wind from behind): flapping and the raised CoP pitch the nose down."""
    m = AeroModel(S500)
    _, t_tail = m.wrench(*_args(wind=(8.0, 0.0, 0.0)))
    _, t_head = m.wrench(*_args(wind=(-8.0, 0.0, 0.0)))
    assert t_tail[0, 1] < 0 < t_head[0, 1]
    assert abs(t_tail[0, 0]) < 1e-12 and abs(t_tail[0, 2]) < 1e-12


def test_uniform_wind_without_flapping_or_cop_gives_no_torque():
    p = S500.replace(rolling_moment=0.0, cop_offset=(0.0, 0.0, 0.0))
    _, t = AeroModel(p).wrench(*_args(wind=(6.0, -3.0, 0.0)))
    np.testing.assert_allclose(t, 0.0, atol=1e-12)


def test_differential_wind_across_the_discs_yaws_the_vehicle():
    """Stronger wind on the right rotors (1 front-right, 4 rear-right): the drag lever arms give a yaw torque."""
    p = S500.replace(rolling_moment=0.0, cop_offset=(0.0, 0.0, 0.0))
    r, v, rate, om, w = _args(wind=(6.0, 0.0, 0.0))
    w[0, 1, 0] += 2.0
    w[0, 4, 0] += 2.0
    _, t = AeroModel(p).wrench(r, v, rate, om, w)
    # right rotors (y > 0) pushed forward more: r x F about z = x F_y - y F_x < 0
    assert t[0, 2] < -1e-3


def test_rotation_damps_yaw_rate():
    """In still air a yaw rate moves the hubs through the air: rotor drag opposes the rotation."""
    f, t = AeroModel(S500).wrench(*_args(rate=(0.0, 0.0, 2.0)))
    np.testing.assert_allclose(f, 0.0, atol=1e-12)
    assert t[0, 2] < 0


def test_bad_shapes_and_nan_raise():
    m = AeroModel(S500)
    r, v, rate, om, w = _args()
    with pytest.raises(ValueError, match="wind"):
        m.wrench(r, v, rate, om, w[:, :4])
    w[0, 2, 0] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        m.wrench(r, v, rate, om, w)


def test_a_row_alone_equals_the_row_in_a_batch():
    """One kernel loops over the rows: a vehicle's wrench alone (N = 1) is bit for bit its row in a batch of 3."""
    rng = np.random.default_rng(5)
    m = AeroModel(S500)
    r = euler_to_rot(*rng.uniform(-0.6, 0.6, (3, 3)))
    v, rate = rng.normal(0, 2, (3, 3)), rng.normal(0, 1, (3, 3))
    omega, wind = rng.uniform(100, 800, (3, 4)), rng.normal(0, 5, (3, 5, 3))
    fb, tb = m.wrench(r, v, rate, omega, wind)
    for k in range(3):
        f1, t1 = m.wrench(r[k:k + 1], v[k:k + 1], rate[k:k + 1], omega[k:k + 1], wind[k:k + 1])
        np.testing.assert_array_equal(f1[0], fb[k])
        np.testing.assert_array_equal(t1[0], tb[k])


def _bad_input_messages(n):
    m = AeroModel(S500)
    messages = []
    for bad in ("nan", "shape", "complex", "string"):
        r, v, rate, om, w = _args(n)
        if bad == "nan":
            v[-1, 1] = np.inf
        elif bad == "shape":
            om = om[:, :3]
        elif bad == "complex":
            w = w + 0j
        else:
            r = np.full((n, 3, 3), "a")
        with pytest.raises(ValueError) as err:
            m.wrench(r, v, rate, om, w)
        messages.append(str(err.value).replace(f"({n},", "(N,"))
    return messages


def test_bad_input_gives_the_same_error_at_every_n():
    one, three = _bad_input_messages(1), _bad_input_messages(3)
    assert one == three
    assert "not finite" in one[0] and "rotor_speeds (N,4)" in one[1]
    assert "wind must be an array of real numbers" in one[2] and "rotation must be" in one[3]
