"""Lie-group helpers on SO(3), in one place, batch-first (leading axes allowed everywhere).

hat/vee (the ``x^`` / ``vex`` maps), the exponential and logarithm of SO(3) (Rodrigues), a
geometric integration step ``R_{k+1} = R_k exp(h Omega^)`` that stays on SO(3) to rounding error,
and a projection back onto SO(3) (polar decomposition via SVD) for inputs that drifted.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.so3_kernels import cross_entries_numpy, exp_so3_rows

_SMALL = 1e-8


def hat(w: ArrayLike) -> NDArray[np.float64]:
    """(..., 3) -> skew-symmetric (..., 3, 3) with hat(a) b = a x b."""
    w = np.asarray(w, dtype=float)
    out = np.zeros(w.shape + (3,))
    out[..., 0, 1] = -w[..., 2]
    out[..., 0, 2] = w[..., 1]
    out[..., 1, 0] = w[..., 2]
    out[..., 1, 2] = -w[..., 0]
    out[..., 2, 0] = -w[..., 1]
    out[..., 2, 1] = w[..., 0]
    return out


def cross(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """``a x b`` over the last axis of (..., 3) arrays, broadcast: the one law
    :func:`fawtgym.core.so3_kernels.cross_entries` evaluated by numpy on the component arrays (much cheaper than
    ``numpy.cross`` on small batches, and bitwise equal to the row kernels' :func:`~fawtgym.core.so3_kernels.cross_row`
    row by row)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0], out[..., 1], out[..., 2] = cross_entries_numpy(a[..., 0], a[..., 1], a[..., 2],
                                                                b[..., 0], b[..., 1], b[..., 2])
    return out


def vee(m: ArrayLike) -> NDArray[np.float64]:
    """Inverse of :func:`hat` applied to the skew part: (..., 3, 3) -> (..., 3)."""
    m = np.asarray(m, dtype=float)
    return 0.5 * np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]],
                          axis=-1)


def exp_so3(w: ArrayLike) -> NDArray[np.float64]:
    """Rodrigues' formula exp(w^) for rotation vectors (..., 3); exact near zero (Taylor series).

    One law: the row helper :func:`fawtgym.core.so3_kernels.exp_so3_row`, looped over the rows."""
    w = np.asarray(w, dtype=float)
    rows = np.ascontiguousarray(w.reshape(-1, 3))
    out = np.empty((rows.shape[0], 3, 3))
    exp_so3_rows(rows, out)
    return out.reshape(w.shape[:-1] + (3, 3))


def log_so3(r: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector (..., 3) of R (..., 3, 3), angle in [0, pi]; robust near 0 and pi."""
    r = np.asarray(r, dtype=float)
    cos = 0.5 * (np.trace(r, axis1=-2, axis2=-1) - 1.0)
    v = vee(r)  # = sin(th) * axis
    th = np.arctan2(np.linalg.norm(v, axis=-1), cos)  # well conditioned at every angle (unlike arccos)
    small = th < 1e-6
    factor = np.where(small, 1.0 + th**2 / 6.0, th / np.sin(np.where(small, 1.0, th)))
    out = factor[..., None] * v
    near_pi = th > np.pi - 0.1
    if np.any(near_pi):
        # near pi, sin(th) -> 0: the axis comes from the symmetric part (R + R^T)/2 = cos I + (1 - cos) a a^T
        rs = r[near_pi]
        c = np.clip(cos[near_pi], -1.0, 1.0)[..., None, None]
        aat = ((rs + np.swapaxes(rs, -1, -2)) / 2.0 - c * np.eye(3)) / (1.0 - c)
        col = np.argmax(np.diagonal(aat, axis1=-2, axis2=-1), axis=-1)
        axis = aat[np.arange(aat.shape[0]), col, :]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        sgn = np.sign(np.sum(axis * v[near_pi], axis=-1))
        sgn = np.where(sgn == 0, 1.0, sgn)
        out[near_pi] = (sgn * th[near_pi])[..., None] * axis
    return out


def integrate_rotation(r: ArrayLike, omega_body: ArrayLike, h: float) -> NDArray[np.float64]:
    """One geometric step of R' = R Omega^ with constant body rate: R exp(h Omega^)."""
    return np.asarray(r, dtype=float) @ exp_so3(h * np.asarray(omega_body, dtype=float))


def project_so3(m: ArrayLike) -> NDArray[np.float64]:
    """Nearest rotation (Frobenius) to m (..., 3, 3): U diag(1, 1, det(U V^T)) V^T."""
    u, _, vt = np.linalg.svd(np.asarray(m, dtype=float))
    d = np.sign(np.linalg.det(u @ vt))
    u = u.copy()
    u[..., :, 2] *= d[..., None]
    return u @ vt


def orthogonality_error(r: ArrayLike) -> NDArray[np.float64]:
    """||R^T R - I||_F per matrix, (...,)."""
    r = np.asarray(r, dtype=float)
    return np.linalg.norm(np.swapaxes(r, -1, -2) @ r - np.eye(3), axis=(-2, -1))
