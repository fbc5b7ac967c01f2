"""Dryden shaping filters: spectrum, step-size independence, seeding, batching (envs/wind/dryden*.py)."""

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.signal
from _tolerance import assert_same_law

from fawtgym.envs.wind.dryden import V_FLOOR, DrydenParams, dryden_psd
from fawtgym.envs.wind.dryden_process import DrydenProcess


@pytest.mark.parametrize("form", ["8785c", "1797"])
def test_lyapunov_std_equals_requested_sigma(form):
    p = DrydenParams(sigma=(1.3, 0.7, 0.4), length=(7.0, 3.0, 2.0), form=form)
    std = DrydenProcess(p).stationary_std()
    np.testing.assert_allclose(std, [1.3, 0.7, 0.4], rtol=1e-9)


@pytest.mark.parametrize("form", ["8785c", "1797"])
def test_analytic_psd_integrates_to_variance(form):
    p = DrydenParams(sigma=(1.3, 0.7, 0.4), length=(7.0, 3.0, 2.0), form=form)
    for i, c in enumerate("uvw"):
        total, _ = scipy.integrate.quad(lambda f, c=c: float(dryden_psd(p, c, f, 10.0)), 0, np.inf, limit=200)
        assert total == pytest.approx(p.sigma[i] ** 2, rel=1e-6)


def test_forms_agree_for_the_same_turbulence():
    """MIL-HDBK-1797 with L_v = L_u / 2 is the same lateral spectrum as MIL-F-8785C with L_v = L_u."""
    f = np.logspace(-3, 2, 50)
    a = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(10.0, 10.0, 4.0), form="8785c")
    b = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(10.0, 5.0, 2.0), form="1797")
    for c in "uvw":
        # two forms of one spectrum (tests/_tolerance.py): positive terms, no cancellation, each value to its own
        # relative accuracy (scale 0)
        assert_same_law(dryden_psd(a, c, f, 7.0), dryden_psd(b, c, f, 7.0), scale=0.0, what=f"Phi_{c}")


@pytest.mark.parametrize("form", ["8785c", "1797"])
def test_welch_psd_matches_analytic_dryden(form):
    """Octave-band mean of the Welch PSD within 10 % of the analytic PSD from 0.1 Hz to fs / 10 = 10 Hz.

    L = 5 m, V = 10 m/s (corner V / (2 pi L) = 0.32 Hz: the band spans 0.3-30 corners), fs = 100 Hz,
    48 fields x 300 s, Welch segments of 4096 samples (resolution 0.024 Hz).
    """
    p = DrydenParams(sigma=(1.0, 0.8, 0.5), length=(5.0, 5.0, 5.0), form=form)
    proc = DrydenProcess(p)
    proc.reset(48, seed=11)
    fs, v = 100.0, 10.0
    y = proc.sample(30000, 1.0 / fs, v)
    for i, c in enumerate("uvw"):
        f, g = scipy.signal.welch(y[:, :, i], fs=fs, nperseg=4096, axis=0)
        g = g.mean(axis=1)
        a = dryden_psd(p, c, f, v)
        lo = 0.1
        while lo < 10.0:
            m = (f >= lo) & (f < 2 * lo)
            ratio = g[m].mean() / a[m].mean()
            assert abs(ratio - 1.0) < 0.10, (form, c, lo, ratio)
            lo *= 2


def _variance(dt, discretization="exact", n_steps=3000, seed=3, length=0.5):
    p = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(length, length, length))
    proc = DrydenProcess(p, discretization=discretization)
    proc.reset(512, seed=seed)
    return proc.sample(n_steps, dt, 10.0).var(axis=(0, 1))


def test_variance_independent_of_time_step():
    """dt = 1 ms and dt = 10 ms give the same variance within 5 % (and both the requested sigma^2 = 1)."""
    v1, v10 = _variance(0.001), _variance(0.01)
    np.testing.assert_allclose(v1 / v10, 1.0, atol=0.05)
    np.testing.assert_allclose(v1, 1.0, atol=0.05)
    np.testing.assert_allclose(v10, 1.0, atol=0.05)


def test_naive_zoh_is_step_dependent_where_exact_is_not():
    """At the FAWT's d / L ~ 5 (L = 2 cm, V = 10 m/s, dt = 10 ms) held-noise ZOH loses ~2/3 of the variance.

    Exact: 1; ZOH (first order): 2 L (1 - a) / (d (1 + a)), a = exp(-d / L) = 0.39 (u).
    """
    zoh = _variance(0.01, "zoh", n_steps=500, length=0.02)
    exact = _variance(0.01, "exact", n_steps=500, length=0.02)
    a = math.exp(-5.0)
    assert zoh[0] == pytest.approx(2 * (1 - a) / (5 * (1 + a)), rel=0.05)
    np.testing.assert_allclose(exact, 1.0, atol=0.03)


