"""GESO gain rule and error transfer function (geso_quadrotor_shi2018.txt, eqs. 21-23, 33-38, Table 2)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal
from _tolerance import assert_same_law

from fawtgym.observers import make_observer
from fawtgym.observers.geso import (
    GesoFilter,
    chain_matrices,
    error_magnitude,
    error_magnitude_lowfreq,
    error_transfer,
    geso_gains,
)

J = np.diag([1.335e-2, 1.335e-2, 2.465e-2])


def test_table2_recomputed_exactly():
    # Table 2 of the paper, w_b = 20 rad/s
    assert geso_gains(1, 20.0).tolist() == [40.0, 400.0]
    assert geso_gains(2, 20.0).tolist() == [60.0, 1200.0, 8000.0]
    assert geso_gains(3, 20.0).tolist() == [80.0, 2400.0, 32000.0, 160000.0]


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("wb", [4.0, 20.0, 55.5])
def test_gains_are_the_coefficients_of_the_bandwidth_polynomial(order, wb):
    # eq. 34: s^(n+1) + l0 s^n + ... + ln = (s + wb)^(n+1), checked against numpy's polynomial from roots
    poly = np.poly(-wb * np.ones(order + 1))
    # two computations of the coefficients (tests/_tolerance.py): sums of positive products, no cancellation, so
    # each to its own relative accuracy (scale 0: relative only), ~order + 1 roundings
    assert_same_law(geso_gains(order, wb), poly[1:], scale=0.0, cond=order + 1, what="l_i")
    # and every observer pole sits at -wb (A - L C has characteristic polynomial (s + wb)^(n+1))
    f = GesoFilter(order, wb).f
    np.testing.assert_allclose(np.poly(f), poly, rtol=1e-9)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("wb", [10.0, 20.0, 40.0])
def test_transfer_magnitude_matches_eq37(order, wb):
    num, den = error_transfer(geso_gains(order, wb))
    # eq. 36 numerator s^n (s + (n+1) wb)
    np.testing.assert_allclose(num, np.r_[1.0, (order + 1) * wb, np.zeros(order)], rtol=1e-12)
    w = np.logspace(-2, 4, 300) * wb / 20.0
    _, h = scipy.signal.freqs(num, den, worN=w)
    np.testing.assert_allclose(np.abs(h), error_magnitude(w, order, wb), rtol=1e-9)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_low_frequency_asymptote_eq38(order):
    wb = 20.0
    kappa = np.array([1e-4, 1e-3, 1e-2, 3e-2])
    exact = error_magnitude(kappa * wb, order, wb)
    approx = error_magnitude_lowfreq(kappa * wb, order, wb)
    assert np.allclose(approx, (order + 1) * kappa**order)
    rel = np.abs(exact / approx - 1.0)
    # the relative error of eq. 38 is O(kappa^2): below (n+1) kappa^2 and shrinking with kappa
    assert np.all(rel < (order + 1) * kappa**2)
    assert np.all(np.diff(rel) > 0)
    # ... and eq. 38 is only an asymptote: at omega = wb it is off by more than 20 %
    assert abs(error_magnitude(wb, order, wb) / error_magnitude_lowfreq(wb, order, wb) - 1.0) > 0.2


def test_low_frequency_attenuation_improves_with_order_and_bandwidth():
    # the paper's reading of Fig. 3: fixed wb, higher n attenuates low frequencies more; fixed n, higher wb too
    w = np.linspace(0.2, 10.0, 50)
    mags = np.array([error_magnitude(w, n, 20.0) for n in (1, 2, 3, 4)])
    assert np.all(np.diff(mags, axis=0) < 0)
    mags_bw = np.array([error_magnitude(w, 3, wb) for wb in (10.0, 20.0, 40.0)])
    assert np.all(np.diff(mags_bw, axis=0) < 0)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_state_space_error_dynamics_give_G(order):
    # eq. 23: x_tilde' = (A - L C) x_tilde + B_d d^(n); the d_tilde = xi_1 output times s^n must be G(s) (eq. 33)
    gains = geso_gains(order, 20.0)
    a, _, bd, c = chain_matrices(order)
    f = a - np.outer(gains, c[0])
    sel = np.zeros((1, order + 1))
    sel[0, 1] = 1.0
    num, den = scipy.signal.ss2tf(f, bd, sel, np.zeros((1, 1)))
    num = np.where(np.abs(num[0]) < 1e-9 * np.abs(num[0]).max(), 0.0, num[0])  # ss2tf round-off in leading terms
    num_g = np.polymul(np.trim_zeros(num, "f"), np.r_[1.0, np.zeros(order)])
    g_num, g_den = error_transfer(gains)
    np.testing.assert_allclose(den, g_den, rtol=1e-9)
    np.testing.assert_allclose(num_g, g_num, rtol=1e-9, atol=1e-6)


@pytest.mark.parametrize("bad", [0, 5, -1, 2.5, True, "3", None])
def test_bad_order_raises(bad):
    with pytest.raises(ValueError, match="order"):
        geso_gains(bad, 20.0)
    with pytest.raises(ValueError, match="order"):
        make_observer("geso", 1.0, J, order=bad)


@pytest.mark.parametrize("bad", [0.0, -3.0, math.nan, math.inf, "fast", None])
def test_bad_bandwidth_raises(bad):
    with pytest.raises(ValueError, match="bandwidth"):
        geso_gains(2, bad)
    with pytest.raises(ValueError, match="bandwidth"):
        make_observer("geso", 1.0, J, bandwidth=bad)


def test_bad_gains_and_options_raise():
    with pytest.raises(ValueError, match="Hurwitz"):
        GesoFilter(gains=[-40.0, 400.0])
    with pytest.raises(ValueError, match="Hurwitz"):
        GesoFilter(gains=[0.0, 400.0])
    with pytest.raises(ValueError, match="gains"):
        GesoFilter(gains=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])  # order 5
    with pytest.raises(ValueError, match="does not match"):
        GesoFilter(order=3, gains=[40.0, 400.0])
    with pytest.raises(ValueError, match="finite"):
        GesoFilter(gains=[np.nan, 400.0])
    with pytest.raises(ValueError, match="channels"):
        make_observer("geso", 1.0, J, channels=("wind",))
    with pytest.raises(ValueError, match="channels"):
        make_observer("geso", 1.0, J, channels=())
    with pytest.raises(ValueError, match="hold"):
        make_observer("geso", 1.0, J, hold="cubic")
    with pytest.raises(ValueError, match="rate_key"):
        make_observer("geso", 1.0, J, rate_key="attitude")
    with pytest.raises(ValueError, match="order mapping"):
        make_observer("geso", 1.0, J, order={"torque": 2})  # force missing
    with pytest.raises(ValueError, match="dt"):
        GesoFilter(2, 20.0).discretize(0.0)
    with pytest.raises(ValueError, match="dt"):
        GesoFilter(2, 20.0).discretize(float("nan"))


def test_default_construction_and_per_channel_options():
    obs = make_observer("geso", 1.5, J)
    assert obs.channels == {"force", "torque"}
    assert obs.filters["torque"].order == 3 and obs.filters["torque"].bandwidth == 20.0
    obs2 = make_observer("geso", 1.5, J, order={"force": 1, "torque": 4}, bandwidth={"force": 5.0, "torque": 30.0})
    assert obs2.filters["force"].gains.tolist() == [10.0, 25.0]
    assert obs2.filters["torque"].order == 4
    obs3 = make_observer("geso", 1.5, J, channels="torque")
    assert obs3.channels == {"torque"}
