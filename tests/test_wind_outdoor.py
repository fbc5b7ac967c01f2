"""MIL-spec low-altitude Dryden presets and the discrete 1-cosine gust (envs/wind/outdoor.py)."""

import math

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.envs.wind import make_wind
from fawtgym.envs.wind.dryden import dryden_psd
from fawtgym.envs.wind.dryden_process import DrydenProcess
from fawtgym.envs.wind.outdoor import DrydenWind, OneCosineGust, low_altitude_params


def test_low_altitude_formulas_at_500_ft():
    """h = 500 ft, moderate (W20 = 30 kt): sigma_w = 3 kt, sigma_u = sigma_w / 0.5885^0.4, L_u = 500 / 0.5885^1.2 ft."""
    p = low_altitude_params("moderate", 500 * 0.3048)
    k = 0.177 + 0.000823 * 500
    sig_w = 3.0 * 0.514444
    assert p.sigma == pytest.approx((sig_w / k**0.4, sig_w / k**0.4, sig_w))
    assert p.length == pytest.approx((500 / k**1.2 * 0.3048, 500 / k**1.2 * 0.3048, 500 * 0.3048))
    q = low_altitude_params("moderate", 500 * 0.3048, form="1797")
    assert q.length == pytest.approx((p.length[0], p.length[0] / 2, p.length[2] / 2))
    f = np.logspace(-3, 1, 20)
    for c in "uvw":  # the two forms describe the same turbulence
        # two forms of one spectrum (tests/_tolerance.py): positive terms, each value to its own relative accuracy
        assert_same_law(dryden_psd(p, c, f, 10.0), dryden_psd(q, c, f, 10.0), scale=0.0, what=f"Phi_{c}")


def test_intensity_levels_scale_with_w20():
    s = [low_altitude_params(lvl, 50.0).sigma[2] for lvl in ("light", "moderate", "severe")]
    assert s == pytest.approx([0.1 * 15 * 0.514444, 0.1 * 30 * 0.514444, 0.1 * 45 * 0.514444])


@pytest.mark.parametrize("bad, word", [({"altitude": 400.0}, "altitude.*400"), ({"altitude": -1.0}, "-1.0"),
                                      ({"form": "mil"}, "mil"), ({"mean_wind": -3.0}, "-3.0"),
                                      ({"length_scale": -0.5}, "-0.5")])
def test_bad_options_raise(bad, word):
    with pytest.raises(ValueError, match=word):
        DrydenWind("light", **bad)
    with pytest.raises(ValueError, match="calm"):
        DrydenWind("calm")


def test_dryden_wind_statistics_and_mean():
    wind = make_wind({"name": "dryden-moderate", "altitude": 20.0, "mean_wind": 5.0, "direction_deg": 90.0,
                      "length_scale": 5.0})
    wind.reset(64, seed=0)
    pts = np.zeros((64, 5, 3))
    w = np.stack([wind.step((k + 1) * 0.02, 0.02, pts, np.zeros((64, 3)))[:, 0].copy() for k in range(1500)])
    sig = wind.params.sigma
    assert w[..., 1].mean() == pytest.approx(5.0, abs=0.1)  # blows toward east
    np.testing.assert_allclose(w.std(axis=(0, 1)), [sig[1], sig[0], sig[2]], rtol=0.05)  # u along east


def test_log_profile_mean_wind():
    wind = DrydenWind("light", altitude=6.096, mean_wind=True)  # 20 ft: W = W20
    assert wind.mean[0] == pytest.approx(15 * 0.514444)


def test_one_cosine_gust_profile_and_timing():
    gust = OneCosineGust(4.0, length=10.0, speed=5.0, start_time=1.0)
    gust.reset(1)
    pts = np.zeros((1, 2, 3))
    pts[0, 1, 0] = 0.5  # a point 0.5 m downstream meets the gust 0.1 s later
    dt = 0.01
    w = np.stack([gust.step((k + 1) * dt, dt, pts, np.zeros((1, 3)))[0].copy() for k in range(500)])
    t = dt * (np.arange(500) + 1)
    assert np.all(w[t <= 1.0] == 0.0)
    # half amplitude at x = d_m / 2, i.e. 1 s after the start at 5 m/s
    assert w[np.argmin(abs(t - 2.0)), 0, 0] == pytest.approx(2.0, abs=1e-9)
    assert w[np.argmin(abs(t - 2.1)), 1, 0] == pytest.approx(2.0, abs=1e-9)
    assert w[-1, 0, 0] == pytest.approx(4.0)  # "rise": holds V_m
    full = OneCosineGust(4.0, length=10.0, speed=5.0, start_time=1.0, shape="full")
    full.reset(1)
    w2 = np.stack([full.step((k + 1) * dt, dt, pts, np.zeros((1, 3)))[0, 0, 0] for k in range(600)])
    assert w2.max() == pytest.approx(4.0, abs=1e-6) and w2[-1] == 0.0


