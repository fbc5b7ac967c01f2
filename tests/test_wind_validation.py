"""Validations of the FAWT wind that are not its inputs (docs/wind.md, "Calibration is an input").

The FAWT's sigma and mean are *set* from seed-000 Table 3 (TI, U, variance), so reproducing Table 3 checks the
generator's calibration, not the model.  What Table 3 does not give, and is validated here:

* the spectrum's shape: the generated PSD has the Dryden form it claims, and in the band a vehicle responds to
  (f <= 20 Hz) the Dryden form is within 5 % of the von Karman form real turbulence follows;
* the autocorrelation at a lag shorter than the integral time scale, identical for two time steps (exact
  discretization: the process, not only its variance, is independent of dt);
* the spatial profile as sampled: the time mean and r.m.s. across the jet at the hover plane, the half-speed
  point at the array's edge, and self-similar spreading (the shear layer's thickness grows linearly with x).
"""

import math

import numpy as np
import pytest
import scipy.signal

from fawtgym.core.frames import fawt_to_ned
from fawtgym.envs.wind import make_wind
from fawtgym.envs.wind.dryden import dryden_psd
from fawtgym.envs.wind.fawt import fawt_profile

HOTWIRE = fawt_to_ned(np.array([1.2, 0.0, 0.0]))


def _series(wind, n, steps, dt, point):
    pts = np.broadcast_to(np.asarray(point, dtype=float), (n, 1, 3)).copy()
    vel = np.zeros((n, 3))
    return np.stack([wind.step((k + 1) * dt, dt, pts, vel)[:, 0, 0].copy() for k in range(steps)])


def von_karman_u_psd(sigma2: float, length: float, speed: float, f: np.ndarray) -> np.ndarray:
    """One-sided longitudinal von Karman PSD [(m/s)^2/Hz] (MIL-F-8785C form, integrates to sigma2)."""
    return sigma2 * 4.0 * length / speed / (1.0 + (1.339 * 2.0 * math.pi * f * length / speed) ** 2) ** (5.0 / 6.0)


def test_spectrum_has_the_dryden_shape_and_the_form_does_not_matter_below_20_hz():
    wind = make_wind("fawt-50")
    wind.reset(8, seed=3)
    dt, n = 0.001, 8192
    u = _series(wind, 8, n, dt, HOTWIRE)
    f, g = scipy.signal.welch(u - u.mean(axis=0), fs=1 / dt, nperseg=1024, axis=0)
    g = g.mean(axis=1)
    sig2, speed, length = wind.variance, wind.mean_speed, wind.length_scale
    folded = sum(sig2 * dryden_psd(wind.params, "u", np.abs(f + k / dt), speed) for k in range(-50, 51))
    # the shape, normalised by the variance (so the calibrated sigma drops out): octave bands 4-256 Hz within 15 %
    # (8 fields x 8 s: ~100 Welch segments per band at 64 Hz and up, fewer below)
    lo = 4.0
    while lo < 256:
        m = (f >= lo) & (f < 2 * lo)
        assert g[m].mean() / (u.var() / sig2) / folded[m].mean() == pytest.approx(1.0, abs=0.15), lo
        lo *= 2
    # the roll-off is real: the 256-500 Hz band holds far less power than the flat part
    assert g[(f >= 256) & (f < 500)].mean() < 0.6 * g[(f >= 4) & (f < 16)].mean()
    # Dryden vs von Karman with the same sigma and L: < 5 % apart up to 20 Hz (corner U / (2 pi L) ~ 90 Hz)
    fv = np.linspace(0.01, 20.0, 400)
    ratio = dryden_psd(wind.params, "u", fv, speed) * sig2 / von_karman_u_psd(sig2, length, speed, fv)
    assert np.abs(ratio - 1).max() < 0.05


def test_autocorrelation_at_a_short_lag_is_independent_of_the_step():
    """Lag 2 ms (about L / U = 1.8 ms at the hot wire): rho = exp(-U tau / L) for the first-order Dryden u, from
    series sampled at 0.5 ms and 2 ms alike."""
    rho = {}
    for dt in (0.0005, 0.002):
        wind = make_wind("fawt-50")
        wind.reset(32, seed=11)
        u = _series(wind, 32, 3000, dt, HOTWIRE)
        u = u - u.mean(axis=0)
        lag = int(round(0.002 / dt))
        rho[dt] = float(np.mean(u[lag:] * u[:-lag]) / np.mean(u * u))
    want = math.exp(-wind.mean_speed * 0.002 / wind.length_scale)
    assert rho[0.0005] == pytest.approx(want, abs=0.04)
    assert rho[0.002] == pytest.approx(want, abs=0.04)
    assert rho[0.0005] == pytest.approx(rho[0.002], abs=0.05)


def test_sampled_profile_across_the_jet_and_self_similar_spreading():
    """Time mean and r.m.s. of generated samples across y at the hover plane x = 1.5 m (not only the formula)."""
    wind = make_wind("fawt-50")
    wind.reset(8, seed=2)
    ys = np.array([0.0, 0.4, 0.6, 0.72, 0.85, 1.0])
    pts = fawt_to_ned(np.stack([np.full(ys.size, 1.5), ys, np.zeros(ys.size)], axis=1))
    pts_b = np.broadcast_to(pts, (8, ys.size, 3)).copy()
    w = np.stack([wind.step((k + 1) * 0.01, 0.01, pts_b, np.zeros((8, 3)))[..., 0].copy() for k in range(400)])
    mean, rms = w.mean(axis=(0, 1)), w.std(axis=(0, 1))
    core = mean[0]
    assert mean[1] == pytest.approx(core, rel=0.03)          # flat core
    assert mean[3] == pytest.approx(core / 2, rel=0.08)      # half speed at the array's edge (y = 0.72 m)
    assert mean[5] < 0.1 * core                              # quiet outside the jet
    assert rms[3] > 3 * rms[0]                               # the shear layer is where the turbulence is
    # self-similarity: the 10-90 % thickness of the mean profile grows linearly with x (mixing layer)
    yy = np.linspace(0.3, 1.2, 2001)

    def thickness(x: float) -> float:
        m, _ = fawt_profile(np.stack([np.full(yy.size, x), yy, np.zeros(yy.size)], axis=1))
        m = m / m[0]
        return float(yy[np.argmin(np.abs(m - 0.1))] - yy[np.argmin(np.abs(m - 0.9))])

    assert thickness(2.4) / thickness(1.2) == pytest.approx(2.0, rel=0.05)
