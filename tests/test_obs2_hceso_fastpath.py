"""HC-ESO on SO(3): the N = 1 fast path (Python floats) equals the batched numpy path, the reference.

``HcEsoSO3._fast_path = False`` (test-only switch) sends every update through the batched path; both
observers are fed the same sequence and must agree at every step as two implementations of one law
(tests/_tolerance.py: the two paths differ in the order of floating-point sums and in BLAS kernels, and
the Hölder terms of eq. 30 and H(s) of eq. 28 amplify that rounding, cond=HC_ESO_COND).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from _tolerance import HC_ESO_COND, assert_same_law

import fawtgym  # noqa: F401  (registers the env ids)
from fawtgym.agents.backstepping_quat import cross3
from fawtgym.agents.px4_agent import PX4Agent
from fawtgym.core.measurement import EARTH_FIELD_NED
from fawtgym.core.so3 import exp_so3
from fawtgym.core.so3 import exp_so3_floats as _exp_so3_single
from fawtgym.observers import make_observer
from fawtgym.observers import vector_attitude as va
from fawtgym.observers.hc_eso_so3 import (
    HcEsoGains,
    _exp_so3,
    hc_eso_step,
    hc_eso_step_single,
)

G = 9.80665
J_QUAD = np.diag([0.015, 0.016, 0.026])


def _pair(mass, inertia, **kw):
    fast = make_observer("hc_eso", mass, inertia, **kw)
    slow = make_observer("hc_eso", mass, inertia, **kw)
    slow._fast_path = False
    return fast, slow


def _agree(a, b, what, *, steps, inertia, torque_scale=0.0):
    """Fast (a) and batched (b) estimates agree as two implementations of one law (tests/_tolerance.py) after
    ``steps`` updates.  Scales: attitude entries 1; body rates and angular accelerations at least 1 (rad/s,
    rad/s^2: the order of the rates and accelerations in these runs) or their own size; sigma at least
    ``torque_scale`` / J (the largest torque acting in the run); the torque estimate J sigma at J times the
    sigma scale; the force, zero in both (HC-ESO estimates torque only), exactly."""
    j = np.diag(np.asarray(inertia, dtype=float))
    assert set(a.states) == set(b.states) == {"attitude", "angular_velocity", "sigma"}
    w_scale = max(1.0, np.abs(b.states["angular_velocity"]).max())
    sigma_scale = max(1.0, np.abs(b.states["sigma"]).max(), torque_scale / j.min())
    law = dict(steps=steps, cond=HC_ESO_COND)
    assert_same_law(a.states["attitude"], b.states["attitude"], scale=1.0, what=f"{what}: attitude", **law)
    assert_same_law(a.states["angular_velocity"], b.states["angular_velocity"], scale=w_scale,
                    what=f"{what}: angular_velocity", **law)
    assert_same_law(a.states["sigma"], b.states["sigma"], scale=sigma_scale, what=f"{what}: sigma", **law)
    assert_same_law(a.torque, b.torque, scale=j.max() * sigma_scale, what=f"{what}: torque", **law)
    assert_same_law(a.force, b.force, scale=0.0, what=f"{what}: force", **law)
    for s in (a.states["attitude"], a.states["angular_velocity"], a.states["sigma"], a.torque, a.force):
        assert s.shape[0] == 1


@pytest.fixture(scope="module")
def env_sequence():
    """1000 steps (10 s at 100 Hz) of the hover env in the fawt-50 wind under PX4 control, with its IMU."""
    env = gym.make("fawtgym/Hover-v0", sensors="mocap_imu", wind="fawt-50")
    u = env.unwrapped
    _, info = env.reset(seed=3)
    agent = PX4Agent.for_env(env)
    agent.reset(info, seed=3)
    seq = [info["measurement"]]
    steps = []
    for _ in range(1000):
        _, _, term, _, info = env.step(agent.act(None, info))
        assert not term, info["failure"]
        ap = info["applied"]
        steps.append((info["measurement"], ap["thrust"], ap["torque"], info["truth"]["torque"]))
    env.close()
    return seq[0], steps, u.preset, u.dt


@pytest.mark.parametrize("kw", [{}, {"vectors": "attitude"}, {"rate_key": "gyro", "max_step": 0.004}])
def test_fast_path_equals_batched_path_on_the_env(env_sequence, kw):
    first, steps, preset, dt = env_sequence
    fast, slow = _pair(preset.mass, preset.inertia_matrix, **kw)
    fast.reset(first)
    slow.reset(first)
    # the largest torque acting in the run: commanded or wind
    torque_scale = max(max(np.abs(s[2]).max(), np.abs(s[3]).max()) for s in steps)
    err = []
    for k, (meas, thrust, torque, truth) in enumerate(steps):
        a = fast.update(meas, thrust, torque, dt)
        assert fast._single is not None, "the env's single-vehicle step must take the fast path"
        b = slow.update(meas, thrust, torque, dt)
        assert slow._single is None
        _agree(a, b, f"step {k}", steps=k + 1, inertia=preset.inertia_matrix, torque_scale=torque_scale)
        err.append(np.abs(a.torque[0] - truth).max())
    # a real estimation run (not two equal failures): the estimate follows the wind torque in the last 2 s
    assert max(err[-200:]) < 0.5 * max(np.abs(s[3]).max() for s in steps[-200:]) + 1e-3
    fast._sync_single()
    for x, y in zip(fast._state + fast._held, slow._state + slow._held, strict=True):
        scale = max(1.0, np.abs(y).max(), torque_scale / np.diag(preset.inertia_matrix).min())
        assert_same_law(x, y, scale=scale, steps=len(steps), cond=HC_ESO_COND, what="state after the run")


def _meas(r, w, rng, noise):
    rt = np.swapaxes(r, -1, -2)
    f = -G * rt[..., :, 2] + noise * rng.uniform(-1, 1, 3)
    m = rt @ EARTH_FIELD_NED + 0.1 * noise * rng.uniform(-1, 1, 3)
    wm = w + noise * rng.uniform(-1, 1, 3)
    return {"specific_force": f, "magnetometer": m, "angular_velocity": wm, "gyro": wm.copy(), "attitude": r,
            "position": np.zeros(3), "velocity": np.zeros(3), "time": 0.0}


def test_fast_path_equals_batched_path_synthetic_with_path_switches():
    """1200 steps of a tumbling body with a time-varying torque disturbance, IMU/gyro noise and dt varying
    so that 1..3 substeps are taken; every 97th step is passed as lists (batched path in both observers), so
    the fast path's float state is written back and read again."""
    rng = np.random.default_rng(11)
    r = exp_so3(np.array([0.3, -0.2, 2.0]))
    w = np.array([0.4, -0.3, 0.8])
    j_inv = np.linalg.inv(J_QUAD)
    fast, slow = _pair(1.0, J_QUAD, morse_gains=(4.0, 2.5, 1.0), k_sigma=20.0, k_psi=12.0)
    m0 = _meas(r, w, rng, 0.02)
    fast.reset(m0, torque=[0.01, 0.0, -0.01])
    slow.reset(m0, torque=[0.01, 0.0, -0.01])
    dts = (0.001, 0.004, 0.0075, 0.012, 0.01)
    t = 0.0
    err = []
    switched = 0
    torque_scale = 0.0
    for k in range(1200):
        dt = dts[k % len(dts)]
        tau = -0.08 * w + 0.01 * np.array([math.sin(3 * t), 0.0, math.cos(2 * t)])
        tau_d = np.array([0.03 * math.sin(0.5 * t), 0.02, -0.015 * math.cos(0.3 * t)])
        torque_scale = max(torque_scale, np.abs(tau).max(), np.abs(tau_d).max())
        for _ in range(4):
            w = w + dt / 4 * ((cross3(w[None] @ J_QUAD.T, w[None])[0] + tau + tau_d) @ j_inv.T)
            r = r @ exp_so3(dt / 4 * w)
        t += dt
        m = _meas(r, w, rng, 0.02)
        if k % 97 == 50:
            m = {key: np.asarray(v).tolist() for key, v in m.items()}
            switched += 1
        a = fast.update(m, 0.0, tau, dt)
        assert (fast._single is None) == (k % 97 == 50)
        b = slow.update(m, 0.0, tau, dt)
        _agree(a, b, f"step {k}", steps=k + 1, inertia=J_QUAD, torque_scale=torque_scale)
        err.append(np.abs(a.torque[0] - tau_d).max())
    assert switched == 12
    assert max(err[-100:]) < 0.25 * 0.03 < err[0]  # a real estimation run: from 0.02 off to within 25 % of |tau_d|


