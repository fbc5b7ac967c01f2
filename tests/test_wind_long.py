"""Long wind studies (pytest -m long): paper-length FAWT runs and the FAWT gust spectrum at 1 kHz."""

import numpy as np
import pytest
import scipy.signal

from fawtgym.core.frames import FAWT_HOVER_POINT_NED, fawt_to_ned
from fawtgym.envs.wind import make_wind
from fawtgym.envs.wind.dryden import dryden_psd

PAPER = {30: (5.472, 0.061), 40: (6.876, 0.082), 50: (8.213, 0.116), 60: (9.590, 0.168), 70: (10.920, 0.237)}


@pytest.mark.long
@pytest.mark.parametrize("duty", sorted(PAPER))
def test_single_field_150_s_at_the_hover_point(duty):
    """One field, the paper's 150 s of fan time at 100 Hz, at the 1.5 m hover point: Table 3 within 2 % / 5 %."""
    wind = make_wind(f"fawt-{duty}")
    wind.reset(1, seed=1000 + duty)
    pts = FAWT_HOVER_POINT_NED[None, None, :].copy()
    w = np.array([wind.step((k + 1) * 0.01, 0.01, pts, np.zeros((1, 3)))[0, 0, 0] for k in range(15000)])
    assert w.mean() == pytest.approx(PAPER[duty][0], rel=0.02)
    assert w.var() == pytest.approx(PAPER[duty][1], rel=0.05)


@pytest.mark.long
def test_fawt_spectrum_at_1_khz_matches_aliased_dryden():
    """fawt-50 at the hot wire, fs = 1 kHz: Welch PSD within 10 % of the analytic Dryden PSD folded at fs
    (the exact spectrum of the sampled process) in every octave band from 2 Hz to 400 Hz."""
    wind = make_wind("fawt-50")
    wind.reset(16, seed=5)
    pts = np.broadcast_to(fawt_to_ned(np.array([1.2, 0.0, 0.0])), (16, 1, 3)).copy()
    dt, n = 0.001, 60000
    u = np.stack([wind.step((k + 1) * dt, dt, pts, np.zeros((16, 3)))[:, 0, 0].copy() for k in range(n)])
    f, g = scipy.signal.welch(u - u.mean(axis=0), fs=1 / dt, nperseg=4096, axis=0)
    g = g.mean(axis=1)
    sig2 = wind.variance
    a = sum(sig2 * dryden_psd(wind.params, "u", np.abs(f + k / dt), wind.mean_speed) for k in range(-50, 51))
    lo = 2.0
    while lo < 400:
        m = (f >= lo) & (f < 2 * lo)
        assert g[m].mean() / a[m].mean() == pytest.approx(1.0, abs=0.10), lo
        lo *= 2
