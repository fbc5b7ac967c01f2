"""GESO exact discretization, batch behaviour and estimation on both channels (geso_quadrotor_shi2018.txt)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal
from _tolerance import assert_same_law
from scipy.integrate import solve_ivp

from fawtgym.core.so3 import cross, exp_so3
from fawtgym.observers import make_observer
from fawtgym.observers.geso import GesoFilter

G = 9.80665
J = np.diag([0.015, 0.017, 0.028])
MASS = 1.2


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_zoh_matches_continuous_observer_for_piecewise_constant_inputs(order):
    rng = np.random.default_rng(order)
    filt = GesoFilter(order, 20.0)
    dt, steps = 0.01, 25
    u = rng.normal(size=steps)
    y = rng.normal(size=steps)
    x_d = np.zeros(order + 1)
    x_c = np.zeros(order + 1)
    for k in range(steps):
        x_d = filt.step(x_d, u[k], y[k], dt, "zoh")
        sol = solve_ivp(lambda t, x, k=k: filt.derivative(x, u[k], y[k]), (0.0, dt), x_c, method="DOP853",
                        rtol=1e-12, atol=1e-12)
        x_c = sol.y[:, -1]
    np.testing.assert_allclose(x_d, x_c, rtol=1e-7, atol=1e-7 * np.abs(x_c).max())


@pytest.mark.parametrize("order", [1, 3])
def test_foh_matches_continuous_observer_for_piecewise_linear_y(order):
    rng = np.random.default_rng(10 + order)
    filt = GesoFilter(order, 15.0)
    dt, steps = 0.02, 20
    u = rng.normal(size=steps)
    y = rng.normal(size=steps + 1)
    x_d = np.zeros(order + 1)
    x_c = np.zeros(order + 1)
    for k in range(steps):
        x_d = filt.step(x_d, u[k], y[k], dt, "foh", y_next=y[k + 1])

        def rhs(t, x, k=k):
            return filt.derivative(x, u[k], y[k] + (y[k + 1] - y[k]) * t / dt)

        x_c = solve_ivp(rhs, (0.0, dt), x_c, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
    np.testing.assert_allclose(x_d, x_c, rtol=1e-7, atol=1e-7 * np.abs(x_c).max())


@pytest.mark.parametrize("order", [1, 4])
def test_zoh_equals_scipy_cont2discrete(order):
    filt = GesoFilter(order, 20.0)
    dt = 0.004
    phi, gamma = filt.discretize(dt, "zoh")
    m = filt.f.shape[0]
    ad, bd, *_ = scipy.signal.cont2discrete((filt.f, filt.g, np.eye(m), np.zeros((m, 2))), dt, method="zoh")
    # two implementations of one discretization (tests/_tolerance.py)
    assert_same_law(phi, ad, what="Phi")
    assert_same_law(gamma, bd, what="Gamma")


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("dt", [0.001, 0.004, 0.01, 0.02, 0.1])
def test_discrete_filter_is_stable_at_env_rates(order, dt):
    # the exact discretization keeps every pole at exp(-wb dt) inside the unit circle, for any step
    filt = GesoFilter(order, 20.0)
    phi = filt.discretize(dt)[0]
    # repeated poles: eigenvalues of a Jordan block are ill-conditioned, so check the norm of Phi^k decays
    pk = np.linalg.matrix_power(phi, 200)
    assert np.linalg.norm(pk) < 1e3 * np.exp(-20.0 * dt * 200) * (200 ** order + 1) + 1e-12
    assert np.all(np.isfinite(phi))


@pytest.mark.parametrize("hold", ["zoh", "foh"])
@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_constant_disturbance_is_recovered_exactly(order, hold):
    # torque channel at 100 Hz: a constant disturbance balanced by the input keeps J Omega constant
    tau_d = np.array([0.03, -0.02, 0.01])
    obs = make_observer("geso", MASS, J, order=order, bandwidth=20.0, channels="torque", hold=hold)
    w = np.zeros((1, 3))
    obs.reset({"angular_velocity": w})
    for _ in range(300):
        est = obs.update({"angular_velocity": w}, [0.0], -tau_d, 0.01)
    np.testing.assert_allclose(est.torque[0], tau_d, atol=1e-9)
    assert np.allclose(est.force, 0.0)


def _rigid_body_run(obs, steps=400, dt=0.004, n=1, seed=0):
    """Exact-enough rigid body with slowly varying disturbances; returns (estimates, truths) per step."""
    rng = np.random.default_rng(seed)
    sub = 4
    h = dt / sub
    j_inv = np.linalg.inv(J)
    R = exp_so3(rng.normal(scale=0.3, size=(n, 3)))
    w = rng.normal(scale=0.3, size=(n, 3))
    v = rng.normal(scale=0.5, size=(n, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(n, 3))

    def dist(t):
        return 0.4 * np.sin(1.5 * t + phase) + 0.2, 0.02 * np.cos(2.0 * t + phase) - 0.01

    meas = {"velocity": v, "attitude": R, "angular_velocity": w}
    obs.reset(meas)
    out = []
    t = 0.0
    for k in range(steps):
        f = MASS * G * (1.0 + 0.1 * np.sin(3.0 * k * dt)) * np.ones(n)
        tau = 0.01 * np.sin(2.0 * k * dt + np.arange(3)) - 0.05 * w
        for _ in range(sub):  # RK2 substeps, inputs held
            phi, td = dist(t + h / 2)
            a = G * np.array([0, 0, 1.0]) - (f[:, None] * R[..., :, 2]) / MASS + phi / MASS
            wd = (cross(w @ J.T, w) + tau + td) @ j_inv.T
            w_mid = w + h / 2 * wd
            wd = (cross(w_mid @ J.T, w_mid) + tau + td) @ j_inv.T
            R = R @ exp_so3(h * w_mid)
            v, w = v + h * a, w + h * wd
            t += h
        est = obs.update({"velocity": v, "attitude": R, "angular_velocity": w}, f, tau, dt)
        out.append((est, dist(t)))
    return out


def _tail_errors(hold, order, dt=0.004):
    obs = make_observer("geso", MASS, J, order=order, bandwidth=25.0, hold=hold)
    run = _rigid_body_run(obs, steps=int(round(1.2 / dt)), dt=dt)
    tail = run[len(run) // 2:]
    return (max(np.abs(e.force - tr[0]).max() for e, tr in tail), max(np.abs(e.torque - tr[1]).max() for e, tr in tail))


def test_both_channels_track_time_varying_disturbances():
    # force amplitude 0.4 N at 1.5 rad/s, torque 0.02 N m at 2 rad/s, inputs varying, 250 Hz updates
    e1, e3 = _tail_errors("foh", 1), _tail_errors("foh", 3)
    assert e3[0] < 0.004 and e3[1] < 1e-4  # GESO-3 at 25 rad/s: 1 % and 0.5 % of the amplitudes
    # the higher order is the more accurate one (eq. 38), on both channels
    assert e3[0] < e1[0] / 10 and e3[1] < e1[1] / 10
    # literal ZOH (y held at the start of the step) works too but lags by dt/2: less accurate than FOH
    z3 = _tail_errors("zoh", 3)
    assert z3[0] < 0.03 and z3[1] < 3e-4
    assert z3[0] > 2 * e3[0] and z3[1] > 2 * e3[1]


@pytest.mark.parametrize("hold", ["zoh", "foh"])
def test_batch_equals_separate_runs(hold):
    n = 4
    rng = np.random.default_rng(3)
    R = exp_so3(rng.normal(scale=0.3, size=(n, 3)))
    w = rng.normal(scale=0.3, size=(n, 3))
    v = rng.normal(scale=0.5, size=(n, 3))
    guess = rng.normal(size=(n, 3))
    obs_b = make_observer("geso", MASS, J, order=2, hold=hold)
    obs_b.reset({"velocity": v, "attitude": R, "angular_velocity": w}, force=guess, torque=np.zeros((n, 3)))
    singles = [make_observer("geso", MASS, J, order=2, hold=hold) for _ in range(n)]
    for i, o in enumerate(singles):
        o.reset({"velocity": v[i], "attitude": R[i], "angular_velocity": w[i]}, force=guess[i])
    steps = 50
    got, want = [], []
    for _ in range(steps):
        v = v + 0.01 * rng.normal(size=(n, 3))
        w = w + 0.01 * rng.normal(size=(n, 3))
        R = R @ exp_so3(0.01 * w)
        f = rng.uniform(5, 15, size=n)
        tau = rng.normal(scale=0.01, size=(n, 3))
        eb = obs_b.update({"velocity": v, "attitude": R, "angular_velocity": w}, f, tau, 0.01)
        want.append((eb.force, eb.torque, eb.states["velocity"]))
        es = [o.update({"velocity": v[i], "attitude": R[i], "angular_velocity": w[i]}, f[i], tau[i], 0.01)
              for i, o in enumerate(singles)]
        got.append(tuple(np.concatenate(x) for x in zip(*((e.force, e.torque, e.states["velocity"]) for e in es),
                                                         strict=True)))
    # the batch and the N = 1 observers are ONE code path (N = 1 is a batch of one; rows never interact): each
    # row of the batch is bitwise its one-row run (tests/_tolerance.py, case 1), on every step
    got, want = np.array(got), np.array(want)
    for j, what in enumerate(("force", "torque", "velocity")):
        np.testing.assert_array_equal(got[:, j], want[:, j], err_msg=f"{what}: batch row != its one-row observer")
    assert eb.force.shape == (n, 3) and not np.allclose(eb.force[0], eb.force[1])


def test_update_errors_are_clear():
    obs = make_observer("geso", MASS, J)
    meas = {"velocity": np.zeros(3), "attitude": np.eye(3), "angular_velocity": np.zeros(3)}
    with pytest.raises(RuntimeError, match="before reset"):
        obs.update(meas, 10.0, np.zeros(3), 0.01)
    obs.reset(meas)
    with pytest.raises(ValueError, match="dt"):
        obs.update(meas, 10.0, np.zeros(3), -0.01)
    with pytest.raises(ValueError, match="velocity"):
        obs.update({"attitude": np.eye(3), "angular_velocity": np.zeros(3)}, 10.0, np.zeros(3), 0.01)
    with pytest.raises(ValueError, match="non-finite"):
        obs.update({**meas, "angular_velocity": np.array([np.nan, 0, 0])}, 10.0, np.zeros(3), 0.01)
    with pytest.raises(ValueError, match="batch"):
        obs.update(meas, np.ones(3), np.zeros((3, 3)), 0.01)
    with pytest.raises(ValueError, match="thrust"):
        obs.update(meas, np.inf, np.zeros(3), 0.01)
    est = obs.update(meas, MASS * G, np.zeros(3), 0.01)
    assert est.force.shape == (1, 3) and est.states["force_derivatives"].shape == (1, 2, 3)
