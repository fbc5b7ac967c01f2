"""Frame conventions and the one place that converts between them.

fawtgym works in world NED and body FRD (as PX4 and the seed papers: ``e3`` points down, hover
thrust acts along ``-e3`` of the body).  MuJoCo is simulated in a z-up world with a body frame
FLU (x forward, y left, z up).  Both pairs of frames differ by the same proper rotation
``T = diag(1, -1, -1)`` (a half turn about x), so

* a world vector:   ``v_ned = T v_mj``
* a body vector:    ``w_frd = T w_flu``
* an attitude:      ``R_ned = T R_mj T`` (body -> world), since ``T = T^T = T^-1``.

Quaternions appear only at interfaces that demand them (MuJoCo, MAVLink) and are in
(w, x, y, z) order.  All functions accept a leading batch axis.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.so3_kernels import quat_to_rot_rows, rot_to_euler_rows, rot_to_quat_rows

#: The half turn about x that maps MuJoCo's z-up world / FLU body onto NED / FRD.
T_MJ_NED: NDArray[np.float64] = np.diag([1.0, -1.0, -1.0])
#: The diagonal of T (vectors: ``v_ned = SIGN_MJ_NED * v_mj``) and its outer product
#: (matrices: ``R_ned = SIGN2_MJ_NED * R_mj``).
SIGN_MJ_NED: NDArray[np.float64] = np.array([1.0, -1.0, -1.0])
SIGN2_MJ_NED: NDArray[np.float64] = np.outer(SIGN_MJ_NED, SIGN_MJ_NED)
_SIGN = SIGN_MJ_NED


def vec_mj_to_ned(v: ArrayLike) -> NDArray[np.float64]:
    """World (or body) vector from MuJoCo z-up/FLU to NED/FRD, shape (..., 3)."""
    return np.asarray(v, dtype=float) * _SIGN


def vec_ned_to_mj(v: ArrayLike) -> NDArray[np.float64]:
    """World (or body) vector from NED/FRD to MuJoCo z-up/FLU, shape (..., 3)."""
    return np.asarray(v, dtype=float) * _SIGN


def rot_mj_to_ned(r_mj: ArrayLike) -> NDArray[np.float64]:
    """Attitude R (body FLU -> world z-up) to R (body FRD -> world NED), shape (..., 3, 3)."""
    r = np.asarray(r_mj, dtype=float)
    return r * SIGN2_MJ_NED


rot_ned_to_mj = rot_mj_to_ned  # T R T is an involution


def quat_to_rot(q: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternion (w, x, y, z), shape (..., 4), to rotation matrix (..., 3, 3).

    The quaternion is normalized first; a zero quaternion raises ValueError.
    """
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1)
    if np.any(n == 0) or not np.all(np.isfinite(n)):
        raise ValueError(f"quaternion must be finite and non-zero, got {q}")
    rows = np.ascontiguousarray(q.reshape(-1, 4))
    out = np.empty((rows.shape[0], 3, 3))
    quat_to_rot_rows(rows, out)        # one law: so3_kernels.quat_to_rot_row
    return out.reshape(q.shape[:-1] + (3, 3))


def rot_to_quat(r: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix (..., 3, 3) to unit quaternion (w, x, y, z) with w >= 0 (Shepperd's method)."""
    r = np.asarray(r, dtype=float)
    rows = np.ascontiguousarray(r.reshape(-1, 3, 3))
    out = np.empty((rows.shape[0], 4))
    rot_to_quat_rows(rows, out)        # one law: so3_kernels.rot_to_quat_row
    return out.reshape(r.shape[:-2] + (4,))


def quat_mj_to_rot_ned(q_mj: ArrayLike) -> NDArray[np.float64]:
    """MuJoCo free-joint quaternion (w, x, y, z; FLU body -> z-up world) to R (FRD -> NED)."""
    return rot_mj_to_ned(quat_to_rot(q_mj))


def rot_ned_to_quat_mj(r_ned: ArrayLike) -> NDArray[np.float64]:
    """R (FRD -> NED) to the MuJoCo free-joint quaternion (w, x, y, z)."""
    return rot_to_quat(rot_ned_to_mj(r_ned))


def euler_to_rot(roll: ArrayLike, pitch: ArrayLike, yaw: ArrayLike) -> NDArray[np.float64]:
    """Z-Y-X (yaw, pitch, roll) Euler angles in radians to R (body FRD -> world NED), as PX4's Dcm."""
    roll, pitch, yaw = (np.asarray(a, dtype=float) for a in (roll, pitch, yaw))
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    r = np.empty(np.broadcast(roll, pitch, yaw).shape + (3, 3))
    r[..., 0, 0] = cp * cy
    r[..., 0, 1] = sr * sp * cy - cr * sy
    r[..., 0, 2] = cr * sp * cy + sr * sy
    r[..., 1, 0] = cp * sy
    r[..., 1, 1] = sr * sp * sy + cr * cy
    r[..., 1, 2] = cr * sp * sy - sr * cy
    r[..., 2, 0] = -sp
    r[..., 2, 1] = sr * cp
    r[..., 2, 2] = cr * cp
    return r


def rot_to_euler(r: ArrayLike) -> NDArray[np.float64]:
    """R (FRD -> NED) to Z-Y-X Euler angles (roll, pitch, yaw), shape (..., 3)."""
    r = np.asarray(r, dtype=float)
    rows = np.ascontiguousarray(r.reshape(-1, 3, 3))
    out = np.empty((rows.shape[0], 3))
    rot_to_euler_rows(rows, out)       # one law: so3_kernels.rot_to_euler_row
    return out.reshape(r.shape[:-2] + (3,))


# ---- the fan-array wind tunnel (FAWT) frame of Wang et al. (2024) Sec. 7.3 -------------------------------
#: Centre of the fan array in world NED [m]: the array centre is 1.5 m above the floor.
FAWT_ORIGIN_NED: NDArray[np.float64] = np.array([0.0, 0.0, -1.5])
#: Rotation taking FAWT-frame vectors (x stream-wise, y span-wise, z up) to NED: x -> N, y -> -E, z -> -D.
R_FAWT_TO_NED: NDArray[np.float64] = np.diag([1.0, -1.0, -1.0])
#: The Wang et al. (2024) hover point, x = 1.5 m in front of the array at the section centre (FAWT y = z = 0).
FAWT_HOVER_POINT_NED: NDArray[np.float64] = FAWT_ORIGIN_NED + np.array([1.5, 0.0, 0.0])


def fawt_to_ned(p_fawt: ArrayLike) -> NDArray[np.float64]:
    """Point in the FAWT frame (..., 3) to world NED."""
    return np.asarray(p_fawt, dtype=float) @ R_FAWT_TO_NED.T + FAWT_ORIGIN_NED


def ned_to_fawt(p_ned: ArrayLike) -> NDArray[np.float64]:
    """Point in world NED (..., 3) to the FAWT frame."""
    return (np.asarray(p_ned, dtype=float) - FAWT_ORIGIN_NED) @ R_FAWT_TO_NED