def test_step_function_single_equals_batched():
    rng = np.random.default_rng(5)
    gains = HcEsoGains(alpha=0.7, gamma=3, kappa=0.4, k_sigma=3.0, k_psi=7.0)
    j = np.array([[0.02, 0.001, 0.0], [0.001, 0.03, 0.002], [0.0, 0.002, 0.05]])
    for _ in range(50):
        r_hat, l = exp_so3(rng.normal(size=(1, 3))), np.diag([3.0, 2.0, 1.0]) @ exp_so3(rng.normal(size=(1, 3)))
        w, sg, om, tau = rng.normal(size=(4, 1, 3))
        h = 10 ** rng.uniform(-4, -1.5)
        ref = hc_eso_step(r_hat, w, sg, l, om, tau, j, gains, h)
        got = hc_eso_step_single(r_hat.ravel().tolist(), w[0].tolist(), sg[0].tolist(), l.ravel().tolist(),
                                 om[0].tolist(), tau[0].tolist(), j.ravel().tolist(),
                                 np.linalg.inv(j).ravel().tolist(), gains, h)
        for x, y, what in zip(got, ref, ("R_hat", "Omega_hat", "sigma_hat"), strict=True):
            # one step of eq. 30 in floats and in numpy (tests/_tolerance.py), through J^-1: cond(J)
            assert_same_law(np.reshape(x, y.shape), y, cond=np.linalg.cond(j), what=what)
    # s_L = 0 (L = K R_hat) hits the floor of the Hölder terms in both
    r_hat = exp_so3(np.array([[0.1, 0.2, 0.3]]))
    l = np.diag([3.0, 2.0, 1.0]) @ r_hat
    args = (r_hat, np.zeros((1, 3)), np.zeros((1, 3)), l, np.zeros((1, 3)), np.zeros((1, 3)), j, gains, 0.01)
    ref = hc_eso_step(*args)
    got = hc_eso_step_single(*(np.ravel(a).tolist() for a in args[:6]), j.ravel().tolist(),
                             np.linalg.inv(j).ravel().tolist(), gains, 0.01)
    for x, y, what in zip(got, ref, ("R_hat", "Omega_hat", "sigma_hat"), strict=True):
        assert_same_law(np.reshape(x, y.shape), y, cond=np.linalg.cond(j), what=f"s_L = 0: {what}")


