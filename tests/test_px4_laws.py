"""PX4 control laws against hand-computed cases (agents/px4_position/attitude/rate_control, px4_filters)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _tolerance import assert_same_law
from scipy import signal

from fawtgym.agents.px4_attitude_control import AttitudeControl, attitude_error_vector, principal_angle
from fawtgym.agents.px4_filters import Butterworth2, FilteredDerivative, FirstOrderLowPass
from fawtgym.agents.px4_params import PX4Params
from fawtgym.agents.px4_position_control import (
    PositionControl,
    bodyz_to_attitude,
    constrain_xy,
    limit_tilt,
    thrust_to_attitude,
)
from fawtgym.agents.px4_rate_control import RateControl
from fawtgym.core.constants import GRAVITY
from fawtgym.core.frames import euler_to_rot, quat_to_rot, rot_to_quat

G = GRAVITY
Z3 = np.zeros((1, 3))


# ---- position control ---------------------------------------------------------------------------
def test_position_step_gives_hand_computed_thrust() -> None:
    pc = PositionControl(PX4Params(), hover_thrust=0.5)
    thr = pc.update(Z3, Z3, Z3, [[1.0, 0.0, -1.0]], dt=0.01)
    # vel_sp = (0.95, 0, -1.0); acc_sp = (1.8 * 0.95, 0, 4 * -1.0)
    np.testing.assert_allclose(pc.vel_sp, [[0.95, 0.0, -1.0]])
    np.testing.assert_allclose(pc.acc_sp, [[1.71, 0.0, -4.0]])
    # body_z = normalize(-a_x, 0, g); c = (a_z Th/g - Th) / bz_z; thr = bz c => thr_x = a_x Th/g * (a_z/g - 1) * -1
    c = -4.0 * 0.5 / G - 0.5
    expected = np.array([-1.71, 0.0, G]) / G * c
    np.testing.assert_allclose(thr, [expected], rtol=1e-12)
    # integrator: I * err * dt on both axes (no saturation)
    np.testing.assert_allclose(pc.vel_int, [[0.4 * 0.95 * 0.01, 0.0, 2.0 * -1.0 * 0.01]], rtol=1e-12)


def test_velocity_d_term_on_measured_derivative() -> None:
    pc = PositionControl(PX4Params(), hover_thrust=0.5)
    pc.update(Z3, Z3, [[2.0, 0.0, 0.0]], Z3, dt=0.01)
    np.testing.assert_allclose(pc.acc_sp, [[-0.2 * 2.0, 0.0, 0.0]])


def test_tilt_limit_45_deg() -> None:
    pc = PositionControl(PX4Params(), hover_thrust=0.5)
    thr = pc.update(Z3, Z3, Z3, [[100.0, 0.0, 0.0]], dt=0.01)
    assert pc.vel_sp[0, 0] == pytest.approx(12.0)  # MPC_XY_VEL_MAX
    tilt = math.degrees(math.acos(-thr[0, 2] / np.linalg.norm(thr[0])))
    assert tilt == pytest.approx(45.0, abs=1e-9)
    b = limit_tilt(np.array([[0.6, 0.0, 0.8]]), np.array([0.0, 0.0, 1.0]), math.radians(10))
    np.testing.assert_allclose(b, [[math.sin(math.radians(10)), 0.0, math.cos(math.radians(10))]], atol=1e-12)


def _px4_limit_tilt(b: np.ndarray, w: np.ndarray, max_angle: float) -> np.ndarray:
    """PX4's ControlMath::limitTilt written out (acos, clamp, cos/sin of the angle along the rejection)."""
    dot = float(np.clip(b @ w, -1.0, 1.0))
    angle = min(math.acos(dot), max_angle)
    rej = b - dot * w
    if rej @ rej < 1.1920929e-07:
        rej = np.array([1.0, 0.0, 0.0])
    return math.cos(angle) * w + math.sin(angle) * rej / np.linalg.norm(rej)


