"""The compiled row helpers of fawtgym.core.so3_kernels (and the batch functions of core.so3/frames built on
them) against independent references: scipy's matrix exponential and ``Rotation``, and defining identities.

Independent implementations agree to a tolerance scaled by the magnitudes involved (all O(1) here), never to
one ulp; edge cases: zero and tiny rotation vectors (Taylor branch), angles near pi, every branch of
Shepperd's method, non-finite input, and the rotation check's refusals.
"""

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from fawtgym.core import so3_kernels as k
from fawtgym.core.frames import euler_to_rot, quat_to_rot, rot_to_euler, rot_to_quat
from fawtgym.core.so3 import exp_so3, hat

TOL = 1e-13  # all quantities below are O(1): rotation entries, angles <= pi, unit quaternions


def _rotvecs(rng):
    small = rng.normal(size=(20, 3)) * 1e-6          # Taylor branch (|w|^2 < 1e-8)
    big = rng.normal(size=(20, 3))
    near_pi = rng.normal(size=(10, 3))
    near_pi *= (np.pi - 1e-7) / np.linalg.norm(near_pi, axis=1, keepdims=True)
    return np.concatenate([np.zeros((1, 3)), small, big, near_pi])


def test_exp_so3_row_equals_rodrigues_of_core_so3():
    w = _rotvecs(np.random.default_rng(0))
    out = np.empty((len(w), 3, 3))
    for i in range(len(w)):
        k.exp_so3_row(w[i], out[i])
    reference = np.array([expm(hat(x)) for x in w])
    np.testing.assert_allclose(out, reference, rtol=0, atol=TOL)
    np.testing.assert_allclose(exp_so3(w[:50].reshape(2, 25, 3)), reference[:50].reshape(2, 25, 3, 3), rtol=0, atol=TOL)
    k.exp_so3_row(np.array([np.inf, 0.0, 0.0]), out[0])
    assert np.isnan(out[0]).all()


def test_matrix_vector_helpers():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(2, 3))
    r, s = exp_so3(rng.normal(size=(2, 3)))
    out3, out33 = np.empty(3), np.empty((3, 3))
    k.cross_row(a, b, out3)
    np.testing.assert_allclose(out3, hat(a) @ b, rtol=0, atol=TOL * np.abs(a).max() * np.abs(b).max())
    k.mat_vec_row(r, a, out3)
    np.testing.assert_allclose(out3, r @ a, rtol=0, atol=TOL * np.abs(a).max())
    k.mat_t_vec_row(r, a, out3)
    np.testing.assert_allclose(out3, r.T @ a, rtol=0, atol=TOL * np.abs(a).max())
    k.mat_mul_row(r, s, out33)
    np.testing.assert_allclose(out33, r @ s, rtol=0, atol=TOL)


def test_euler_and_quaternion_rows_equal_core_frames():
    rng = np.random.default_rng(2)
    angles = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], size=(50, 3))
    r = euler_to_rot(angles[:, 0], angles[:, 1], angles[:, 2])
    # Shepperd's four branches: trace largest, and each diagonal entry largest (rotations by ~pi about x, y, z)
    r = np.concatenate([r, exp_so3(np.diag([3.0, 3.0, 3.0])), np.eye(3)[None]])
    euler, quat, back = np.empty((len(r), 3)), np.empty((len(r), 4)), np.empty((len(r), 3, 3))
    for i in range(len(r)):
        k.rot_to_euler_row(r[i], euler[i])
        k.rot_to_quat_row(r[i], quat[i])
        k.quat_to_rot_row(3.0 * quat[i], back[i])       # un-normalized input is normalized first
    scipy_rot = Rotation.from_matrix(r)
    np.testing.assert_allclose(euler[:50], angles, rtol=0, atol=1e-12)
    np.testing.assert_allclose(euler[:, ::-1], scipy_rot.as_euler("ZYX"), rtol=0, atol=1e-12)
    xyzw = scipy_rot.as_quat(canonical=False)
    reference = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    reference *= np.where(reference[:, :1] < 0, -1.0, 1.0)
    np.testing.assert_allclose(quat, reference, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back, r, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rot_to_euler(r), euler, rtol=0, atol=TOL)
    np.testing.assert_allclose(rot_to_quat(r), quat, rtol=0, atol=TOL)
    np.testing.assert_allclose(quat_to_rot(quat), back, rtol=0, atol=TOL)


@pytest.mark.parametrize("bad", [2.0 * np.eye(3), np.diag([1.0, 1.0, -1.0]), np.zeros((3, 3)),
                                 1.001 * np.eye(3), np.full((3, 3), np.nan),
                                 np.random.default_rng(3).normal(size=(3, 3))])
def test_first_non_rotation_finds_the_bad_row(bad):
    rots = exp_so3(np.random.default_rng(4).normal(size=(4, 3)))
    assert k.first_non_rotation(rots, 1e-9) == -1
    rots[2] = bad
    assert k.first_non_rotation(rots, 1e-6) == 2
    assert k.rotation_defect_row(exp_so3(np.array([0.3, -2.0, 1.0]))) < 1e-14