@pytest.mark.parametrize("scale", [0.0, 1e-7, 1e-4, 0.1, 2.0, 3.1])
def test_exp_single_equals_batched(scale):
    x = scale * np.random.default_rng(2).standard_normal(3)
    # two implementations of Rodrigues' formula (tests/_tolerance.py), at the scale of its terms I, theta^, theta^2
    theta = np.linalg.norm(x)
    assert_same_law(np.reshape(_exp_so3_single(*x.tolist()), (3, 3)), _exp_so3(x[None])[0],
                    scale=1.0 + theta + theta**2, what=f"exp, |theta| = {theta:.3g}")
    assert all(map(math.isnan, _exp_so3_single(math.inf, 0.0, 0.0)))


def test_imu_body_vectors_single_equals_batched():
    rng = np.random.default_rng(4)
    for _ in range(20):
        f, m = rng.normal(size=(2, 3))
        # two implementations (floats, numpy) of unit vectors (tests/_tolerance.py); the normalized cross product
        # amplifies rounding by 1 / sin(angle between f and m)
        sin_angle = np.linalg.norm(np.cross(f, m)) / (np.linalg.norm(f) * np.linalg.norm(m))
        assert_same_law(np.reshape(va.imu_body_vectors_single(f.tolist(), m.tolist()), (3, 3)),
                        va.imu_body_vectors(f[None], m[None])[0], scale=1.0, cond=1.0 / sin_angle, what="U^m")
    assert va.imu_body_vectors_single([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]) is None
    assert va.imu_body_vectors_single([0.0, 0.0, -9.8], [0.0, 0.0, 0.0]) is None
    assert va.imu_body_vectors_single([0.0, 0.0, -9.8], [0.0, 0.0, 0.4]) is None


