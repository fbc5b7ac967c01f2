"""hc_eso_so3._exp_so3 (one-branch exponential used in the HC-ESO step) equals lie.exp_so3."""

import numpy as np
import pytest

from fawtgym.observers.hc_eso_so3 import _exp_so3
from fawtgym.observers.lie import exp_so3


@pytest.mark.parametrize("scale", [1e-7, 1e-5, 1e-4, 1e-3, 0.1, 1.0, 3.0])
@pytest.mark.parametrize("n", [1, 7, 300])
def test_fast_exp_equals_lie_exp(scale: float, n: int) -> None:
    w = scale * np.random.default_rng(n).standard_normal((n, 3))  # 1e-4: batches mixing both branches
    np.testing.assert_allclose(_exp_so3(w), exp_so3(w), rtol=0, atol=1e-16)
