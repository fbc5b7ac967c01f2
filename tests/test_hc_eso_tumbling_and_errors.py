"""HC-ESO on SO(3) as the env uses it: on the hover env (a batch of copies gives each row the N = 1 numbers
bitwise: one kernel, rows independent), on a tumbling body with a time-varying disturbance and varying dt (1..3
substeps), and its errors: dt bounds, the substep cap, an absurd sample (held over the next step) that diverges
the estimate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _env_helpers import px4_hover_sequence

import fawtgym  # noqa: F401  (registers the env ids)
from fawtgym.core.measurement import EARTH_FIELD_NED, batch_measurement
from fawtgym.core.so3 import cross, exp_so3
from fawtgym.observers import make_observer

G = 9.80665
J_QUAD = np.diag([0.015, 0.016, 0.026])


@pytest.fixture(scope="module")
def env_sequence():
    """1000 steps (10 s at 100 Hz) of the hover env in the fawt-50 wind under PX4 control, with its IMU."""
    return px4_hover_sequence(seed=3)


def _three(meas):
    return {k: np.repeat(v, 3, 0) for k, v in batch_measurement(meas).items()}


@pytest.mark.parametrize("kw", [{}, {"vectors": "attitude"}, {"rate_key": "gyro", "max_step": 0.004}])
def test_on_the_env_batch_rows_equal_single(env_sequence, kw):
    first, steps, preset, dt = env_sequence
    one = make_observer("hc_eso", preset.mass, preset.inertia_matrix, **kw)
    three = make_observer("hc_eso", preset.mass, preset.inertia_matrix, **kw)
    one.reset(first)
    three.reset(_three(first))
    err = []
    for meas, thrust, torque, truth in steps:
        a = one.update(meas, thrust, torque, dt)
        b = three.update(_three(meas), np.repeat(thrust, 3), np.repeat(np.atleast_2d(torque), 3, 0), dt)
        np.testing.assert_array_equal(b.torque, np.repeat(a.torque, 3, 0))
        for key in ("attitude", "angular_velocity", "sigma"):
            np.testing.assert_array_equal(b.states[key], np.repeat(a.states[key], 3, 0), err_msg=key)
        err.append(np.abs(a.torque[0] - truth["torque"]).max())
    # a real estimation run: the estimate follows the wind torque in the last 2 s
    assert max(err[-200:]) < 0.5 * max(np.abs(s[3]["torque"]).max() for s in steps[-200:]) + 1e-3


def _meas(r, w, rng, noise):
    rt = np.swapaxes(r, -1, -2)
    f = -G * rt[..., :, 2] + noise * rng.uniform(-1, 1, 3)
    m = rt @ EARTH_FIELD_NED + 0.1 * noise * rng.uniform(-1, 1, 3)
    wm = w + noise * rng.uniform(-1, 1, 3)
    return {"specific_force": f, "magnetometer": m, "angular_velocity": wm, "gyro": wm.copy(), "attitude": r,
            "position": np.zeros(3), "velocity": np.zeros(3), "time": 0.0}


def test_tumbling_body_with_varying_dt():
    """1200 steps of a tumbling body with a time-varying torque disturbance, IMU/gyro noise and dt varying so that
    1..3 substeps are taken: the torque estimate converges from 0.02 N m off to within 25 % of |tau_d|."""
    rng = np.random.default_rng(11)
    r = exp_so3(np.array([0.3, -0.2, 2.0]))
    w = np.array([0.4, -0.3, 0.8])
    j_inv = np.linalg.inv(J_QUAD)
    obs = make_observer("hc_eso", 1.0, J_QUAD, morse_gains=(4.0, 2.5, 1.0), k_sigma=20.0, k_psi=12.0)
    obs.reset(_meas(r, w, rng, 0.02), torque=[0.01, 0.0, -0.01])
    dts = (0.001, 0.004, 0.0075, 0.012, 0.01)
    t = 0.0
    err = []
    for k in range(1200):
        dt = dts[k % len(dts)]
        tau = -0.08 * w + 0.01 * np.array([math.sin(3 * t), 0.0, math.cos(2 * t)])
        tau_d = np.array([0.03 * math.sin(0.5 * t), 0.02, -0.015 * math.cos(0.3 * t)])
        for _ in range(4):
            w = w + dt / 4 * ((cross(w[None] @ J_QUAD.T, w[None])[0] + tau + tau_d) @ j_inv.T)
            r = r @ exp_so3(dt / 4 * w)
        t += dt
        a = obs.update(_meas(r, w, rng, 0.02), 0.0, tau, dt)
        err.append(np.abs(a.torque[0] - tau_d).max())
    assert max(err[-100:]) < 0.25 * 0.03 < err[0]


def _hover(n):
    r = np.repeat(exp_so3(np.array([[0.05, -0.02, 0.3]])), n, 0)
    return _meas(r, np.zeros((n, 3)), np.random.default_rng(0), 0.0) | {
        "position": np.zeros((n, 3)), "velocity": np.zeros((n, 3)), "time": np.zeros(n)}


@pytest.mark.parametrize("n", [1, 3])
def test_absurd_sample_diverges_on_the_next_update_and_keeps_the_state(n):
    """The sample of an update is held over the next one (eq. 30 integrated with the previous sample): a finite
    but absurd rate (1e200 rad/s) is accepted, and the next update's estimate diverges: FloatingPointError naming
    the observer and the channel, the same text at every N, and the state is left as it was."""
    obs, twin = make_observer("hc_eso", 1.0, J_QUAD), make_observer("hc_eso", 1.0, J_QUAD)
    good = _hover(n)
    bad = {**good, "angular_velocity": good["angular_velocity"].copy()}
    bad["angular_velocity"][0] = 1e200
    for o in (obs, twin):
        o.reset(good)
        o.update(bad, np.zeros(n), np.zeros((n, 3)), 0.01)
    with np.errstate(all="ignore"), pytest.raises(FloatingPointError, match=r"^hc_eso: the \w+ estimate diverged"):
        obs.update(good, np.zeros(n), np.zeros((n, 3)), 0.01)
    with np.errstate(all="ignore"), pytest.raises(FloatingPointError) as again:
        obs.update(good, np.zeros(n), np.zeros((n, 3)), 0.01)
    with np.errstate(all="ignore"), pytest.raises(FloatingPointError) as other:
        twin.update(good, np.zeros(n), np.zeros((n, 3)), 0.01)
    assert str(again.value) == str(other.value)  # the failed update changed nothing


@pytest.mark.parametrize("n", [1, 3])
def test_dt_bounds_and_substep_cap(n):
    obs = make_observer("hc_eso", 1.0, J_QUAD)
    obs.reset(_hover(n))
    for dt in (1e6, obs.max_dt * 1.01):  # 1e6 s used to run 2e8 substeps
        with pytest.raises(ValueError, match=r"hc_eso: dt must be .* \(0, 0.1\]"):
            obs.update(_hover(n), np.zeros(n), np.zeros((n, 3)), dt)
    obs.update(_hover(n), np.zeros(n), np.zeros((n, 3)), obs.max_dt)
    with pytest.raises(ValueError, match="max_step"):
        make_observer("hc_eso", 1.0, J_QUAD, max_step=1e-6)


@pytest.mark.parametrize("n", [1, 3])
def test_free_fall_sample_is_refused(n):
    obs = make_observer("hc_eso", 1.0, J_QUAD)
    obs.reset(_hover(n))
    bad = {**_hover(n), "specific_force": np.zeros((n, 3))}
    with pytest.raises(ValueError, match=r"^hc_eso: row 0: specific force has \(near\) zero length"):
        obs.update(bad, np.zeros(n), np.zeros((n, 3)), 0.01)