def test_batch_of_two_takes_the_batched_path():
    rng = np.random.default_rng(0)
    r = exp_so3(rng.normal(size=(2, 3)))
    w = rng.normal(size=(2, 3))
    rt = np.swapaxes(r, -1, -2)
    m = {"specific_force": -G * rt[..., :, 2], "magnetometer": rt @ EARTH_FIELD_NED, "angular_velocity": w}
    fast, slow = _pair(1.0, J_QUAD)
    fast.reset(m)
    slow.reset(m)
    for _ in range(3):
        a, b = fast.update(m, np.zeros(2), np.zeros((2, 3)), 0.01), slow.update(m, np.zeros(2), np.zeros((2, 3)), 0.01)
        assert fast._single is None
        np.testing.assert_array_equal(a.torque, b.torque)
        np.testing.assert_array_equal(a.states["attitude"], b.states["attitude"])


def _good():
    r = exp_so3(np.array([0.1, -0.2, 0.3]))
    rt = r.T
    return {"specific_force": -G * rt[:, 2], "magnetometer": rt @ EARTH_FIELD_NED,
            "angular_velocity": np.array([0.1, 0.0, -0.2]), "attitude": r, "time": np.array([0.0])}


_BAD = {
    "batch of two": ({"angular_velocity": np.zeros((2, 3)), "specific_force": np.tile([0.0, 0.0, -G], (2, 1)),
                      "magnetometer": np.tile(EARTH_FIELD_NED, (2, 1)), "attitude": np.tile(np.eye(3), (2, 1, 1))},
                     0.0, np.zeros(3), 0.01),
    "rate of two": ({"angular_velocity": np.zeros((2, 3))}, 0.0, np.zeros(3), 0.01),
    "torque of two": ({}, 0.0, np.zeros((2, 3)), 0.01),
    "torque (1, 1, 3)": ({}, 0.0, np.zeros((1, 1, 3)), 0.01),
    "torque (4,)": ({}, 0.0, np.zeros(4), 0.01),
    "free fall": ({"specific_force": np.zeros(3)}, 0.0, np.zeros(3), 0.01),
    "no magnetometer": ({"magnetometer": None}, 0.0, np.zeros(3), 0.01),
    "nan gyro": ({"angular_velocity": np.array([0.0, np.nan, 0.0])}, 0.0, np.zeros(3), 0.01),
    "inf accel": ({"specific_force": np.array([0.0, 0.0, -np.inf])}, 0.0, np.zeros(3), 0.01),
    "nan thrust": ({}, np.nan, np.zeros(3), 0.01),
    "nan torque": ({}, 0.0, np.array([0.0, np.nan, 0.0]), 0.01),
    "dt zero": ({}, 0.0, np.zeros(3), 0.0),
    "dt nan": ({}, 0.0, np.zeros(3), float("nan")),
    "unused key misshaped": ({"position": np.zeros(4)}, 0.0, np.zeros(3), 0.01),
    "rate (3, 1)": ({"angular_velocity": np.zeros((3, 1))}, 0.0, np.zeros(3), 0.01),
    "attitude (9,)": ({"attitude": np.eye(3).ravel()}, 0.0, np.zeros(3), 0.01),
    "text under an unknown key": ({"note": np.array(["x"])}, 0.0, np.zeros(3), 0.01),
    "time (1, 1)": ({"time": np.zeros((1, 1))}, 0.0, np.zeros(3), 0.01),
    "number as a vector": ({"velocity": 1.0}, 0.0, np.zeros(3), 0.01),
    "collinear vectors": ({"magnetometer": np.array([0.0, 0.0, 0.4]), "specific_force": np.array([0.0, 0.0, -G])},
                          0.0, np.zeros(3), 0.01),
}


