"""The plain-float N = 1 paths equal the batched paths: QUEST (observers/quest.py ``_quest_unit_single``) and
the STSMO step (observers/gyroless_attitude.py ``GibbsSTSMO._step_single``)."""

import numpy as np
import pytest

from fawtgym.observers import quest as Q
from fawtgym.observers.gyroless_attitude import GibbsSTSMO
from fawtgym.observers.lie import exp_so3

FIELDS = ("R", "quaternion", "gibbs", "lambda_max", "loss")


def _case(rng: np.random.Generator, angle: float, noise: float, nobs: int):
    ref = rng.standard_normal((1, nobs, 3))
    ref /= np.linalg.norm(ref, axis=-1, keepdims=True)
    axis = rng.standard_normal(3)
    R = exp_so3(angle * axis / np.linalg.norm(axis))
    body = np.einsum("ji,nkj->nki", R, ref) + noise * rng.standard_normal((1, nobs, 3))
    body /= np.linalg.norm(body, axis=-1, keepdims=True)
    return body, ref, rng.uniform(0.1, 3.0, (1, nobs))


@pytest.mark.parametrize("nobs", [2, 3, 4])
def test_single_path_equals_batch_path(nobs: int) -> None:
    rng = np.random.default_rng(nobs)
    used = 0
    for k in range(200):
        body, ref, a = _case(rng, angle=rng.uniform(0.0, 3.1), noise=(0.0, 1e-3, 0.1)[k % 3], nobs=nobs)
        used += Q._quest_unit_single(body[0].tolist(), ref[0].tolist(), a[0].tolist()) is not None
        one = Q.quest_unit(body, ref, a)  # N = 1: the float path (or its fallback)
        two = Q.quest_unit(np.repeat(body, 2, 0), np.repeat(ref, 2, 0), np.repeat(a, 2, 0))  # batched
        for f in FIELDS:
            np.testing.assert_allclose(getattr(one, f), getattr(two, f)[:1], rtol=0, atol=1e-15, err_msg=f)
    assert used > 100  # the float path itself was exercised, not only its fallback


def test_single_path_falls_back_near_half_turn() -> None:
    rng = np.random.default_rng(7)
    body, ref, a = _case(rng, angle=np.pi - 1e-4, noise=0.0, nobs=2)
    assert Q._quest_unit_single(body[0].tolist(), ref[0].tolist(), a[0].tolist()) is None  # |g| > 10
    res = Q.quest_unit(body, ref, a)
    assert np.linalg.norm(res.gibbs) > 10
    np.testing.assert_allclose(res.lambda_max, 1.0, atol=1e-12)


def test_stsmo_single_step_equals_batch_step() -> None:
    """Through the exact (t < t_c) and STA phases, with e1 = 0 steps and varying dt."""
    rng = np.random.default_rng(3)
    J = np.diag([0.082, 0.0845, 0.1377])
    for _ in range(5):
        one, two = (GibbsSTSMO(J, t_c=0.3, eta=5.0, kappa1=2.5, kappa2=0.5) for _ in range(2))
        x0 = 0.3 * rng.standard_normal((1, 3))
        one.reset(x0, 0.1 * x0)
        two.reset(np.repeat(x0, 2, 0), np.repeat(0.1 * x0, 2, 0))
        for k in range(200):
            y = 0.3 * rng.standard_normal((1, 3)) if k % 7 else one.x1.copy()
            u = 0.05 * rng.standard_normal((1, 3))
            dt = float(rng.choice([1e-3, 2e-3, 7e-3]))
            one.step(y, u, dt)  # N = 1: the float path
            two.step(np.repeat(y, 2, 0), np.repeat(u, 2, 0), dt)  # batched
            for a, b in ((one.x1, two.x1), (one.x2, two.x2), (one.t, two.t)):
                np.testing.assert_allclose(a, b[:1], rtol=0, atol=1e-15)
        assert one.t[0] > one.t_s  # both phases were covered
