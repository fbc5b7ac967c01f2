"""HC-FFTSD (seed-000 Theorem 1, eqs. 9-17, 32, Lemma 2 eq. 5)."""

import numpy as np
import pytest
import scipy.integrate
from _tolerance import assert_same_law

from fawtgym.observers.hc_ffts import (
    HCFFTSD,
    frac_power,
    frac_power_rate,
    h_matrix,
    lyapunov_p,
    phi1,
    phi1_jacobian,
    phi2,
)

RNG = np.random.default_rng(3)
GAINS = [(3.0, 2.0, 6.0, 1.2), (3.0, 2.0, 4.0, 1.2), (6.0, 3.0, 1.0, 1.2), (2.0, 5.0, 0.5, 1.7), (1.0, 1.0, 2.0, 1.05)]


def _num_jac(fun, e, h=1e-7):
    n = e.shape[-1]
    cols = [(fun(e + h * np.eye(n)[i]) - fun(e - h * np.eye(n)[i])) / (2 * h) for i in range(n)]
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("k1,k2,k3,p", GAINS)
@pytest.mark.parametrize("n", [1, 3])
def test_phi2_equals_jacobian_of_phi1_times_phi1(k1, k2, k3, p, n):
    """Eqs. (12)-(13): phi_2 = phi_1' phi_1, with phi_1' both analytic (eq. 12) and by finite differences."""
    for _ in range(20):
        e = RNG.standard_normal(n) * 10 ** RNG.uniform(-3, 1)
        jac_num = _num_jac(lambda x: phi1(x, k3, p), e, h=1e-6 * max(np.linalg.norm(e), 1e-3))
        jac = phi1_jacobian(e, k3, p)
        np.testing.assert_allclose(jac, jac_num, rtol=1e-5, atol=1e-6)
        # eq. (9) and phi_1' phi_1: two implementations of one function (tests/_tolerance.py)
        assert_same_law(phi2(e, k3, p), jac @ phi1(e, k3, p), what="phi_2")
        np.testing.assert_allclose(phi2(e, k3, p), jac_num @ phi1(e, k3, p), rtol=1e-5)
        # eqs. (15)-(16): extreme eigenvalues of phi_1'
        lam = np.linalg.eigvalsh(jac)
        r = (e @ e) ** ((1 - p) / (3 * p - 2))
        # closed forms vs eigvalsh: eigenvalues of an n x n symmetric matrix to n |lambda|_max eps (tests/_tolerance.py)
        law = dict(scale=np.abs(lam).max(), cond=n)
        if n > 1:  # eq. (15): directions orthogonal to e (none when n = 1)
            assert_same_law(lam[-1], k3 + r, what="eq. 15", **law)
        assert_same_law(lam[0], k3 + r * p / (3 * p - 2), what="eq. 16", **law)


def test_zero_error_is_safe():
    """No NaN/inf (and no floating-point warning) at e = 0, including the derivative terms."""
    z = np.zeros((4, 3))
    w = RNG.standard_normal((4, 3))
    with np.errstate(all="raise"):
        assert np.all(phi1(z, 6.0, 1.2) == 0) and np.all(phi2(z, 6.0, 1.2) == 0)
        assert np.all(frac_power(z, 1.2) == 0) and np.all(frac_power(z, 1.2, eps=1e-12) == 0)
        rate = frac_power_rate(z, w, 1.2)
        jac = phi1_jacobian(z, 6.0, 1.2)
        h = h_matrix(z, 0.5)
    assert np.all(np.isfinite(rate)) and np.all(np.isfinite(jac))
    np.testing.assert_allclose(h, np.tile(np.eye(3), (4, 1, 1)))
    # continuity of phi1/phi2 at 0 (Hölder exponents p/(3p-2) and (2-p)/(3p-2) are positive)
    for scale in (1e-6, 1e-12, 1e-30):
        assert np.linalg.norm(phi1(scale * w[0], 6.0, 1.2)) < 10 * scale ** 0.75
        assert np.linalg.norm(phi2(scale * w[0], 6.0, 1.2)) < 10 * scale ** 0.5


def test_frac_power_rate_is_the_derivative_and_matches_h_matrix_form():
    """frac_power_rate = d/dt frac_power (finite differences), = |e|^(2(1-p)/p) H(e, (p-1)/p) e' (Def. 1)."""
    p, eps = 1.2, 1e-12
    for scale in (1.0, 1e-2, 1e-5, 1e-8):
        e = RNG.standard_normal((5, 3)) * scale
        ed = RNG.standard_normal((5, 3))
        h = 1e-6 * scale
        num = (frac_power(e + h * ed, p, eps) - frac_power(e - h * ed, p, eps)) / (2 * h)
        np.testing.assert_allclose(frac_power_rate(e, ed, p, eps), num, rtol=1e-5, atol=1e-9 * np.abs(num).max())
        if scale > 1e-5:
            r2 = np.sum(e * e, -1)[:, None]
            form = (r2 ** ((1 - p) / p))[..., None] * h_matrix(e, (p - 1) / p)
            # the fused rate and the H-matrix form: two implementations of one law (tests/_tolerance.py)
            assert_same_law(frac_power_rate(e, ed, p, eps), np.einsum("nij,nj->ni", form, ed), what="H form")


