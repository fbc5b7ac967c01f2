"""QUEST (pdt_sta_attitude_silva2023.txt eqs. 56-66, Shuster and Oh 1981), batch-first."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.core.frames import quat_to_rot
from fawtgym.core.so3 import exp_so3, log_so3
from fawtgym.observers.gibbs import rot_to_gibbs
from fawtgym.observers.quest import quest, wahba_loss

REF = np.array([[0.0, 0.0, -9.80665], [0.22, 0.0, 0.42], [0.3, -0.5, 0.1]])


def _rotations(n: int, seed: int = 0, scale: float = 1.2) -> np.ndarray:
    return exp_so3(np.random.default_rng(seed).normal(size=(n, 3)) * scale)


def test_noise_free_exact_with_weights() -> None:
    R = _rotations(500)
    body = np.einsum("nji,kj->nki", R, REF)  # b = R^T r
    for w in (None, [1.0, 1.0], [1 / 1.5e-5, 1 / 2e-2], [0.2, 5.0]):
        res = quest(body[:, :2], REF[:2], w)
        assert np.abs(res.R - R).max() < 1e-9
        assert np.abs(quat_to_rot(res.quaternion) - R).max() < 1e-9  # (w, x, y, z) convention of envs/frames
        assert np.abs(res.lambda_max - 1.0).max() < 1e-12
    res = quest(body, REF, [1.0, 2.0, 3.0])
    assert np.abs(res.R - R).max() < 1e-9
    small = np.linalg.norm(log_so3(R), axis=1) < 2.5  # Gibbs vector well conditioned there
    assert np.abs(res.gibbs[small] - rot_to_gibbs(R[small])).max() < 1e-9


def test_half_turn_is_finite_and_exact() -> None:
    R = exp_so3(np.array([[np.pi, 0, 0], [0, np.pi - 1e-9, 0], [0.0, 0.0, 3.1]]))
    body = np.einsum("nji,kj->nki", R, REF)
    res = quest(body, REF)
    assert np.all(np.isfinite(res.gibbs)) and np.abs(res.R - R).max() < 1e-9


def test_noisy_minimizes_wahba_loss() -> None:
    rng = np.random.default_rng(2)
    R = _rotations(50, 1)
    body = np.einsum("nji,kj->nki", R, REF) + 0.05 * rng.normal(size=(50, 3, 3))
    w = np.array([1.0, 3.0, 0.5])
    res = quest(body, REF, w)
    best = wahba_loss(res.R, body, REF, w)
    assert np.allclose(best, res.loss, atol=1e-10)  # eq. 56 at the optimum = 1 - lambda_max
    for _ in range(5):  # any perturbation increases the loss
        Rp = res.R @ exp_so3(rng.normal(size=(50, 3)) * 1e-3)
        assert np.all(wahba_loss(Rp, body, REF, w) >= best - 1e-14)
    # weights matter: a heavy accelerometer weight pins the tilt to it
    b2 = np.einsum("nji,kj->nki", R, REF[:2])
    b2[:, 1] += 0.05
    r_heavy = quest(b2, REF[:2], [1e4, 1.0]).R
    g_body = np.einsum("nji,j->ni", r_heavy, REF[0] / np.linalg.norm(REF[0]))
    assert np.abs(g_body - b2[:, 0] / np.linalg.norm(b2[:, 0], axis=1, keepdims=True)).max() < 1e-3


def test_batch_equals_single() -> None:
    R = _rotations(4, 3)
    body = np.einsum("nji,kj->nki", R, REF[:2]) + 0.01
    batch = quest(body, REF[:2], [2.0, 1.0])
    for i in range(4):
        one = quest(body[i], REF[:2], [2.0, 1.0])
        # N = 1 and a row of the batch: the same kernel on the same row, bitwise (a row does not see the others)
        np.testing.assert_array_equal(one.R[0], batch.R[i], err_msg=f"row {i}")


def test_bad_inputs_raise() -> None:
    with pytest.raises(ValueError, match="at least 2"):
        quest(REF[:1], REF[:1])
    with pytest.raises(ValueError, match="collinear"):
        quest(np.array([[0, 0, 1.0], [0, 0, 2.0]]), REF[:2])
    with pytest.raises(ValueError, match="zero vector"):
        quest(np.array([[0, 0, 0.0], [0, 1, 0.0]]), REF[:2])
    with pytest.raises(ValueError, match="weights"):
        quest(REF[:2], REF[:2], [1.0, -1.0])
    with pytest.raises(ValueError, match="non-finite"):
        quest(np.array([[np.nan, 0, 1.0], [0, 1, 0.0]]), REF[:2])
    with pytest.raises(ValueError, match="shape"):
        quest(np.zeros((2, 2)), REF[:2])
