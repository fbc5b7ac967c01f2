"""Quaternion backstepping controller of geso_quadrotor_shi2018.txt Sec. V (agents/backstepping_quat.py)."""

from __future__ import annotations

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.agents.backstepping_quat import (
    QuaternionBackstepping,
    euler_rates_to_body,
    euler_to_quat,
    quat_conjugate,
    quat_derivative,
    quat_multiply,
)
from fawtgym.core.frames import euler_to_rot, quat_to_rot, rot_to_quat
from fawtgym.core.so3 import cross, exp_so3, vee

J = np.diag([1.335e-2, 1.335e-2, 2.465e-2])


def test_quaternion_helpers_agree_with_rotation_matrices():
    rng = np.random.default_rng(0)
    ra, rb = exp_so3(rng.normal(size=(6, 3))), exp_so3(rng.normal(size=(6, 3)))
    qa, qb = rot_to_quat(ra), rot_to_quat(rb)
    # quaternion and matrix forms: two implementations of one rotation law (tests/_tolerance.py), unit scale
    assert_same_law(quat_to_rot(quat_multiply(qa, qb)), ra @ rb, scale=1.0, what="product")
    assert_same_law(quat_to_rot(quat_conjugate(qa)), np.swapaxes(ra, -1, -2), scale=1.0, what="conjugate")
    e = rng.uniform(-1.2, 1.2, size=(6, 3))
    assert_same_law(quat_to_rot(euler_to_quat(e)), euler_to_rot(e[:, 0], e[:, 1], e[:, 2]), scale=1.0, what="euler")
    a, b = rng.normal(size=(6, 3)), rng.normal(size=(6, 3))
    scale = (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)).max()
    assert_same_law(cross(a, b), np.cross(a, b), scale=scale, what="core.so3.cross")
    # eq. 5: q' = 1/2 q (x) [0, w] is the body-rate kinematics R' = R w^
    w = rng.normal(size=(6, 3))
    h = 1e-6
    dq = quat_derivative(qa, w)
    dr = (quat_to_rot(qa + h * dq) - quat_to_rot(qa - h * dq)) / (2 * h)
    np.testing.assert_allclose(vee(np.swapaxes(ra, -1, -2) @ dr), w, atol=1e-6)


def test_euler_rates_to_body_matches_rotation_derivative():
    rng = np.random.default_rng(1)
    e = rng.uniform(-1.0, 1.0, size=(5, 3))
    de = rng.normal(size=(5, 3))
    h = 1e-6
    r = euler_to_rot(*e.T)
    dr = (euler_to_rot(*(e + h * de).T) - euler_to_rot(*(e - h * de).T)) / (2 * h)
    np.testing.assert_allclose(euler_rates_to_body(e, de), vee(np.swapaxes(r, -1, -2) @ dr), atol=1e-7)


def _closed_loop(ctrl, d_fn, dhat_fn, t_end=1.6, dt=1e-3, j_true=J):
    q = np.array([[1.0, 0.0, 0.0, 0.0]])
    w = np.zeros((1, 3))
    q_d = euler_to_quat(np.radians([[30.0, 15.0, 25.0]]))
    j_inv = np.linalg.inv(j_true)
    for k in range(int(t_end / dt)):
        t = k * dt
        u = ctrl.torque(q, w, q_d, np.zeros((1, 3)), np.zeros((1, 3)), disturbance=dhat_fn(t))
        for _ in range(2):
            w_dot = (u + d_fn(t) - cross(w, w @ j_true.T)) @ j_inv.T
            q = q + dt / 2 * quat_derivative(q, w)
            w = w + dt / 2 * w_dot
            q /= np.linalg.norm(q)
    return ctrl.errors(q, w, q_d, np.zeros((1, 3)))


def test_backstepping_converges_and_feedforward_cancels_a_known_disturbance():
    ctrl = QuaternionBackstepping(J)  # K1 = 11.5 I, K2 = 16.2 I (Sec. VI-A)
    d = np.array([[4.0, 4.0, 4.0]])
    # exact feedforward of the disturbance: the set-point is reached (to integration error)
    q_e, w_e, _ = _closed_loop(ctrl, lambda t: d, lambda t: d)
    assert np.linalg.norm(q_e[0, 1:]) < 1e-4 and np.linalg.norm(w_e) < 1e-3
    # without feedforward: a constant offset remains, as the paper's "without GESO" runs
    q_e0, _, _ = _closed_loop(ctrl, lambda t: d, lambda t: np.zeros((1, 3)))
    assert np.linalg.norm(q_e0[0, 1:]) > 0.01


def test_bad_gains_raise():
    with pytest.raises(ValueError, match="K1"):
        QuaternionBackstepping(J, k1=-1.0)
    with pytest.raises(ValueError, match="K2"):
        QuaternionBackstepping(J, k2=[1.0, 2.0])
    with pytest.raises(ValueError, match="inertia"):
        QuaternionBackstepping(np.diag([1.0, -1.0, 1.0]))
    ctrl = QuaternionBackstepping(J)
    with pytest.raises(ValueError, match="non-finite"):
        ctrl.torque([[1.0, 0, 0, 0]], [[np.nan, 0, 0]], [[1.0, 0, 0, 0]], np.zeros((1, 3)), np.zeros((1, 3)))
