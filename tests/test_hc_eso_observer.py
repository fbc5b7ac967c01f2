"""HC-ESO on SO(3), Prop. 3 eq. 30 (hc_eso_so3_wang2022.txt) as a function and as a registered observer."""

from __future__ import annotations

import numpy as np
import pytest
from _tolerance import HC_ESO_COND, assert_same_law

from fawtgym.core.measurement import EARTH_FIELD_NED
from fawtgym.core.so3 import cross, exp_so3, hat, log_so3, orthogonality_error
from fawtgym.observers import make_observer
from fawtgym.observers import vector_attitude as va
from fawtgym.observers.hc_eso import HcEsoGains, hc_eso_rates, hc_eso_step

G = 9.80665
K = np.array([3.0, 2.0, 1.0])
J_PAPER = np.diag([4.0, 4.0, 10.0])
J_QUAD = np.diag([0.015, 0.015, 0.026])


def test_eq30_produces_the_error_dynamics_eq31():
    # with exact measurements, Psi' = -k_Psi |Psi|^(alpha-1) Psi + sigma_tilde and sigma_tilde' = -k_sigma
    # |Psi|^(2 alpha - 2) Psi (sigma constant) and Q' = Q (R_hat Omega_tilde)^x, checked by central differences
    rng = np.random.default_rng(0)
    n = 4
    gains = HcEsoGains()
    r, r_hat = exp_so3(rng.normal(size=(n, 3))), exp_so3(rng.normal(size=(n, 3)))
    w, w_hat = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    sigma, sigma_hat = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    tau = rng.normal(size=(n, 3))
    j_inv = np.linalg.inv(J_PAPER)
    w_dot = (np.cross(w @ J_PAPER.T, w) + tau) @ j_inv.T + sigma  # eq. 6
    p, q, psi, _ = hc_eso_rates(r_hat, w_hat, sigma_hat, np.diag(K) @ r, w, tau, J_PAPER, gains)

    def psi_at(t):
        rt, rht = r @ exp_so3(t * w), r_hat @ exp_so3(t * w_hat)
        wt, wht = w + t * w_dot, w_hat + t * p
        s = va.s_l(np.diag(K) @ rt, rht)
        return (wt - wht) - gains.kappa * va.z_l(s, gains.alpha, gains.gamma), rt @ np.swapaxes(rht, -1, -2)

    h = 1e-6
    (psi_p, q_p), (psi_m, q_m) = psi_at(h), psi_at(-h)
    a = gains.alpha
    n2 = np.sum(psi * psi, axis=-1, keepdims=True)
    expected = -gains.k_psi * n2 ** ((a - 1) / 2) * psi + (sigma - sigma_hat)
    np.testing.assert_allclose((psi_p - psi_m) / (2 * h), expected, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(-q, -gains.k_sigma * n2 ** (a - 1) * psi, rtol=1e-12)
    q0 = r @ np.swapaxes(r_hat, -1, -2)
    expected_q = q0 @ hat(np.einsum("nij,nj->ni", r_hat, w - w_hat))
    np.testing.assert_allclose((q_p - q_m) / (2 * h), expected_q, atol=1e-6)


def test_geometric_step_stays_on_so3():
    rng = np.random.default_rng(1)
    r_hat, w_hat, s_hat = np.eye(3)[None], np.array([[0.0, 0.0, 1.0]]), np.array([[2.0, 3.0, 5.0]])
    l = np.diag(K) @ exp_so3(np.array([[np.pi, 0, 0]]))
    for _ in range(2000):
        r_hat, w_hat, s_hat = hc_eso_step(r_hat, w_hat, s_hat, l, rng.normal(size=(1, 3)), np.zeros((1, 3)),
                                          J_PAPER, HcEsoGains(), 0.01)
    assert orthogonality_error(r_hat)[0] < 1e-12
    assert abs(np.linalg.det(r_hat[0]) - 1.0) < 1e-12


@pytest.mark.parametrize("kwargs, match", [
    (dict(alpha=0.5), "alpha"), (dict(alpha=1.0), "alpha"), (dict(alpha="0.8"), "alpha"), (dict(gamma=0), "gamma"),
    (dict(gamma=1.5), "gamma"), (dict(gamma="2"), "gamma"),
    (dict(gamma=1, alpha=0.9), "gamma - 3 alpha"), (dict(kappa=0.0), "kappa"), (dict(k_sigma=-1.0), "k_sigma"),
    (dict(k_psi=float("nan")), "k_psi"), (dict(morse_gains=[1.0, 1.0, 1.0]), "k1 > k2"),
    (dict(vectors="gps"), "vectors"), (dict(rate_key="velocity"), "rate_key"), (dict(max_step=0.0), "max_step"),
])
def test_bad_gains_and_options_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_observer("hc_eso", 1.0, J_QUAD, **kwargs)


def _meas(r, w):
    rt = np.swapaxes(r, -1, -2)
    return {"specific_force": -G * rt[..., :, 2], "magnetometer": rt @ EARTH_FIELD_NED, "angular_velocity": w,
            "attitude": r}


def _synthetic(obs, tau_d, t_end=6.0, dt=0.01, n=1, seed=0):
    """A quad-size rigid body spinning slowly under a damping torque and a constant disturbance (exact IMU)."""
    rng = np.random.default_rng(seed)
    r = exp_so3(rng.normal(scale=0.3, size=(n, 3)))
    w = rng.normal(scale=0.3, size=(n, 3))
    j_inv = np.linalg.inv(J_QUAD)
    obs.reset(_meas(r, w))
    sub = 4
    h = dt / sub
    out = []
    for _ in range(int(round(t_end / dt))):
        tau = -0.05 * w
        for _ in range(sub):  # semi-implicit Lie-Euler substeps, torque held
            w = w + h * ((cross(w @ J_QUAD.T, w) + tau + tau_d) @ j_inv.T)
            r = r @ exp_so3(h * w)
        out.append(obs.update(_meas(r, w), np.zeros(n), tau, dt))
    return out, r, w


@pytest.mark.parametrize("vectors", ["imu", "attitude"])
def test_observer_recovers_a_constant_torque(vectors):
    tau_d = np.array([0.02, -0.01, 0.005])
    obs = make_observer("hc_eso", 1.0, J_QUAD, vectors=vectors)  # the paper's gains
    est, r, w = _synthetic(obs, tau_d)
    assert obs.channels == {"torque"}
    assert np.abs(est[-1].torque[0] - tau_d).max() < 1e-5  # AG-FTS for a constant disturbance (Theorem 1)
    assert np.abs(est[50].torque[0] - tau_d).max() > 1e-4  # ... which it did not know at first
    # attitude and rate converge more slowly (kappa = 0.15 scales the attitude correction, eq. 29)
    att_err = lambda e: np.linalg.norm(log_so3(r[0] @ e.states["attitude"][0].T))
    assert att_err(est[-1]) < 0.01
    np.testing.assert_allclose(est[-1].states["angular_velocity"][0], w[0], atol=5e-3)
    np.testing.assert_allclose(est[-1].force, 0.0)


def test_batch_equals_separate_runs():
    tau_d = np.array([0.01, 0.0, -0.01])
    batch, _, _ = _synthetic(make_observer("hc_eso", 1.0, J_QUAD), tau_d, t_end=0.3, n=3, seed=7)
    # two implementations of one law (tests/_tolerance.py): the 3-row batch and N = 1 runs, each fed by its own
    # shape of the same dynamics (3-row vs 1-row BLAS products, which round differently on some CPUs); the
    # Hölder terms of eq. 30 and H(s) of eq. 28 amplify that rounding (cond=HC_ESO_COND)
    scale = max(np.abs(b.torque).max() for b in batch)
    rng = np.random.default_rng(7)
    r0 = exp_so3(rng.normal(scale=0.3, size=(3, 3)))
    w0 = rng.normal(scale=0.3, size=(3, 3))
    # replay each vehicle alone through the same dynamics (the simulation is row-wise independent)
    for i in range(3):
        obs = make_observer("hc_eso", 1.0, J_QUAD)
        r, w = r0[i:i + 1], w0[i:i + 1]
        obs.reset(_meas(r, w))
        for k in range(30):
            tau = -0.05 * w
            for _ in range(4):
                w = w + 0.0025 * ((cross(w @ J_QUAD.T, w) + tau + tau_d) @ np.linalg.inv(J_QUAD).T)
                r = r @ exp_so3(0.0025 * w)
            e = obs.update(_meas(r, w), np.zeros(1), tau, 0.01)
            assert_same_law(e.torque[0], batch[k].torque[i], scale=scale, steps=k + 1, cond=HC_ESO_COND,
                            what=f"row {i} step {k} torque")
            assert_same_law(e.states["attitude"][0], batch[k].states["attitude"][i], scale=1.0, steps=k + 1,
                            cond=HC_ESO_COND, what=f"row {i} step {k} attitude")


def test_update_errors_are_clear():
    obs = make_observer("hc_eso", 1.0, J_QUAD)
    m = _meas(np.eye(3)[None], np.zeros((1, 3)))
    with pytest.raises(RuntimeError, match="before reset"):  # the same type and text as every observer
        obs.update(m, 0.0, np.zeros(3), 0.01)
    with pytest.raises(ValueError, match="magnetometer"):
        obs.reset({k: v for k, v in m.items() if k != "magnetometer"})
    obs.reset(m, torque=[0.01, 0.0, 0.0])
    with pytest.raises(ValueError, match="dt"):
        obs.update(m, 0.0, np.zeros(3), 0.0)
    with pytest.raises(ValueError, match="free fall"):
        obs.update({**m, "specific_force": np.zeros((1, 3))}, 0.0, np.zeros(3), 0.01)
    est = obs.update(m, 0.0, np.zeros(3), 0.01)
    assert est.torque[0, 0] == pytest.approx(0.01, rel=1e-2)  # the initial guess is J sigma_hat