def test_limit_tilt_is_px4s_formula_inside_and_outside_the_limit() -> None:
    """Within the limit the kernel returns b as it is (PX4's formula is b there, up to its rounding); beyond it, the
    vector at the limit angle in the plane of b and w.  Both agree with PX4's formula to its rounding."""
    rng = np.random.default_rng(3)
    w = np.array([0.0, 0.0, 1.0])
    max_angle = math.radians(45.0)
    b = rng.normal(size=(400, 3))
    b[:, 2] = np.abs(b[:, 2]) + 0.3 * rng.random(400)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    out = limit_tilt(b, w, max_angle)
    inside = b @ w >= math.cos(max_angle)
    assert 50 < inside.sum() < 350  # both branches exercised
    np.testing.assert_array_equal(out[inside], b[inside])
    expected = np.array([_px4_limit_tilt(bi, w, max_angle) for bi in b])
    # PX4's formula rebuilds b from acos(b.w) and r / |r|, |r| = sin(angle) up to the rounding of |b| = 1: its error
    # grows as 1 / |r| near w (tests/_tolerance.py; the vectors are unit, scale 1, a chain of ~10 operations)
    cond = 1.0 / np.linalg.norm(b - np.outer(b @ w, w), axis=1).min()
    assert_same_law(out, expected, scale=1.0, steps=10, cond=cond, what="limit_tilt against PX4's formula")
    tilt = np.degrees(np.arccos(np.clip(out[~inside] @ w, -1, 1)))
    np.testing.assert_allclose(tilt, 45.0, atol=1e-9)


def test_vertical_antiwindup_freezes_integrator_at_thrust_limit() -> None:
    pc = PositionControl(PX4Params(), hover_thrust=0.5)
    # climb at 3 m/s demanded: acc_z = -12 -> collective -1.11 < -THR_MAX => saturated, error <= 0 => frozen
    thr = pc.update(Z3, Z3, Z3, [[0.0, 0.0, -10.0]], dt=0.01)
    assert np.linalg.norm(thr[0]) == pytest.approx(1.0)
    assert pc.vel_int[0, 2] == 0.0
    # descending at 1.5 m/s with a light hover thrust: collective 6 * 0.2/g - 0.2 > -THR_MIN => at the minimum
    pc = PositionControl(PX4Params(), hover_thrust=0.2)
    pc.update(Z3, Z3, Z3, [[0.0, 0.0, 10.0]], dt=0.01)
    assert -pc.thr_sp[0, 2] == pytest.approx(0.12)
    assert pc.vel_int[0, 2] == 0.0
    # unsaturated: integrates
    pc = PositionControl(PX4Params(), hover_thrust=0.5)
    pc.update(Z3, Z3, Z3, [[0.0, 0.0, -0.1]], dt=0.01)
    assert pc.vel_int[0, 2] == pytest.approx(2.0 * -0.1 * 0.01)


def test_horizontal_tracking_antiwindup() -> None:
    pc = PositionControl(PX4Params(), hover_thrust=0.5)
    pc.update(Z3, Z3, Z3, [[100.0, 0.0, 0.0]], dt=0.01)
    acc_x = 1.8 * 12.0
    produced = 0.5 * math.tan(math.radians(45)) * G / 0.5  # thr_x * g / Th at the tilt limit
    expected = (12.0 - 2.0 / 1.8 * (acc_x - produced)) * 0.4 * 0.01
    assert pc.vel_int[0, 0] == pytest.approx(expected, rel=1e-9)
    assert pc.vel_int[0, 0] < 0.4 * 12.0 * 0.01


def test_vertical_priority_keeps_horizontal_margin() -> None:
    pc = PositionControl(PX4Params(), hover_thrust=0.5)
    thr = pc.update(Z3, [[0.0, 0.0, 0.0]], Z3, [[3.0, 0.0, -10.0]], dt=0.01)
    assert np.linalg.norm(thr[0]) == pytest.approx(1.0)
    assert np.linalg.norm(thr[0, :2]) >= 0.3 - 1e-12  # MPC_THR_XY_MARG kept


def test_constrain_xy_cases() -> None:
    v = constrain_xy(np.array([[1.0, 0.0], [3.0, 0.0], [0.0, 0.0], [1.0, 0.0]]),
                     np.array([[0.5, 0.0], [1.0, 0.0], [0.0, 5.0], [0.0, 5.0]]), 2.0)
    np.testing.assert_allclose(v[0], [1.5, 0.0])
    np.testing.assert_allclose(v[1], [2.0, 0.0])
    np.testing.assert_allclose(v[2], [0.0, 2.0])
    np.testing.assert_allclose(v[3], [1.0, math.sqrt(3.0)])  # |v0 + s u1| = 2 with v0 kept


def test_bodyz_to_attitude_and_thrust_to_attitude() -> None:
    r = bodyz_to_attitude(np.array([[0.0, 0.0, 1.0]]), np.array([0.5]))
    np.testing.assert_allclose(r[0], euler_to_rot(0.0, 0.0, 0.5), atol=1e-12)
    thr = np.array([[0.1, -0.05, -0.4]])
    r, c = thrust_to_attitude(thr, np.array([0.2]))
    np.testing.assert_allclose(r[0] @ np.array([0.0, 0.0, -1.0]) * c[0], thr[0], atol=1e-12)
    assert math.atan2(r[0, 1, 0], r[0, 0, 0]) == pytest.approx(0.2, abs=0.02)
    np.testing.assert_allclose(r[0].T @ r[0], np.eye(3), atol=1e-12)


