"""QB observer design (seed-001 qb_observer_cayero2019.txt, Sec. 2): LMIs, projection, trade-off."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.observers import qb_design as qd
from fawtgym.observers.qb_uav_model import disturbance_model, paper_q2, scaled_q2, uav_model


def small_problem(q1: float = 100.0, q2: float = 25.0) -> qd.QBProblem:
    """Double integrator with a constant-disturbance state: x = (position, disturbance), y = position."""
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    return qd.QBProblem(A=A, B=np.array([[1.0], [0.0]]), C=np.array([[1.0, 0.0]]), D=np.zeros((1, 1)),
                        W1=np.array([[0.0], [1.0]]), W2=np.array([[1.0]]), Q=np.diag([q1, q2]) / 2,
                        E1=np.array([[0.0, 1.0]]))


@pytest.fixture(scope="module")
def small_solution() -> tuple[qd.QBProblem, qd.QBSolution]:
    pr = small_problem()
    return pr, qd.solve_qb_lmi(pr, 1.0)


@pytest.fixture(scope="module")
def small_sweep() -> tuple[qd.QBProblem, qd.AlphaSweep]:
    pr = small_problem()
    return pr, qd.sweep_alpha(pr, np.geomspace(0.01, 50.0, 10))


def check_lmis(pr: qd.QBProblem, sol: qd.QBSolution, rel: float = 1e-6) -> None:
    r = qd.lmi_residuals(pr, sol)
    assert r["lmi7_max_eig"] <= rel * r["lmi7_scale"], r  # eq. 7 (<= 0)
    assert r["lmi30_min_eig"] >= -rel * r["lmi30_scale"], r  # eq. 30 (>= 0)
    assert r["P_min_eig"] > 0 and r["X_min_eig"] > 0, r
    assert r["decay_margin"] <= 1e-6 * sol.alpha, r  # Re eig(A+LC) <= -alpha/2
    # the log-det maximization makes X equal to the projection P_z (text after eq. 31)
    np.testing.assert_allclose(sol.X, sol.Pz, rtol=1e-3, atol=1e-6 * np.abs(sol.Pz).max())


def test_small_problem_solution_satisfies_lmis(small_solution):
    pr, sol = small_solution
    check_lmis(pr, sol)
    np.testing.assert_allclose(sol.L, np.linalg.solve(sol.P, sol.Y))  # eq. 9
    assert math.isclose(sol.volume, 2.0 / math.sqrt(sol.Pz[0, 0]), rel_tol=1e-9)  # eq. 20, B_1 = 2


def test_qb_bound_holds_along_worst_case_simulation(small_solution):
    """Eq. 18: V(e) <= 1 + (V0 - 1) exp(-alpha t) for any eta inside the ellipsoid (2)."""
    pr, sol = small_solution
    rng = np.random.default_rng(1)
    acl = pr.A + sol.L @ pr.C
    qh = np.linalg.cholesky(np.linalg.inv(pr.Q))  # eta = qh w with |w| <= 1 -> eta^T Q eta <= 1
    e = np.array([3.0, -2.0])
    v0 = e @ sol.P @ e
    h = 1e-3
    for k in range(1, 8001):
        w = rng.normal(size=2)
        w /= np.linalg.norm(w)
        eta = qh @ w
        e = e + h * (acl @ e + pr.W1 @ eta[:1] + sol.L @ pr.W2 @ eta[1:])
        bound = 1 + (v0 - 1) * math.exp(-sol.alpha * k * h)
        assert e @ sol.P @ e <= bound * 1.01 + 1e-3


def test_infeasible_problem_raises_clear_error():
    # an unstable mode that C cannot see: no L makes A + L C stable, (7) has no solution
    pr = qd.QBProblem(A=np.diag([1.0, -1.0]), B=np.zeros((2, 1)), C=np.array([[0.0, 1.0]]), D=np.zeros((1, 1)),
                      W1=np.eye(2)[:, :1], W2=np.eye(1), Q=np.eye(2), E1=np.array([[1.0, 0.0]]))
    with pytest.raises(qd.QBInfeasibleError, match=r"alpha=0\.5.*(infeasible|status|failed)"):
        qd.solve_qb_lmi(pr, 0.5)
    with pytest.raises(qd.QBInfeasibleError, match="every alpha"):
        qd.sweep_alpha(pr, [0.5, 1.0])


@pytest.mark.parametrize("bad", [
    dict(Q=np.diag([1.0, -1.0])), dict(Q=np.array([[1.0, 0.5], [0.0, 1.0]])),
    dict(E1=np.array([[0.0, 2.0]])), dict(W1=np.ones((3, 1))), dict(A=np.ones((2, 3))),
])
def test_bad_problem_data_raise(bad):
    base = small_problem()
    kw = base.as_arrays() | bad
    with pytest.raises(ValueError):
        qd.QBProblem(**kw)


def test_bad_alpha_raises():
    with pytest.raises(ValueError, match="alpha"):
        qd.solve_qb_lmi(small_problem(), 0.0)
    with pytest.raises(ValueError, match="alpha"):
        qd.solve_qb_lmi(small_problem(), float("nan"))


# ------------------------------------------------------------------------- projection (19) ----
def _random_spd(n: int, rng: np.random.Generator) -> np.ndarray:
    a = rng.normal(size=(n, n))
    return a @ a.T + 0.5 * np.eye(n)


@pytest.mark.parametrize("selection", [True, False])
def test_projection_properties(selection):
    rng = np.random.default_rng(3)
    n, q = 6, 2
    P = _random_spd(n, rng)
    if selection:
        E1 = np.eye(n)[[1, 4]]
    else:
        E1 = np.linalg.qr(rng.normal(size=(n, n)))[0][:, :q].T
    Pz = qd.projection_matrix(P, E1)
    # (i) P_z = (E1 P^-1 E1^T)^-1 : the shadow of e^T P e <= 1 on <E1>
    # two implementations of one formula (tests/_tolerance.py), through inverses of P: cond(P)
    assert_same_law(Pz, np.linalg.inv(E1 @ np.linalg.inv(P) @ E1.T), cond=np.linalg.cond(P), what="P_z")
    # (ii) support function: max_{x^T P x <= 1} c^T E1 x = sqrt(c^T P_z^-1 c)
    for _ in range(5):
        c = rng.normal(size=q)
        g = E1.T @ c
        x = np.linalg.solve(P, g) / math.sqrt(g @ np.linalg.solve(P, g))  # the maximizer, on the boundary
        assert math.isclose(c @ E1 @ x, math.sqrt(c @ np.linalg.solve(Pz, c)), rel_tol=1e-10)
        # (iii) boundary points with E2 P x = 0 project onto the boundary z^T P_z z = 1 (Appendix A5-A6)
        E2 = qd.orthogonal_complement(E1)
        np.testing.assert_allclose(E2 @ P @ x, 0.0, atol=1e-10)
        z = E1 @ x
        assert math.isclose(z @ Pz @ z, 1.0, rel_tol=1e-10)
    # (iv) independent of the choice of E2, and a shrinkage: P_z <= E1 P E1^T
    assert np.linalg.eigvalsh(E1 @ P @ E1.T - Pz).min() >= -1e-10
    # (v) X <= P_z  <=>  P - E1^T X E1 >= 0 (eq. 27 <=> eq. 30)
    for s in (0.99, 1.01):
        ok = np.linalg.eigvalsh(P - E1.T @ (s * Pz) @ E1).min() >= -1e-10
        assert ok == (s <= 1.0)


def test_projection_rejects_bad_input():
    with pytest.raises(ValueError, match="positive definite"):
        qd.projection_matrix(np.diag([1.0, -1.0, 1.0]), np.eye(3)[:1])


def test_unit_ball_volume_and_ellipsoid_volume():
    assert math.isclose(qd.unit_ball_volume(2), math.pi)
    assert math.isclose(qd.unit_ball_volume(3), 4 * math.pi / 3)
    assert math.isclose(qd.unit_ball_volume(6), math.pi**3 / 6)
    # ellipse with semi-axes 2 and 3: area 6 pi
    assert math.isclose(qd.ellipsoid_volume(np.diag([1 / 4, 1 / 9])), 6 * math.pi)


# --------------------------------------------------------------------------- the UAV model ----
def test_uav_model_structure():
    F, G, H = disturbance_model(3)
    assert F.shape == (18, 18) and G.shape == (18, 6) and H.shape == (6, 18)
    assert np.allclose(np.linalg.matrix_power(F, 3), 0) and not np.allclose(np.linalg.matrix_power(F, 2), 0)
    pr = uav_model(r=3)
    x = np.arange(24.0)
    # p' = H d_v (+ u), d' = F d_v: (d, d', d'') -> (d', d'', 0)
    np.testing.assert_allclose((pr.A @ x)[:6], x[6:12])
    np.testing.assert_allclose((pr.A @ x)[6:18], x[12:24])
    np.testing.assert_allclose((pr.A @ x)[18:], 0.0)
    np.testing.assert_allclose(pr.C @ x, x[:9])  # (m v, spin momentum, external force)
    np.testing.assert_allclose(pr.E1 @ x, x[6:12])  # eq. 60
    np.testing.assert_allclose(pr.Q[:6, :6], 0.5e6 * np.eye(6))  # eq. 59
    q2 = paper_q2()
    assert q2[3, 3] == 2903 and q2[4, 3] == 111.7 and np.linalg.eigvalsh(q2).min() > 0
    np.testing.assert_allclose(scaled_q2(1.023, [9.5e-3, 9.5e-3, 18.6e-3]), q2)
    np.testing.assert_allclose(scaled_q2(2 * 1.023, [9.5e-3, 9.5e-3, 18.6e-3])[0, 0], q2[0, 0] / 4)
    with pytest.raises(ValueError, match="order r"):
        disturbance_model(0)


# ---------------------------------------------------------------------- trade-off (21-25) ----
def test_jmu_normalization(small_sweep):
    _, sw = small_sweep
    a = qd.anchors_from_sweep(sw)
    assert math.isclose(float(qd.j_mu(0.3, a.alpha_nadir, a.vol_star, a)), 0.3 * 0 + 0.7 * 1)
    assert math.isclose(float(qd.j_mu(0.3, a.alpha_star, a.vol_nadir, a)), 0.3)
    with pytest.raises(ValueError, match="mu"):
        qd.j_mu(1.5, 1.0, 1.0, a)


def test_sweep_tradeoff_and_line_search(small_sweep):
    """Fig. 4 shape (interior minimum, then growth) and Fig. 6 monotonicity (the r = 3 UAV model is
    checked in test_qb_observer and the long reproduction)."""
    pr, sw = small_sweep
    assert not sw.failed
    a = qd.anchors_from_sweep(sw)
    assert sw.alphas.min() < a.alpha_nadir < a.alpha_star == 50.0
    tail = sw.log_volumes[sw.alphas >= a.alpha_nadir]
    assert np.all(np.diff(tail) > 0)
    lo = qd.optimal_alpha(pr, 0.95, sw)
    hi = qd.optimal_alpha(pr, 0.2, sw)
    assert lo.alpha < hi.alpha and lo.log_volume < hi.log_volume
    for s in (lo, hi):
        check_lmis(pr, s)
        grid_j = qd.j_mu(0.95 if s is lo else 0.2, sw.alphas, sw.volumes, a)
        assert float(qd.j_mu(0.95 if s is lo else 0.2, s.alpha, s.volume, a)) <= grid_j[
            (sw.alphas >= a.alpha_nadir)].min() + 1e-9
