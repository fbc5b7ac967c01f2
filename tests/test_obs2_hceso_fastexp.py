"""hc_eso_so3._exp_so3 (one-branch exponential used in the HC-ESO step) equals lie.exp_so3."""

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.so3 import exp_so3
from fawtgym.observers.hc_eso_so3 import _exp_so3


@pytest.mark.parametrize("scale", [1e-7, 1e-5, 1e-4, 1e-3, 0.1, 1.0, 3.0])
@pytest.mark.parametrize("n", [1, 7, 300])
def test_fast_exp_equals_lie_exp(scale: float, n: int) -> None:
    w = scale * np.random.default_rng(n).standard_normal((n, 3))  # 1e-4: batches mixing both branches
    # two implementations of Rodrigues' formula (tests/_tolerance.py), at the scale of its terms I, w^, w^2
    theta = np.linalg.norm(w, axis=-1).max()
    assert_same_law(_exp_so3(w), exp_so3(w), scale=1.0 + theta + theta**2, what=f"max |w| = {theta:.3g}")
