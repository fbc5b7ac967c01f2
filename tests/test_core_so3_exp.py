"""The SO(3) exponentials of the package agree with an independent reference, scipy's
``Rotation.from_rotvec(w).as_matrix()`` (quaternion algebra, not Rodrigues' formula), on batches that mix the
Taylor branch (|w|^2 < 1e-8) and the closed-form branch, and on batches of one branch."""

import numpy as np
import pytest
from _tolerance import assert_same_law
from scipy.spatial.transform import Rotation

from fawtgym.core.so3 import exp_so3

IMPLEMENTATIONS = {"core.so3.exp_so3": exp_so3}  # the one exponential (core.so3_kernels.exp_so3_row, looped)


def _rotvecs(scale: float, n: int) -> np.ndarray:
    w = scale * np.random.default_rng(n).standard_normal((n, 3))
    if n > 2:  # mix both branches in one batch: one tiny and one large rotation vector
        w[0] *= 1e-6 / max(np.linalg.norm(w[0]), 1e-300)
        w[1] *= 2.0 / max(np.linalg.norm(w[1]), 1e-300)
    return w


@pytest.mark.parametrize("impl", list(IMPLEMENTATIONS))
@pytest.mark.parametrize("scale", [1e-7, 1e-5, 1e-4, 1e-3, 0.1, 1.0, 3.0])
@pytest.mark.parametrize("n", [1, 7, 300])
def test_exp_so3_equals_scipy_rotation_from_rotvec(impl: str, scale: float, n: int) -> None:
    w = _rotvecs(scale, n)
    reference = Rotation.from_rotvec(w).as_matrix()
    # two implementations of one law (tests/_tolerance.py), at the scale of the Rodrigues terms I, w^, w^2
    theta = np.linalg.norm(w, axis=-1).max()
    assert_same_law(IMPLEMENTATIONS[impl](w), reference, scale=1.0 + theta + theta**2, what=f"max |w| = {theta:.3g}")


def test_the_reference_catches_a_wrong_exponential() -> None:
    """The comparison has teeth: a 1e-7 relative error in the angle is far outside the tolerance."""
    w = _rotvecs(1.0, 7)
    with pytest.raises(AssertionError):
        theta = np.linalg.norm(w, axis=-1).max()
        assert_same_law(exp_so3(w * (1 + 1e-7)), Rotation.from_rotvec(w).as_matrix(), scale=1.0 + theta + theta**2)