# ---- attitude control ---------------------------------------------------------------------------
def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])


def _px4_quaternion_reference(r: np.ndarray, rd: np.ndarray, gain: np.ndarray, w: float) -> np.ndarray:
    """PX4 v1.13 AttitudeControl::update written with quaternions, for one vehicle (reference)."""
    inv = np.array([1.0, -1.0, -1.0, -1.0])
    q, qd = rot_to_quat(r), rot_to_quat(rd)
    ez, ezd = r[:, 2], rd[:, 2]
    cr = np.cross(ez, ezd)
    qred = np.concatenate([[ez @ ezd + 1.0], cr])
    qred = _quat_mul(qred / np.linalg.norm(qred), q)
    dyaw = _quat_mul(qred * inv, qd)
    dyaw = dyaw if dyaw[0] >= 0 else -dyaw
    qmix = _quat_mul(qred, np.array([math.cos(w * math.acos(min(dyaw[0], 1.0))), 0.0, 0.0,
                                     math.sin(w * math.asin(max(min(dyaw[3], 1.0), -1.0)))]))
    qe = _quat_mul(q * inv, qmix)
    qe = qe if qe[0] >= 0 else -qe
    return 2.0 * qe[1:] * np.array([gain[0], gain[1], gain[2] / w])


def test_attitude_roll_and_yaw_errors_hand_computed() -> None:
    ac = AttitudeControl(PX4Params())
    rate = ac.update(np.eye(3)[None], euler_to_rot(0.2, 0.0, 0.0)[None])
    np.testing.assert_allclose(rate, [[2 * math.sin(0.1) * 6.5, 0.0, 0.0]], atol=1e-12)
    rate = ac.update(np.eye(3)[None], euler_to_rot(0.0, 0.0, 0.3)[None])
    np.testing.assert_allclose(rate, [[0.0, 0.0, 2 * math.sin(0.4 * 0.3 / 2) * 2.8 / 0.4]], atol=1e-12)


def test_attitude_rate_limits_and_yaw_feedforward() -> None:
    ac = AttitudeControl(PX4Params())
    rate = ac.update(np.eye(3)[None].repeat(2, 0), euler_to_rot(np.array([1.5, 0.0]), np.array([0.0, -1.5]), 0.0))
    np.testing.assert_allclose(rate, [[math.radians(220), 0, 0], [0, -math.radians(220), 0]], atol=1e-12)
    rate = ac.update(np.eye(3)[None], np.eye(3)[None], yawspeed_sp=np.array([0.5]))
    np.testing.assert_allclose(rate, [[0.0, 0.0, 0.5]], atol=1e-12)


def test_attitude_matrix_form_equals_px4_quaternion_law() -> None:
    rng = np.random.default_rng(3)
    ac = AttitudeControl(PX4Params(MC_ROLLRATE_MAX=1800, MC_PITCHRATE_MAX=1800, MC_YAWRATE_MAX=1800))
    r = quat_to_rot(rng.normal(size=(50, 4)))
    rd = quat_to_rot(rng.normal(size=(50, 4)))
    # keep the reduced rotation away from the exactly-opposite corner case
    keep = np.einsum("ni,ni->n", r[:, :, 2], rd[:, :, 2]) > -0.95
    got = ac.update(r[keep], rd[keep])
    ref = np.array([_px4_quaternion_reference(a, b, ac.gain * np.array([1, 1, ac.yaw_weight]), ac.yaw_weight)
                    for a, b in zip(r[keep], rd[keep], strict=True)])
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_error_vector_and_principal_angle() -> None:
    r = euler_to_rot(0.0, 0.7, 0.0)[None]
    np.testing.assert_allclose(attitude_error_vector(r), [[0.0, 2 * math.sin(0.35), 0.0]], atol=1e-12)
    half = euler_to_rot(math.pi, 0.0, 0.0)[None]
    np.testing.assert_allclose(np.abs(attitude_error_vector(half)), [[2.0, 0.0, 0.0]], atol=1e-9)
    assert principal_angle(euler_to_rot(0.3, 0.0, 0.0), np.eye(3)) == pytest.approx(0.3)


