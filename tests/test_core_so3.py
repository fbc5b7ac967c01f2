"""Lie-group helpers (fawtgym/core/so3.py): hat/vee, exp/log, geometric integration keeps R on SO(3)."""

import numpy as np
import pytest
import scipy.linalg
from _tolerance import assert_same_law

from fawtgym.core.so3 import exp_so3, hat, integrate_rotation, log_so3, orthogonality_error, project_so3, vee

RNG = np.random.default_rng(7)


def test_hat_vee_cross_product_and_inverse():
    a, b = RNG.standard_normal((2, 50, 3))
    # hat(a) b and numpy's cross product: two implementations of one law (tests/_tolerance.py)
    scale = (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1)).max()
    assert_same_law(np.einsum("nij,nj->ni", hat(a), b), np.cross(a, b), scale=scale, what="a x b")
    np.testing.assert_allclose(vee(hat(a)), a, atol=0)
    np.testing.assert_allclose(hat(a) + np.swapaxes(hat(a), -1, -2), 0.0, atol=0)


def test_exp_matches_scipy_expm_and_is_a_rotation():
    w = RNG.standard_normal((40, 3)) * RNG.uniform(0, 3, (40, 1))
    w = np.concatenate([w, [[0, 0, 0], [1e-9, 0, 0], [0, 1e-5, 1e-5]]])
    r = exp_so3(w)
    for wi, ri in zip(w, r, strict=True):
        # Rodrigues' formula and scipy's Pade expm: two implementations of one law (tests/_tolerance.py), at the
        # scale of the exponential series' terms (their magnitudes sum to e^|w|)
        theta = np.linalg.norm(wi)
        assert_same_law(ri, scipy.linalg.expm(hat(wi)), scale=np.exp(theta), what=f"|w| = {theta:.3g}")
    assert np.max(orthogonality_error(r)) < 1e-14
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-7, 1e-3, 0.5, 2.0, 3.0, np.pi - 1e-3, np.pi - 1e-6])
def test_exp_log_round_trip(angle):
    axes = RNG.standard_normal((20, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    w = angle * axes
    np.testing.assert_allclose(log_so3(exp_so3(w)), w, atol=1e-9 if angle > np.pi - 1e-5 else 1e-12)
    # and log -> exp reproduces the rotation
    np.testing.assert_allclose(exp_so3(log_so3(exp_so3(w))), exp_so3(w), atol=1e-12)


def test_log_at_exactly_pi_returns_a_valid_rotation_vector():
    r = np.diag([1.0, -1.0, -1.0])
    w = log_so3(r)
    assert np.isclose(np.linalg.norm(w), np.pi)
    np.testing.assert_allclose(exp_so3(w), r, atol=1e-12)


def test_integrate_rotation_is_exact_for_constant_rate():
    r0 = exp_so3(RNG.standard_normal(3))
    w = RNG.standard_normal(3)
    r = r0.copy()
    for _ in range(100):
        r = integrate_rotation(r, w, 0.01)
    # 100 exact steps and one expm: two implementations of one law (tests/_tolerance.py)
    assert_same_law(r, r0 @ scipy.linalg.expm(hat(w)), scale=1.0, steps=100, what="R(1 s)")


def test_project_so3():
    r = exp_so3(RNG.standard_normal((10, 3)))
    # a rotation is its own projection (the SVD route and the identity; tests/_tolerance.py, 3 x 3 SVD: cond 3)
    assert_same_law(project_so3(r), r, scale=1.0, cond=3, what="projection of a rotation")
    noisy = r + 1e-3 * RNG.standard_normal(r.shape)
    assert np.max(orthogonality_error(project_so3(noisy))) < 1e-14
    np.testing.assert_allclose(np.linalg.det(project_so3(noisy)), 1.0, atol=1e-14)
    # a reflection is mapped to a proper rotation
    assert np.linalg.det(project_so3(np.diag([1.0, 1.0, -1.0]))) > 0


def _integrate(steps: int, batch: int, h: float = 1e-3, chunk: int = 100_000) -> np.ndarray:
    """R_{k+1} = R_k exp(h Omega_k) sequentially for ``steps`` updates on ``batch`` vehicles.

    exp(h Omega_k) is computed batched per chunk (exp_so3 is element-wise, so the values are the same as in
    integrate_rotation); the sequential product -- where rounding accumulates -- is done step by step.
    """
    r = np.tile(np.eye(3), (batch, 1, 1))
    scale = np.linspace(0.5, 3.0, batch)[None, :, None]
    phase = np.arange(batch)[None, :, None]
    for c0 in range(0, steps, chunk):
        t = (c0 + np.arange(min(chunk, steps - c0)))[:, None, None] * h
        w = scale * np.concatenate([np.sin(0.7 * t + phase), np.cos(1.3 * t + 2 * phase),
                                    np.sin(0.2 * t + 0 * phase) + 0.5], axis=-1)
        e = exp_so3(h * w)
        for ek in e:
            r = r @ ek
    return r


def test_orthogonality_after_many_updates_batched():
    """64 vehicles x 1 min at 1 kHz (the full sequential hour is the long test below): error < 1e-11."""
    r = _integrate(60_000, 64)
    assert np.max(orthogonality_error(r)) < 1e-11
    assert np.all(np.isfinite(r))


@pytest.mark.long
def test_orthogonality_after_one_hour_at_1khz():
    """3.6e6 sequential updates (1 hour at 1 kHz): orthogonality error < 1e-9 (measured ~5e-13)."""
    r = _integrate(3_600_000, 4)
    assert np.max(orthogonality_error(r)) < 1e-9