def test_gust_bad_input():
    with pytest.raises(ValueError, match="shape"):
        OneCosineGust(shape="square")
    with pytest.raises(ValueError, match="length"):
        OneCosineGust(length=0.0)


def test_dryden_process_used_by_outdoor_is_exact():
    p = low_altitude_params("light", 30.0)
    assert DrydenProcess(p).stationary_std() == pytest.approx(p.sigma, rel=1e-9)
    assert math.isclose(p.length[2], 30.0)


def test_turbulence_advected_by_the_spec_wind_without_mean_output():
    """Turbulence-only output still evolves on L / W(h): lag-1 autocorrelation exp(-W dt / L_u)."""
    from fawtgym.envs.wind.outdoor import log_profile_speed

    wind = DrydenWind("light", altitude=10.0, length_scale=20.0)
    wind.reset(32, seed=2)
    pts = np.zeros((32, 1, 3))
    u = np.stack([wind.step((k + 1) * 0.1, 0.1, pts, np.zeros((32, 3)))[:, 0, 0].copy() for k in range(1500)])
    u = u - u.mean(axis=0)
    rho = float((u[:-1] * u[1:]).sum() / (u * u).sum())
    w_h = log_profile_speed("light", 10.0)
    assert np.all(wind.mean == 0.0)
    assert rho == pytest.approx(math.exp(-w_h * 0.1 / 20.0), abs=0.02)


@pytest.mark.parametrize("rates", [False, True])
def test_dryden_wind_is_its_gust_process_along_the_wind_axes(rates):
    """DrydenWind (one kernel over rows) against its definition written with numpy: the same process (same seed)
    stepped at V = |W_adv - v|, gust [u, v, w] along the wind axes, gradients across the vehicle, plus the mean."""
    from _tolerance import assert_same_law

    wind = DrydenWind("moderate", mean_wind=True, direction_deg=30.0, rates=rates, span=0.4)
    proc = DrydenProcess(wind.params, rates=rates)
    wind.reset(3, seed=5)
    proc.reset(3, seed=5)
    rng = np.random.default_rng(0)
    for k in range(50):
        pts = rng.normal(0.0, 0.3, (3, 5, 3))
        vel = rng.normal(0.0, 2.0, (3, 3))
        got = wind.step((k + 1) * 0.01, 0.01, pts, vel)
        rel = wind.advection - vel
        y = proc.step(0.01, np.sqrt((rel * rel).sum(axis=1)))
        if rates:
            d = (pts - pts[:, :1, :]) @ wind.axes.T
            gv = y[:, None, 1] - d[..., 0] * y[:, None, 5]
            gw = y[:, None, 2] - d[..., 0] * y[:, None, 4] + d[..., 1] * y[:, None, 3]
            gust = np.stack([np.broadcast_to(y[:, None, 0], gv.shape), gv, gw], axis=-1) @ wind.axes
        else:
            gust = (y[:, :3] @ wind.axes)[:, None, :]
        want = wind.mean + gust
        # the kernel and numpy: two implementations of one law (tests/_tolerance.py), at the wind's scale
        assert_same_law(got, np.broadcast_to(want, got.shape), scale=np.abs(want).max(), what=f"step {k}")


def test_dryden_wind_row_equals_that_vehicle_alone():
    seeds = np.random.SeedSequence(3).spawn(3)
    batch = DrydenWind("light", rates=True)
    batch.reset(3, seed=seeds)
    alone = DrydenWind("light", rates=True)
    alone.reset(1, seed=[seeds[2]])
    rng = np.random.default_rng(1)
    for k in range(100):
        pts, vel = rng.normal(0.0, 0.3, (3, 5, 3)), rng.normal(0.0, 3.0, (3, 3))
        np.testing.assert_array_equal(batch.step(0.01 * (k + 1), 0.01, pts, vel)[2],
                                      alone.step(0.01 * (k + 1), 0.01, pts[2:], vel[2:])[0])