# ---- rate control --------------------------------------------------------------------------------
def test_rate_pid_hand_computed_and_i_factor() -> None:
    rc = RateControl(PX4Params.s500())
    e = np.array([[1.0, -2.0, 0.5]])
    acc = np.array([[10.0, 0.0, 0.0]])
    tau = rc.update(np.zeros((1, 3)), e, acc, dt=0.004)
    np.testing.assert_allclose(tau, [[0.18 * 1.0 - 0.003 * 10.0, 0.18 * -2.0, 0.2 * 0.5]])
    i_factor = 1.0 - (e / math.radians(400.0)) ** 2
    np.testing.assert_allclose(rc.rate_int, i_factor * np.array([0.15, 0.15, 0.1]) * e * 0.004)
    tau2 = rc.update(np.zeros((1, 3)), e, acc, dt=0.004)
    np.testing.assert_allclose(tau2 - tau, i_factor * np.array([0.15, 0.15, 0.1]) * e * 0.004)


def test_rate_k_gain_scales_pid() -> None:
    rc = RateControl(PX4Params.s500(MC_ROLLRATE_K=2.0))
    tau = rc.update(np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]), np.array([[5.0, 0.0, 0.0]]), dt=0.004)
    assert tau[0, 0] == pytest.approx(2.0 * (0.18 - 0.003 * 5.0))


def test_rate_integrator_limit_and_saturation_freeze() -> None:
    rc = RateControl(PX4Params.s500())
    for _ in range(2000):
        rc.update(np.zeros((1, 3)), np.array([[3.0, -3.0, 3.0]]), np.zeros((1, 3)), dt=0.004)
    np.testing.assert_allclose(rc.rate_int, [[0.3, -0.3, 0.3]])
    rc.reset()
    rc.set_saturation(np.array([[True, False, False]]), np.array([[False, True, False]]))
    rc.update(np.zeros((1, 3)), np.array([[1.0, -1.0, -1.0]]), np.zeros((1, 3)), dt=0.004)
    assert rc.rate_int[0, 0] == 0.0 and rc.rate_int[0, 1] == 0.0  # frozen in the saturated direction
    assert rc.rate_int[0, 2] < 0.0
    rc.update(np.zeros((1, 3)), np.array([[-1.0, 1.0, 0.0]]), np.zeros((1, 3)), dt=0.004)
    assert rc.rate_int[0, 0] < 0.0 and rc.rate_int[0, 1] > 0.0  # unwinding is allowed


def test_laws_reject_bad_dt() -> None:
    with pytest.raises(ValueError, match="dt"):
        RateControl().update(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        PositionControl().update(Z3, Z3, Z3, Z3, dt=float("nan"))
    with pytest.raises(ValueError, match="hover_thrust"):
        PositionControl(hover_thrust=1.5)


# ---- filters ---------------------------------------------------------------------------------------
def test_butterworth_matches_lfilter_and_cutoff_gain() -> None:
    fs, fc = 250.0, 40.0
    f = Butterworth2(fs, fc)
    t = np.arange(2000) / fs
    x = np.sin(2 * math.pi * fc * t)
    f.reset(np.zeros(1))
    y = np.array([f.update(np.array([xi]))[0] for xi in x])
    b, a = signal.butter(2, fc, fs=fs)
    # the filter's update loop and scipy's lfilter: two implementations of one law over 2000 steps (tests/_tolerance.py)
    assert_same_law(y, signal.lfilter(b, a, x), scale=1.0, steps=x.size, what="Butterworth")
    assert np.max(np.abs(y[1000:])) == pytest.approx(1 / math.sqrt(2), rel=0.01)  # -3 dB at the cut-off
    f.reset(np.array([2.0, -1.0]))
    np.testing.assert_allclose(f.update(np.array([2.0, -1.0])), [2.0, -1.0])  # steady state after reset
    assert not Butterworth2(250.0, 0.0).enabled and not Butterworth2(250.0, 200.0).enabled
    with pytest.raises(ValueError, match="cutoff"):
        Butterworth2(250.0, -1.0)


def test_first_order_lowpass_and_derivative() -> None:
    lp = FirstOrderLowPass(5.0)
    lp.reset(np.zeros(1))
    b = 2 * math.pi * 5.0 * 0.01
    np.testing.assert_allclose(lp.update(np.ones(1), 0.01), [b / (1 + b)])
    d = FilteredDerivative(5.0)
    out = [d.update(np.array([0.5 * k * 0.01]), 0.01)[0] for k in range(300)]
    assert out[0] == 0.0
    assert out[-1] == pytest.approx(0.5, rel=1e-6)
