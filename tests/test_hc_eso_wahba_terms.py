"""Generalized Wahba cost and Morse-function terms (hc_eso_so3_wang2022.txt, eqs. 12-28, Lemmas 1, 2, 4)."""

from __future__ import annotations

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.measurement import EARTH_FIELD_NED
from fawtgym.core.so3 import exp_so3
from fawtgym.observers import vector_attitude as va

K = np.array([3.0, 2.0, 1.0])
G = 9.80665


def _setup(seed=0, n=5, k=4):
    rng = np.random.default_rng(seed)
    e = rng.normal(size=(3, k))
    r = exp_so3(rng.normal(size=(n, 3)))
    r_hat = exp_so3(rng.normal(size=(n, 3)))
    return rng, e, r, r_hat


def test_weight_eq13_gives_e_w_et_equal_k():
    _, e, _, _ = _setup()
    w = va.wahba_weight(e, K)
    assert w.shape == (4, 4)
    # symmetric up to rounding: W and W^T are two evaluations of one matrix (tests/_tolerance.py), through the
    # inverse of E E^T (cond)
    assert_same_law(w, w.T, cond=np.linalg.cond(e @ e.T), what="W symmetric")
    np.testing.assert_allclose(e @ w @ e.T, np.diag(K), atol=1e-12)


def test_lemma1_cost_is_the_morse_function():
    _, e, r, r_hat = _setup(1)
    w = va.wahba_weight(e, K)
    u = np.swapaxes(r, -1, -2) @ e  # exact measurements, eq. 10
    q = r @ np.swapaxes(r_hat, -1, -2)
    morse = np.sum(K * (1.0 - np.diagonal(q, axis1=-2, axis2=-1)), axis=-1)  # <K, I - Q>, eq. 14
    np.testing.assert_allclose(va.wahba_cost(e, u, r_hat, w), morse, atol=1e-12)
    # the critical points of eq. 15 are stationary: s_K vanishes there; Q = I is the minimum (value 0)
    for d in ([1, 1, 1], [-1, -1, 1], [1, -1, -1], [-1, 1, -1]):
        assert np.allclose(va.s_k(np.diag(d).astype(float), K), 0.0)
    assert va.wahba_cost(e, np.swapaxes(r, -1, -2) @ e, r, w) == pytest.approx(0.0, abs=1e-12)


def test_lemma4_norms_of_s_l_and_s_k_agree():
    _, e, r, r_hat = _setup(2)
    w = va.wahba_weight(e, K)
    l = va.gain_matrix(e, w, np.swapaxes(r, -1, -2) @ e)
    np.testing.assert_allclose(l, np.diag(K) @ r, atol=1e-12)  # L = K R without noise
    q = r @ np.swapaxes(r_hat, -1, -2)
    np.testing.assert_allclose(np.linalg.norm(va.s_l(l, r_hat), axis=-1), np.linalg.norm(va.s_k(q, K), axis=-1),
                               atol=1e-12)


def test_lemma2_cost_rate_and_w_l_are_time_derivatives():
    rng, e, r0, rh0 = _setup(3, n=4)
    w = va.wahba_weight(e, K)
    omega, omega_hat = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))

    def at(t):
        r = r0 @ exp_so3(t * omega)
        rh = rh0 @ exp_so3(t * omega_hat)
        l = va.gain_matrix(e, w, np.swapaxes(r, -1, -2) @ e)
        return l, rh

    h = 1e-5
    (lp, rhp), (lm, rhm), (l0, rh0_) = at(h), at(-h), at(0.0)
    cost = lambda l, rh: np.sum(K) - np.trace(np.swapaxes(l, -1, -2) @ rh, axis1=-2, axis2=-1)  # eq. 19
    d_cost = (cost(lp, rhp) - cost(lm, rhm)) / (2 * h)
    s = va.s_l(l0, rh0_)
    np.testing.assert_allclose(d_cost, -np.sum(s * (omega - omega_hat), axis=-1), atol=1e-7)
    ds = (va.s_l(lp, rhp) - va.s_l(lm, rhm)) / (2 * h)
    np.testing.assert_allclose(va.w_l(l0, rh0_, omega_hat, omega), ds, atol=1e-7)  # eq. 27


def test_z_l_derivative_is_the_h_term_of_eq30():
    # d/dt z_L = (s^T s)^((alpha-1)/gamma) H(s) s' : the identity that turns eq. 30 into the error dynamics eq. 31
    rng = np.random.default_rng(4)
    s0, ds = rng.normal(size=(6, 3)), rng.normal(size=(6, 3))
    for alpha, gamma in ((0.85, 2), (0.6, 1), (0.95, 3)):
        h = 1e-6
        num = (va.z_l(s0 + h * ds, alpha, gamma) - va.z_l(s0 - h * ds, alpha, gamma)) / (2 * h)
        s2 = np.sum(s0 * s0, axis=-1)[:, None]
        ana = s2 ** ((alpha - 1) / gamma) * np.einsum("nij,nj->ni", va.h_matrix(s0, alpha, gamma), ds)
        np.testing.assert_allclose(num, ana, rtol=1e-6, atol=1e-8)
    # Hölder-continuous at 0: z_L(0) = 0, H(0) = I, nothing is NaN
    assert np.all(va.z_l(np.zeros((1, 3)), 0.85, 2) == 0.0)
    np.testing.assert_allclose(va.h_matrix(np.zeros((1, 3)), 0.85, 2)[0], np.eye(3))


def test_imu_vector_set_and_static_wahba_solution():
    rng = np.random.default_rng(5)
    r = exp_so3(rng.normal(size=(3, 3)))
    rt = np.swapaxes(r, -1, -2)
    f = -G * rt[..., :, 2]  # at rest: specific force R^T (0 - g e3)
    m = np.einsum("nij,j->ni", rt, EARTH_FIELD_NED)
    e, u = va.imu_vector_set(f, m)
    np.testing.assert_allclose(u, rt @ e, atol=1e-12)
    w = va.wahba_weight(e, K)
    np.testing.assert_allclose(va.solve_wahba(va.gain_matrix(e, w, u)), r, atol=1e-10)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="rank 3"):
        va.wahba_weight(np.array([[1.0, 0, 2], [0, 1, 0], [0, 0, 0]]), K)
    with pytest.raises(ValueError, match=r"shape \(3, k\)"):
        va.wahba_weight(np.eye(3)[:, :2], K)
    with pytest.raises(ValueError, match="k1 > k2 > k3 >= 1"):
        va.wahba_weight(np.eye(3), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="k1 > k2 > k3 >= 1"):
        va.wahba_weight(np.eye(3), [3.0, 2.0, 0.5])
    with pytest.raises(ValueError, match="free fall"):
        va.imu_vector_set(np.zeros(3), EARTH_FIELD_NED)
    with pytest.raises(ValueError, match="parallel"):
        va.imu_inertial_vectors([0.0, 0.0, 0.5])