def test_seeded_reproducibility_and_per_field_streams():
    p = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(2.0, 2.0, 2.0))
    a, b, c = DrydenProcess(p), DrydenProcess(p), DrydenProcess(p)
    a.reset(4, seed=5)
    b.reset(4, seed=5)
    c.reset(1, seed=5)
    ya, yb, yc = a.sample(300, 0.01, 8.0), b.sample(300, 0.01, 8.0), c.sample(300, 0.01, 8.0)
    np.testing.assert_array_equal(ya, yb)
    # field 0 does not depend on N: a row of a batch of 4 and a batch of 1, possibly two paths (tests/_tolerance.py)
    assert_same_law(ya[:, 0], yc[:, 0], scale=a.stationary_std().max(), steps=300, what="field 0")
    a.reset(4, seed=6)
    assert not np.allclose(a.sample(300, 0.01, 8.0), ya)


def test_batched_fields_are_independent():
    p = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(1.0, 1.0, 1.0))
    proc = DrydenProcess(p)
    proc.reset(8, seed=9)
    y = proc.sample(20000, 0.01, 10.0)[:, :, 0]  # 200 s, L/V = 0.1 s: ~1000 independent samples
    r = np.corrcoef(y.T)
    off = r[~np.eye(8, dtype=bool)]
    assert np.max(np.abs(off)) < 0.15
    assert abs(off.mean()) < 0.05


def test_batched_airspeeds_per_field():
    """A per-field airspeed: the slower field decorrelates more slowly (lag-1 autocorrelation exp(-V dt / L))."""
    p = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(1.0, 1.0, 1.0))
    proc = DrydenProcess(p)
    proc.reset(2, seed=1)
    speeds = np.array([2.0, 20.0])
    y = np.stack([proc.step(0.01, speeds)[:, 0].copy() for _ in range(8000)])
    for k, vs in enumerate(speeds):
        rho = np.corrcoef(y[:-1, k], y[1:, k])[0, 1]
        assert rho == pytest.approx(math.exp(-vs * 0.01), abs=0.02)


def test_airspeed_floor():
    p = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(1.0, 1.0, 1.0))
    a, b = DrydenProcess(p), DrydenProcess(p)
    a.reset(1, seed=2)
    b.reset(1, seed=2)
    np.testing.assert_array_equal(a.sample(50, 0.01, 0.0), b.sample(50, 0.01, V_FLOOR))


def test_rates_variance_matches_spectrum():
    """p (= dw/dy) from the Lyapunov solution equals the integral of the MIL-F-8785C Phi_p."""
    span, lw, sw = 0.5, 20.0, 1.5
    p = DrydenParams(sigma=(1.0, 1.0, sw), length=(20.0, 20.0, lw), span=span)
    proc = DrydenProcess(p, rates=True)
    k_p = sw**2 * 0.8 * (math.pi / (4 * span)) ** (1 / 3) * lw ** (-2 / 3)
    phi_p = lambda om: k_p / (1 + (4 * span * om / math.pi) ** 2)
    var_p, _ = scipy.integrate.quad(phi_p, 0, np.inf)
    assert proc.stationary_std()[3] ** 2 == pytest.approx(var_p, rel=1e-9)
    # q = s/(1 + 4b s / pi) w: variance = int Omega^2 / (1 + (4 b Omega / pi)^2) Phi_w dOmega
    phi_w = lambda om: sw**2 * lw / math.pi * (1 + 3 * (lw * om) ** 2) / (1 + (lw * om) ** 2) ** 2
    tq = 4 * span / math.pi
    var_q, _ = scipy.integrate.quad(lambda om: om**2 / (1 + (tq * om) ** 2) * phi_w(om), 0, np.inf, limit=400)
    assert proc.stationary_std()[4] ** 2 == pytest.approx(var_q, rel=1e-6)


@pytest.mark.parametrize("kwargs, word", [
    ({"sigma": (1.0, -1.0, 1.0), "length": (1.0, 1.0, 1.0)}, "sigma_v"),
    ({"sigma": (1.0, 1.0, 1.0), "length": (1.0, -2.0, 1.0)}, "-2.0"),
    ({"sigma": (1.0, 1.0, 1.0), "length": (1.0, 1.0, float("nan"))}, "L_w"),
    ({"sigma": (1.0, 1.0, 1.0), "length": (1.0, 1.0, 1.0), "form": "8785"}, "8785"),
])
def test_bad_parameters_raise(kwargs, word):
    with pytest.raises(ValueError, match=word):
        DrydenParams(**kwargs)


