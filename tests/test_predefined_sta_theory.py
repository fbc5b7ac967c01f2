"""Predefined-time STA theory (pdt_sta_attitude_silva2023.txt Sec. 3): Example 1, eqs. 23-25, 36, 39, 43."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fawtgym.observers import predefined_sta as P

TC, X0, ETA, K1, K2 = 0.5, (-2.0, 1.0), 5.0, 1.0, 8.0


def test_example1_first_crossing_matches_paper() -> None:
    # paper: t1 = 0.2062 s (4 decimals) -> tolerance half a unit in the last digit
    t1 = P.zero_crossings(X0, TC, ETA, K2)[0].t
    assert abs(t1 - 0.2062) <= 5e-5


def test_example1_kappa2_bound() -> None:
    t1 = P.zero_crossings(X0, TC, ETA, K2)[0].t
    lo_rounded, hi = P.kappa2_interval_36(X0, round(t1, 4), TC)
    assert abs(lo_rounded - 11.4155) < 5e-5  # the paper's number, from t1 rounded to 0.2062
    lo_exact, _ = P.kappa2_interval_36(X0, t1, TC)
    assert abs(lo_exact - 1.0 / (TC - 2 * t1)) < 1e-12
    assert 11.42 < lo_exact < 11.43  # ours with the unrounded t1 = 0.206243 s
    assert hi == math.inf
    assert K2 * TC >= abs(X0[1])  # (30) holds, (36) does not
    assert K2 < lo_exact


def test_fig3_ptc_membership() -> None:
    ok_a, _, x2a = P.first_crossing_in_ptc(X0, TC, 5.0, 8.0)
    ok_b, t1b, x2b = P.first_crossing_in_ptc(X0, TC, 5.0, 12.0)
    ok_c, _, _ = P.first_crossing_in_ptc(X0, TC, 8.0, 8.0)
    assert (ok_a, ok_b, ok_c) == (False, True, True)
    assert abs(x2b) <= 12.0 * (TC - t1b)


def test_algorithm1_gain_and_rate() -> None:
    g = P.tune_algorithm1(X0, TC, ETA, K2, strategy="gain")
    assert g.kappa2 == 12.0 and g.eta == ETA  # ceil(11.43) = 12, as Fig. 3b
    r = P.tune_algorithm1(X0, TC, ETA, K2, strategy="rate")
    assert r.kappa2 == K2 and r.eta > ETA
    assert P.first_crossing_in_ptc(X0, TC, r.eta, r.kappa2)[0]


def test_early_switch_time_eq43() -> None:
    ell = math.sqrt(3.0) * 2e-2  # the paper's ||delta|| <= 0.0346 from eq. 84
    assert abs(P.early_switch_time(1.5, 5.0, ell) - 1.3268) < 5e-5


@pytest.mark.parametrize("kappa2,eta", [(8.0, 5.0), (12.0, 5.0), (8.0, 8.0), (15.0, 6.0)])
def test_analytic_solution_vs_solve_ivp(kappa2: float, eta: float) -> None:
    """Eqs. 23-25 chained over zero crossings vs numerical integration of eqs. 21-22 (delta = 0)."""
    x0 = X0
    rhs = P.modified_sta_rhs(TC, eta, K1, kappa2)

    def ev(t: float, x: np.ndarray) -> float:
        return x[0]

    ev.terminal = True
    t_start, state, worst = 0.0, list(x0), 0.0
    cross = P.zero_crossings(x0, TC, eta, kappa2)
    # integrate segment by segment (Filippov sign fixed per segment), up to 3 crossings
    for j in range(min(3, len(cross)) + 1):
        t_end = cross[j].t if j < len(cross) else TC * 0.999
        s = np.sign(state[0]) if j == 0 else -cross[j - 1].sign_before

        def seg_rhs(t: float, x: np.ndarray, s: float = s) -> np.ndarray:
            return np.array([-eta / (TC - t) * x[0] + x[1], -kappa2 * s])

        sol = solve_ivp(seg_rhs, (t_start, t_end), state, method="DOP853", rtol=1e-12, atol=1e-13,
                        dense_output=True)
        tt = np.linspace(t_start, t_end, 50, endpoint=False)
        a1, a2 = P.analytic_solution(tt, x0, TC, eta, kappa2)
        worst = max(worst, np.abs(sol.sol(tt)[0] - a1).max(), np.abs(sol.sol(tt)[1] - a2).max())
        if j >= len(cross):
            break
        t_start, state = t_end, [0.0, float(sol.y[1, -1])]
    assert worst < 1e-8
    # the event-driven integration of the original discontinuous rhs finds the same first crossing
    sol = solve_ivp(rhs, (0.0, TC * 0.999), list(x0), method="DOP853", rtol=1e-12, atol=1e-13, events=ev)
    assert abs(sol.t_events[0][0] - cross[0].t) < 1e-9


def test_noise_free_convergence_at_tc() -> None:
    """Fig. 3b/3c settings: x1 and x2 reach (a tiny neighbourhood of) 0 at t_c (Theorem 2)."""
    for eta, k2 in ((5.0, 12.0), (8.0, 8.0)):
        t, x1, x2 = P.simulate_scalar(X0, 0.7, 1e-5, TC, eta, K1, k2)
        k = int(round(TC / 1e-5))
        assert abs(x1[k]) < 1e-6 and abs(x2[k]) < 2e-3
        assert np.abs(x1[k:]).max() < 1e-6 and np.abs(x2[k:]).max() < 2e-3
        assert abs(x2[k // 2]) > 0.1  # not trivially small before
    # kappa2 = 8, eta = 5 violates (36): x2 misses 0 at t_c; analytically x2(t_c) = x2(t1) - 8 (t_c - t1)
    t, x1, x2 = P.simulate_scalar(X0, 0.5, 1e-5, TC, 5.0, K1, 8.0)
    c = P.zero_crossings(X0, TC, 5.0, 8.0)
    assert len(c) == 1
    assert abs(x2[-1] - (c[0].x2 - 8.0 * (TC - c[0].t))) < 1e-3
    assert abs(x2[-1]) > 0.2


def test_bounded_with_noise_and_early_switch() -> None:
    """Eqs. 40-44: with |v| <= ell, early switching at t_e keeps x in a bounded neighbourhood."""
    rng = np.random.default_rng(3)
    ell = 1e-3
    h = 1e-4
    t_e = P.early_switch_time(TC, 5.0, ell)
    noise = ell * rng.uniform(-1, 1, int(round(1.0 / h)))
    t, x1, x2 = P.simulate_scalar(X0, 1.0, h, TC, 5.0, K1, 12.0, t_switch=t_e, noise=noise)
    after = t >= TC
    assert np.all(np.isfinite(x1)) and np.all(np.isfinite(x2))
    assert np.abs(x1[after]).max() < 20 * ell
    assert np.abs(x2[after]).max() < 0.5
    # x1 stays inside eq. 39's envelope before the switch (plus the noise level)
    before = t < t_e
    xi = P.xi_bound(t[before], X0[0], TC, 5.0, 12.0)
    assert np.all(np.abs(x1[before]) <= xi + 2 * ell)


def test_xi_bound_contains_noise_free_solution() -> None:
    t = np.linspace(0.0, TC * 0.999, 500)
    x1, _ = P.analytic_solution(t, X0, TC, 5.0, 12.0)
    assert np.all(np.abs(x1) <= P.xi_bound(t, X0[0], TC, 5.0, 12.0) + 1e-12)


def test_bad_parameters_raise() -> None:
    with pytest.raises(ValueError, match="eta"):
        P.zero_crossings(X0, TC, 2.0, K2)
    with pytest.raises(ValueError, match="t_c"):
        P.zero_crossings(X0, -1.0, ETA, K2)
    with pytest.raises(ValueError, match="kappa2"):
        P.zero_crossings(X0, TC, ETA, -1.0)
    with pytest.raises(ValueError, match="kappa1"):
        P.modified_sta_rhs(TC, ETA, 0.0, K2)
    with pytest.raises(ValueError, match="t_e"):
        P.early_switch_time(1.5, 5.0, 0.5)
    with pytest.raises(ValueError, match="ell"):
        P.early_switch_time(1.5, 5.0, -1.0)
    with pytest.raises(ValueError, match="strategy"):
        P.tune_algorithm1(X0, TC, strategy="magic")
    with pytest.raises(ValueError, match=r"\(30\)"):
        P.tune_algorithm1(X0, TC, ETA, kappa2=1.0)
    with pytest.raises(ValueError, match="x1"):
        P.zero_crossings((0.0, 1.0), TC, ETA, K2)
    with pytest.raises(ValueError, match="increase eta"):
        P.kappa2_interval_36(X0, 0.3, TC)
    with pytest.raises(ValueError, match="t_c"):
        P.analytic_solution([0.6], X0, TC, ETA, K2)


def test_exact_linear_step_matches_integration() -> None:
    """The eq.-7 step of x1' = -eta/(t_c - t)(x1 - y) + x2 (y, x2 held) against solve_ivp, up to t_c."""
    t_c, eta, y, x2 = 0.5, 5.0, 0.3, -1.2
    for t, h in ((0.0, 0.1), (0.3, 0.15), (0.45, 0.05), (0.49, 0.01)):
        sol = solve_ivp(lambda s, x: [-eta / (t_c - s) * (x[0] - y) + x2], (t, t + h * (1 - 1e-9)), [1.0],
                        rtol=1e-12, atol=1e-13, method="DOP853")
        ours = float(P.exact_linear_step(1.0, x2, y, t, h, t_c, eta))
        assert abs(ours - sol.y[0, -1]) < 1e-6
    assert float(P.exact_linear_step(1.0, x2, y, 0.4, 0.1, t_c, eta)) == pytest.approx(y, abs=1e-15)  # lands on y
    batch = P.exact_linear_step(np.ones((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)), np.array([0.0, 0.25]),
                                np.array([0.1, 0.1]), t_c, eta)
    assert np.allclose(batch[0], (0.4 / 0.5) ** eta) and np.allclose(batch[1], (0.15 / 0.25) ** eta)
    with pytest.raises(ValueError, match="t_s"):
        P.exact_linear_step(1.0, 0.0, 0.0, 0.45, 0.1, t_c, eta)
