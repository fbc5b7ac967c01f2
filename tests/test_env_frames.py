"""Frames: NED/FRD <-> MuJoCo round trips and the physical meaning of signs."""

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core import frames
from fawtgym.core.so3 import exp_so3

RNG = np.random.default_rng(7)


def test_vector_round_trip_and_half_turn():
    v = RNG.normal(size=(50, 3))
    assert np.array_equal(frames.vec_mj_to_ned(frames.vec_ned_to_mj(v)), v)
    # NED down is MuJoCo -z (up is +z)
    assert np.allclose(frames.vec_ned_to_mj([0, 0, 1]), [0, 0, -1])
    # NED east is MuJoCo -y (MuJoCo world is x north, y west, z up)
    assert np.allclose(frames.vec_ned_to_mj([0, 1, 0]), [0, -1, 0])


def test_rotation_quaternion_round_trip():
    r = exp_so3(RNG.normal(size=(200, 3)) * 2.0)
    q = frames.rot_ned_to_quat_mj(r)
    assert np.allclose(np.linalg.norm(q, axis=-1), 1.0)
    assert np.all(q[:, 0] >= 0)
    assert np.allclose(frames.quat_mj_to_rot_ned(q), r, atol=1e-12)
    # identity attitude in NED is identity in MuJoCo (both frames turned by the same half turn)
    assert np.allclose(frames.rot_ned_to_quat_mj(np.eye(3)), [1, 0, 0, 0])


def test_quat_matches_scipy_convention():
    from scipy.spatial.transform import Rotation

    q = RNG.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    ref = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # scipy is (x, y, z, w)
    assert_same_law(frames.quat_to_rot(q), ref, scale=1.0, what="quat_to_rot vs scipy")  # tests/_tolerance.py


def test_zero_quaternion_rejected():
    with pytest.raises(ValueError, match="quaternion"):
        frames.quat_to_rot([0, 0, 0, 0])


def test_euler_round_trip_and_px4_sense():
    angles = RNG.uniform([-3, -1.4, -3], [3, 1.4, 3], size=(100, 3))
    r = frames.euler_to_rot(*angles.T)
    assert np.allclose(frames.rot_to_euler(r), angles, atol=1e-9)
    # positive pitch (nose up) turns the body x axis upward, i.e. towards -D
    assert frames.euler_to_rot(0.0, 0.3, 0.0)[2, 0] < 0


def test_fawt_frame_mapping():
    # FAWT x stream-wise -> north, z up -> -down, origin 1.5 m above the floor
    assert np.allclose(frames.fawt_to_ned([0, 0, 0]), [0, 0, -1.5])
    assert np.allclose(frames.fawt_to_ned([1.5, 0, 0]), frames.FAWT_HOVER_POINT_NED)
    assert np.allclose(frames.fawt_to_ned([0, 0, 1]), [0, 0, -2.5])
    p = RNG.normal(size=(10, 3))
    assert np.allclose(frames.ned_to_fawt(frames.fawt_to_ned(p)), p)
    assert np.isclose(np.linalg.det(frames.R_FAWT_TO_NED), 1.0)