def test_expm_small_matches_scipy():
    import scipy.linalg

    from fawtgym.envs.wind.dryden_discrete import expm_small

    for rates in (False, True):
        a = DrydenProcess(DrydenParams(sigma=(1.0, 1.0, 1.0), length=(0.015, 0.02, 0.01)), rates=rates).a
        for d in (1e-5, 1e-3, 0.08, 1.0, 30.0):
            # two implementations of one matrix exponential (tests/_tolerance.py): entries <= 1 (a stable
            # matrix), rounding of n-term products (cond n) through the scaling-and-squaring steps
            squarings = max(1, math.ceil(math.log2(4 * np.abs(a * d).sum(axis=0).max())))
            assert_same_law(expm_small(a * d), scipy.linalg.expm(a * d), scale=1.0, steps=squarings, cond=a.shape[0],
                            what=f"rates={rates}, d={d}")


@pytest.mark.parametrize("rates", [False, True])
def test_a_row_does_not_depend_on_the_other_rows(rates):
    """Row i of an N = 5 run is bit for bit the run of that field alone with the same seed and airspeeds: the rows'
    airspeeds vary and fall in different step-matrix bins, some shared, some not (same path, tests/_tolerance.py)."""
    p = DrydenParams(sigma=(1.0, 0.8, 0.5), length=(0.02, 0.02, 0.02))
    seeds = np.random.SeedSequence(7).spawn(5)
    base = np.array([1.0, 8.0, 8.0, 9.5, 30.0])
    speeds = [base * (1.0 + 0.3 * np.sin(0.07 * k + np.arange(5))) for k in range(600)]  # crosses block refills
    batch = DrydenProcess(p, rates=rates)
    batch.reset(5, seed=seeds)
    got = np.stack([batch.step(0.01, v) for v in speeds])
    for i in range(5):
        alone = DrydenProcess(p, rates=rates)
        alone.reset(1, seed=[seeds[i]])
        ref = np.stack([alone.step(0.01, v[i]) for v in speeds])
        np.testing.assert_array_equal(got[:, i], ref[:, 0], err_msg=f"row {i}")
    # and the same with a scalar airspeed for all rows
    batch.reset(5, seed=seeds)
    alone = DrydenProcess(p, rates=rates)
    alone.reset(1, seed=[seeds[3]])
    for k in range(300):
        np.testing.assert_array_equal(batch.step(0.01, 8.0 + k % 3)[3], alone.step(0.01, 8.0 + k % 3)[0])


def test_step_matrix_bins_at_their_edges():
    """Speeds right at, just inside and just outside bin edges (and outside the table) pick the bin of the table's
    own formula, whose matrix is the exact step of the bin's length."""
    from fawtgym.envs.wind.dryden_discrete import BIN, D_MAX, D_MIN, expm_small

    p = DrydenParams(sigma=(1.0, 0.8, 0.5), length=(0.02, 0.02, 0.02))
    proc = DrydenProcess(p)
    proc.reset(1, seed=2)
    table, dt = proc.table, 0.01
    for k in (-110, -109, 20, 21, 150):
        edge = math.exp((k + 0.5) * BIN)
        for d in (edge * (1 - 1e-9), edge * (1 + 1e-9)):
            b = table.bin_of(d)
            assert abs(math.log(table.bin_length(b) / d)) <= BIN / 2 + 1e-9  # the nearest bin
            x0 = proc.x.copy()
            proc.step(dt, d / dt)
            assert table.filled[b]
            ad, _ = proc.discrete(d)
            np.testing.assert_array_equal(ad, expm_small(proc.a * table.bin_length(b)))
            assert np.all(np.isfinite(proc.x)) and not np.array_equal(proc.x, x0)
    assert table.bin_of(D_MIN * 0.5) == table.bin_of(D_MIN)
    assert table.bin_of(2 * D_MAX) == table.bin_of(D_MAX) == table.matrices.shape[0] - 1


@pytest.mark.parametrize("bad, word", [
    ({"dt": 0.0}, "dt"), ({"dt": float("nan")}, "dt"), ({"dt": "0.01"}, "dt"), ({"dt": True}, "dt"),
    ({"airspeed": float("inf")}, "airspeed"), ({"airspeed": np.ones(3)}, "airspeed"),
])
@pytest.mark.parametrize("n", [1, 2])
def test_bad_step_input_raises_the_same_at_every_n(bad, word, n):
    p = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(1.0, 1.0, 1.0))
    proc = DrydenProcess(p)
    proc.reset(n, seed=0)
    args = {"dt": 0.01, "airspeed": 5.0, **bad}
    with pytest.raises(ValueError, match=word) as err:
        proc.step(**args)
    assert "\n" not in str(err.value)


def test_step_before_reset_and_bad_seed_raise():
    proc = DrydenProcess(DrydenParams(sigma=(1.0, 1.0, 1.0), length=(1.0, 1.0, 1.0)))
    with pytest.raises(RuntimeError, match="reset"):
        proc.step(0.01, 5.0)
    with pytest.raises(ValueError, match="seed"):
        proc.reset(2, seed=[np.random.SeedSequence(1)])
    with pytest.raises(ValueError, match="seed"):
        proc.reset(2, seed=1.5)
    with pytest.raises(ValueError, match="n must"):
        proc.reset(True)