@pytest.mark.parametrize("k1,k2,k3,p", GAINS)
def test_lyapunov_p_solves_eq17_and_augmented_eq18(k1, k2, k3, p):
    q = np.array([[2.0, 0.3], [0.3, 1.0]])
    pm = lyapunov_p(k1, k2, q)
    a = np.array([[-k1, 1.0], [-k2, 0.0]])
    np.testing.assert_allclose(a.T @ pm + pm @ a, -q, atol=1e-12)
    assert np.linalg.eigvalsh(pm).min() > 0
    n = 3
    aa, pa, qa = (np.kron(x, np.eye(n)) for x in (a, pm, q))
    np.testing.assert_allclose(aa.T @ pa + pa @ aa, -qa, atol=1e-12)
    # the same eigenvalues from the 6 x 6 Kronecker form and from the 2 x 2 P: two computations (tests/_tolerance.py)
    lam = np.linalg.eigvalsh(pm)[[0, -1]]
    assert_same_law(np.linalg.eigvalsh(pa)[[0, -1]], lam, cond=2 * n, what="eigenvalues of P")


@pytest.mark.parametrize("k1,k2,k3,p", GAINS)
def test_lyapunov_decrease_inequality_31(k1, k2, k3, p):
    """V' <= -gamma_1 V - gamma_2 V^(1/p) along the flow (eq. 31) at random states (V' by chain rule, numerically)."""
    d = HCFFTSD(k1, k2, k3, p)
    g1, g2 = d.gammas()
    for _ in range(60):
        e1 = RNG.standard_normal(3) * 10 ** RNG.uniform(-4, 1)
        e2 = RNG.standard_normal(3) * 10 ** RNG.uniform(-4, 1)
        f1, f2 = d.rhs(e1, e2)
        h = 1e-7 * min(np.linalg.norm(e1) / max(np.linalg.norm(f1), 1e-300), 1.0)
        vdot = (d.lyapunov(e1 + h * f1, e2 + h * f2) - d.lyapunov(e1 - h * f1, e2 - h * f2)) / (2 * h)
        v = d.lyapunov(e1, e2)
        assert vdot <= (-g1 * v - g2 * v ** (1 / p)) * (1 - 1e-4) + 1e-12 * v


def test_settling_time_formula_matches_the_comparison_ode():
    """Eq. (5) equals the time at which V' = -g1 V - g2 V^(1/p) reaches 0 (integrated by scipy)."""
    d = HCFFTSD(3.0, 2.0, 6.0, 1.2)
    g1, g2 = d.gammas()
    e1, e2 = np.array([1.0, -0.5, 0.3]), np.array([2.0, 1.0, -1.0])
    v0 = float(d.lyapunov(e1, e2))
    hit = lambda t, v: v[0] - 1e-40  # V^(1-1/p) = 2e-7 there: negligible time left
    hit.terminal = True
    sol = scipy.integrate.solve_ivp(lambda t, v: [-g1 * v[0] - g2 * max(v[0], 0) ** (1 / 1.2)], (0, 100), [v0],
                                    events=hit, rtol=1e-10, atol=1e-50)
    assert np.isclose(sol.t_events[0][0], d.settling_time_bound(e1, e2), rtol=1e-4)


@pytest.mark.parametrize("k1,k2,k3,p", GAINS[:2])
def test_simulated_convergence_inside_eq5_bound(k1, k2, k3, p):
    """Heun integration of (11): V(t) stays below the comparison solution and reaches ~0 before the eq. (5) time."""
    d = HCFFTSD(k1, k2, k3, p)
    e1 = RNG.standard_normal((4, 3)) * np.array([[1.0], [0.1], [3.0], [1e-3]])
    e2 = RNG.standard_normal((4, 3)) * np.array([[2.0], [0.1], [0.5], [1.0]])
    v0 = d.lyapunov(e1, e2)
    t_bound = d.settling_time_bound(e1, e2)
    h = 1e-3
    t = 0.0
    x1, x2 = e1.copy(), e2.copy()
    while t < t_bound.max():
        a1, a2 = d.rhs(x1, x2)
        b1, b2 = d.rhs(x1 + h * a1, x2 + h * a2)
        x1, x2 = x1 + 0.5 * h * (a1 + b1), x2 + 0.5 * h * (a2 + b2)
        t += h
        v = d.lyapunov(x1, x2)
        bound = d.comparison_bound(v0, t)
        assert np.all(v <= bound * (1 + 1e-3) + 1e-9 * v0)
        done = t >= t_bound
        assert np.all(v[done] <= 1e-10 * v0[done])
    assert np.all(np.isfinite(x1)) and np.all(np.isfinite(x2))


@pytest.mark.parametrize("kwargs,match", [
    ({"p": 1.0}, "open interval"), ({"p": 2.0}, "open interval"), ({"k1": -1.0}, "Hurwitz"),
    ({"k2": 0.0}, "Hurwitz"), ({"k3": 0.0}, "k3"),
])
def test_gain_validation(kwargs, match):
    gains = {"k1": 3.0, "k2": 2.0, "k3": 6.0, "p": 1.2} | kwargs
    with pytest.raises(ValueError, match=match):
        HCFFTSD(**gains)


def test_lyapunov_q_must_be_positive_definite():
    with pytest.raises(ValueError, match="positive-definite"):
        lyapunov_p(3.0, 2.0, np.diag([1.0, -1.0]))
    with pytest.raises(ValueError, match="eps"):
        frac_power_rate(np.ones(3), np.ones(3), 1.2, eps=0.0)