#: steps the batched path accepts with vectors="attitude" (the IMU keys are unused there)
_FINE_WITH_ATTITUDE = {"free fall", "no magnetometer", "inf accel", "collinear vectors"}


@pytest.mark.parametrize("vectors", ["imu", "attitude"])
@pytest.mark.parametrize("case", sorted(_BAD))
def test_malformed_steps_raise_the_batched_errors_and_change_nothing(case, vectors):
    change, thrust, torque, dt = _BAD[case]
    bad = {k: v for k, v in {**_good(), **change}.items() if v is not None}
    fast, slow = _pair(1.0, J_QUAD, vectors=vectors)
    fast.reset(_good())
    slow.reset(_good())
    for _ in range(2):  # the fast observer holds its state as floats when the bad step comes
        fast.update(_good(), 0.0, np.zeros(3), 0.01)
        slow.update(_good(), 0.0, np.zeros(3), 0.01)
    assert fast._single is not None
    try:
        ref = slow.update(bad, thrust, torque, dt)
    except ValueError as exc:
        assert not (vectors == "attitude" and case in _FINE_WITH_ATTITUDE), exc
        with pytest.raises(ValueError) as got:
            fast.update(bad, thrust, torque, dt)
        assert str(got.value) == str(exc)
    else:
        assert vectors == "attitude" and case in _FINE_WITH_ATTITUDE
        _agree(fast.update(bad, thrust, torque, dt), ref, case, steps=3, inertia=J_QUAD)
    _agree(fast.update(_good(), 0.0, np.zeros(3), 0.01), slow.update(_good(), 0.0, np.zeros(3), 0.01), case,
           steps=4, inertia=J_QUAD)


@pytest.mark.parametrize("extra, fast_path", [
    ({"time": 0.5}, True), ({"time": np.float64(0.5)}, True), ({"seq": 3}, True), ({"time": np.zeros(1)}, True),
    ({"time": [0.5]}, False), ({"angular_velocity": [0.1, 0.0, -0.2]}, False),
])
def test_which_values_take_the_fast_path(extra, fast_path):
    fast, slow = _pair(1.0, J_QUAD)
    fast.reset(_good())
    slow.reset(_good())
    m = {**_good(), **extra}
    for k in range(3):
        a, b = fast.update(m, 0.0, np.zeros(3), 0.01), slow.update(m, 0.0, np.zeros(3), 0.01)
        assert (fast._single is not None) == fast_path
        _agree(a, b, str(extra), steps=k + 1, inertia=J_QUAD)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # numpy's overflow warnings in the batched path
def test_diverging_state_raises_in_both_paths():
    fast, slow = _pair(1.0, J_QUAD, k_psi=1e160, k_sigma=1e160, max_step=0.01)
    m = {**_good(), "angular_velocity": np.array([50.0, -30.0, 20.0])}
    msgs = []
    for obs in (fast, slow):
        obs.reset(_good())
        done = 0
        with pytest.raises(ValueError, match="HC-ESO state became non-finite") as got:
            while done < 5:
                obs.update(m, 0.0, np.zeros(3), 0.01)
                assert (obs._single is not None) == (obs is fast)
                done += 1
        msgs.append((done, str(got.value)))
    assert msgs[0] == msgs[1] and msgs[0][0] > 0  # same step, same message; the fast one raised in the fast path
