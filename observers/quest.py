"""QUEST (Shuster and Oh, 1981): least-squares attitude from >= 2 weighted vector pairs, batch-first.

Source: Silva and Santos (2023), Sec. 4.2, eqs. 56-66 (Wahba's loss (56), the K matrix (57)-(63), its largest
eigenvalue (64), the optimal Gibbs vector (65) and quaternion (66)), after Shuster and Oh, J. Guidance and
Control 4(1), 1981.

Frames.  The paper's attitude matrix D^{b/g} maps reference (S^g) components to body (S^b) components,
mu_b = D mu_g.  With world NED / body FRD this is D = R^T for the project's R (body -> world).  The returned
Gibbs vector ``gibbs`` is the paper's g of D (so R = D(g)^T, see :func:`fawtgym.observers.gibbs.gibbs_to_rot`),
and ``quaternion`` is the project's (w, x, y, z) quaternion of R: Shuster's scalar-last q = [g; 1]/sqrt(1 + g^T g)
of D reordered to (q4, q1, q2, q3) (the same numbers: D(q) = R(q)^T).

Algorithm (one row kernel, :func:`quest_row`, shared by :func:`quest` and the ``pdt_sta`` observer).  Vectors are
unit length (QUEST's assumption; then lambda_max <= 1 with normalized weights a_i / m, eq. 63).  lambda_max is
found by Newton-Raphson on Shuster's characteristic polynomial of K, started from 1; g from eq. 65 by a 3x3
solve.  Where that solve is ill-conditioned (|g| > 10: rotation angle above 168.6 deg, g -> infinity at pi) the
problem is solved again with the reference vectors rotated by pi about x, y or z (Shuster and Oh's method of
sequential rotations; one of the three rotated attitudes is within 120 deg of identity) and the quaternion
rotated back exactly; the eigenvector of K (eq. 64, ``numpy.linalg.eigh``) remains as the last resort, so every
attitude is returned finitely.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.kernel_types import NO_REFCOUNT, REFCOUNTED
from fawtgym.core.so3 import cross
from fawtgym.core.so3_kernels import cross_entries, quat_to_rot_row

_NEWTON_ITERS = 8
#: where the attitude is a half turn the Gibbs vector does not exist: reported with this norm
GIBBS_MAX = 1e8
#: beyond |g| = 10 (rotation angle > 168.6 deg) eq. 65 loses digits: sequential rotations
_GIBBS_SWITCH = 10.0


@dataclasses.dataclass(frozen=True)
class QuestResult:
    """QUEST output, batch-first: rotation ``R`` (N, 3, 3) body -> world, ``quaternion`` (N, 4) (w, x, y, z)
    of R, ``gibbs`` (N, 3) the paper's Gibbs vector of D = R^T (inf-free; where the attitude is a
    half turn the Gibbs vector does not exist and is reported with norm ``GIBBS_MAX``), ``lambda_max`` (N,),
    ``loss`` (N,) = 1 - lambda_max (Wahba's loss (56) with unit vectors and weights summing to 1)."""

    R: NDArray[np.float64]
    quaternion: NDArray[np.float64]
    gibbs: NDArray[np.float64]
    lambda_max: NDArray[np.float64]
    loss: NDArray[np.float64]


# --------------------------------------------------------------------------------------------------
# the row kernel
# --------------------------------------------------------------------------------------------------
@njit(cache=True)
def _profile(b, r, a, f0, f1, f2):
    """B (eq. 61) and z (eq. 62) with weights a_i / sum a (eq. 63), the references flipped componentwise by
    (f0, f1, f2) (+-1: a rotation by pi about an axis, or the identity).  Returns (B row-major 9, z 3)."""
    sa = 0.0
    for i in range(a.shape[0]):
        sa += a[i]
    B00 = B01 = B02 = B10 = B11 = B12 = B20 = B21 = B22 = 0.0
    z0 = z1 = z2 = 0.0
    for i in range(b.shape[0]):
        w = a[i] / sa  # eq. 63
        p0, p1, p2 = w * b[i, 0], w * b[i, 1], w * b[i, 2]  # a_i b_i
        s0, s1, s2 = f0 * r[i, 0], f1 * r[i, 1], f2 * r[i, 2]  # r_i
        B00 += p0 * s0
        B01 += p0 * s1
        B02 += p0 * s2
        B10 += p1 * s0
        B11 += p1 * s1
        B12 += p1 * s2
        B20 += p2 * s0
        B21 += p2 * s1
        B22 += p2 * s2
        x0, x1, x2 = cross_entries(p0, p1, p2, s0, s1, s2)  # eq. 62: a_i b_i x r_i
        z0 += x0
        z1 += x1
        z2 += x2
    return B00, B01, B02, B10, B11, B12, B20, B21, B22, z0, z1, z2


@njit(cache=True)
def _newton_lambda(a1, b1, c1, rho, d1):
    """lambda_max: Newton-Raphson on Shuster's characteristic equation of K (eq. 58), started from 1,
    (l^2 - a1)(l^2 - b1) - c1 l + c1 rho - d1 = 0 (quadratic convergence: usually 2-4 iterations)."""
    lam = 1.0
    for _ in range(_NEWTON_ITERS):
        l2 = lam * lam
        f = (l2 - a1) * (l2 - b1) - c1 * lam + c1 * rho - d1
        df = 2.0 * lam * (2.0 * l2 - a1 - b1) - c1
        step = f / df if abs(df) > 1e-14 else 0.0
        lam = lam - step
        if abs(step) < 1e-15:
            break
    return lam


@njit(cache=True, inline="always")
def _sym_adjugate(x00, x11, x22, x01, x02, x12):
    """The adjugate of a symmetric 3x3 matrix X (its six distinct cofactors c00, c01, c02, c11, c12, c22) and det X
    (expanded along the first row)."""
    c00 = x11 * x22 - x12 * x12
    c01 = x12 * x02 - x01 * x22
    c02 = x01 * x12 - x11 * x02
    c11 = x22 * x00 - x02 * x02
    c12 = x02 * x01 - x00 * x12
    c22 = x00 * x11 - x01 * x01
    return c00, c01, c02, c11, c12, c22, x00 * c00 + x01 * c01 + x02 * c02


@njit(cache=True)
def _gibbs_solve(b, r, a, f0, f1, f2):
    """Eqs. 57-65 in the frame of the references flipped by (f0, f1, f2): (g0, g1, g2, lambda_max, ok); ok is
    False where eq. 65 is ill-conditioned (|det M| <= 1e-9 or |g| > 10; g is then meaningless)."""
    B00, B01, B02, B10, B11, B12, B20, B21, B22, z0, z1, z2 = _profile(b, r, a, f0, f1, f2)
    # eq. 59 S = B + B^T, eq. 60 rho = tr B
    S00, S01, S02, S11, S12, S22 = 2.0 * B00, B01 + B10, B02 + B20, 2.0 * B11, B12 + B21, 2.0 * B22
    rho = B00 + B11 + B22
    C00, C01, C02, C11, _, C22, det_s = _sym_adjugate(S00, S11, S22, S01, S02, S12)  # cofactors of S, det S
    Sz0 = S00 * z0 + S01 * z1 + S02 * z2
    Sz1 = S01 * z0 + S11 * z1 + S12 * z2
    Sz2 = S02 * z0 + S12 * z1 + S22 * z2
    # eq. 58 written as Shuster's quartic: a1 = rho^2 - tr adj S, b1 = rho^2 + z.z, c1 = det S + z.S z, d1 = z.S^2 z
    rho2 = rho * rho
    a1 = rho2 - (C00 + C11 + C22)
    b1 = rho2 + (z0 * z0 + z1 * z1 + z2 * z2)
    c1 = det_s + (z0 * Sz0 + z1 * Sz1 + z2 * Sz2)
    d1 = Sz0 * Sz0 + Sz1 * Sz1 + Sz2 * Sz2
    lam = _newton_lambda(a1, b1, c1, rho, d1)
    # eq. 65: g = [(lambda + rho) I - S]^-1 z = adj(M) z / det M, M symmetric
    lr = lam + rho
    D00, D01, D02, D11, D12, D22, det_m = _sym_adjugate(lr - S00, lr - S11, lr - S22, -S01, -S02, -S12)
    if not abs(det_m) > 1e-9:
        return 0.0, 0.0, 0.0, lam, False
    g0 = (D00 * z0 + D01 * z1 + D02 * z2) / det_m
    g1 = (D01 * z0 + D11 * z1 + D12 * z2) / det_m
    g2 = (D02 * z0 + D12 * z1 + D22 * z2) / det_m
    ok = g0 * g0 + g1 * g1 + g2 * g2 <= _GIBBS_SWITCH * _GIBBS_SWITCH  # also False for a non-finite g
    return g0, g1, g2, lam, ok


@njit(cache=True, **REFCOUNTED)
def _eigh_quaternion(b, r, a):
    """The last resort, eq. 64: the eigenvector of K for its largest eigenvalue, (w, x, y, z) with w >= 0, and
    that eigenvalue."""
    B00, B01, B02, B10, B11, B12, B20, B21, B22, z0, z1, z2 = _profile(b, r, a, 1.0, 1.0, 1.0)
    rho = B00 + B11 + B22
    K = np.empty((4, 4))
    K[0, 0], K[0, 1], K[0, 2] = 2.0 * B00 - rho, B01 + B10, B02 + B20
    K[1, 0], K[1, 1], K[1, 2] = B01 + B10, 2.0 * B11 - rho, B12 + B21
    K[2, 0], K[2, 1], K[2, 2] = B02 + B20, B12 + B21, 2.0 * B22 - rho
    K[0, 3], K[1, 3], K[2, 3] = z0, z1, z2
    K[3, 0], K[3, 1], K[3, 2] = z0, z1, z2
    K[3, 3] = rho
    w, v = np.linalg.eigh(K)  # ascending eigenvalues; scalar-last eigenvectors
    s = -1.0 if v[3, 3] < 0 else 1.0
    return s * v[3, 3], s * v[0, 3], s * v[1, 3], s * v[2, 3], w[3]


#: Shuster and Oh's sequential rotations: the references rotated by pi about x, y, z (two components negated)
_FLIPS = ((1.0, -1.0, -1.0), (-1.0, 1.0, -1.0), (-1.0, -1.0, 1.0))


@njit(cache=True, **NO_REFCOUNT)
def quest_row(b, r, a, q, g):
    """QUEST (eqs. 57-66) of one attitude: unit vectors ``b``, ``r`` (n, 3), weights ``a`` (n,) > 0 -> writes the
    (w, x, y, z) quaternion of R into ``q`` (4,) and the Gibbs vector of D = R^T into ``g`` (3,); returns
    lambda_max.  Preconditions (not checked): finite unit vectors, >= 2 non-collinear pairs.

    Eq. 65 in the given frame; where it is ill-conditioned, in the frames rotated by pi about x, y, z (the
    rotated problem's quaternion q' maps back to q = (0, e_k) (x) q', a signed permutation); the eigenvector of K
    (eq. 64) last."""
    g0, g1, g2, lam, ok = _gibbs_solve(b, r, a, 1.0, 1.0, 1.0)
    if ok:
        d = math.sqrt(1.0 + (g0 * g0 + g1 * g1 + g2 * g2))  # eq. 66
        q[0], q[1], q[2], q[3] = 1.0 / d, g0 / d, g1 / d, g2 / d
        g[0], g[1], g[2] = g0, g1, g2
        return lam
    done = False
    w = x = y = z = 0.0
    for k in range(3):
        f0, f1, f2 = _FLIPS[k]
        k0, k1, k2, lam_k, ok_k = _gibbs_solve(b, r, a, f0, f1, f2)
        if ok_k:
            d = math.sqrt(1.0 + (k0 * k0 + k1 * k1 + k2 * k2))
            w, x, y, z = 1.0 / d, k0 / d, k1 / d, k2 / d
            if k == 0:  # (0, e_x) (x) q' = (-x, w, -z, y)
                w, x, y, z = -x, w, -z, y
            elif k == 1:  # (0, e_y) (x) q' = (-y, z, w, -x)
                w, x, y, z = -y, z, w, -x
            else:  # (0, e_z) (x) q' = (-z, -y, x, w)
                w, x, y, z = -z, -y, x, w
            lam = lam_k
            done = True
            break
    if not done:
        w, x, y, z, lam = _eigh_quaternion(b, r, a)
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    q[0], q[1], q[2], q[3] = w, x, y, z
    w_floor = w if w > 1.0 / GIBBS_MAX else 1.0 / GIBBS_MAX
    g[0], g[1], g[2] = x / w_floor, y / w_floor, z / w_floor
    return lam


@njit(cache=True)
def _quest_rows(b, r, a, R, q, g, lam):
    """:func:`quest_row` over the rows of b (N, n, 3); r and a have N rows or one (shared by every row)."""
    for i in range(R.shape[0]):
        ri = r[i] if r.shape[0] > 1 else r[0]
        ai = a[i] if a.shape[0] > 1 else a[0]
        lam[i] = quest_row(b[i], ri, ai, q[i], g[i])
        quat_to_rot_row(q[i], R[i])


# --------------------------------------------------------------------------------------------------
# the batch function (validation in front of the kernel)
# --------------------------------------------------------------------------------------------------
def _as_batch_vectors(name: str, v: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(v, dtype=float)
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (n, 3) or (N, n, 3), got {np.shape(v)}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains non-finite values")
    norm = np.sqrt((a * a).sum(axis=-1, keepdims=True))
    if (norm <= 1e-12).any():
        raise ValueError(f"{name} contains a zero vector; every observation needs a direction")
    return a / norm


def quest(body: ArrayLike, reference: ArrayLike, weights: ArrayLike | None = None,
          min_sin: float = 1e-6) -> QuestResult:
    """Optimal attitude from vector pairs body_i = R^T reference_i (eqs. 56-66).

    body: (n, 3) or (N, n, 3); reference: (n, 3) or (N, n, 3) (broadcast against body);
    weights a_i > 0: (n,) or (N, n), default equal.  n >= 2 non-collinear directions are needed:
    raises ValueError if every pair of body (or reference) directions has |sin| < ``min_sin``.
    """
    b = _as_batch_vectors("body", body)
    r = _as_batch_vectors("reference", reference)
    try:
        b, r = np.broadcast_arrays(b, r)
    except ValueError as exc:
        raise ValueError(f"body {np.shape(body)} and reference {np.shape(reference)} do not broadcast") from exc
    n_obs = b.shape[1]
    if n_obs < 2:
        raise ValueError(f"QUEST needs at least 2 vector pairs, got {n_obs}")
    try:
        a = np.broadcast_to(np.ones(1) if weights is None else np.asarray(weights, dtype=float), b.shape[:2])
    except ValueError as exc:
        got = np.shape(np.asarray(weights))
        raise ValueError(f"weights must have shape ({n_obs},) or (N, {n_obs}), got {got}") from exc
    if not (np.isfinite(a) & (a > 0)).all():
        raise ValueError(f"weights must be finite and > 0, got {shown(weights)}")
    for name, v in (("body", b), ("reference", r)):
        c = cross(v[:, :, None, :], v[:, None, :, :])  # largest |v_i x v_j|^2 over the pairs
        s2 = (c * c).sum(axis=-1)
        if (s2.reshape(s2.shape[0], -1).max(axis=1) < min_sin * min_sin).any():
            raise ValueError(f"{name} directions are collinear (|sin| < {min_sin}); attitude is not observable")
    return quest_unit(b, r, a)


def quest_unit(b: NDArray[np.float64], r: NDArray[np.float64], a: NDArray[np.float64]) -> QuestResult:
    """QUEST core (eqs. 57-66, :func:`quest_row` over the rows) on validated input: unit vectors b (N, n, 3),
    r (N or 1, n, 3), weights a (N or 1, n) > 0 (normalized in the kernel, eq. 63).  :func:`quest` validates and
    calls this; callers that already guarantee the preconditions may call it directly."""
    n = b.shape[0]
    R, q, g, lam = np.empty((n, 3, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty(n)
    _quest_rows(np.ascontiguousarray(b, dtype=float), np.ascontiguousarray(r, dtype=float),
                np.ascontiguousarray(a, dtype=float), R, q, g, lam)
    return QuestResult(R=R, quaternion=q, gibbs=g, lambda_max=lam, loss=1.0 - lam)


def wahba_loss(R: ArrayLike, body: ArrayLike, reference: ArrayLike, weights: ArrayLike | None = None) -> NDArray:
    """Eq. 56 with unit vectors and normalized weights: 1/2 sum a_i |b_i - R^T r_i|^2 per batch row."""
    b = _as_batch_vectors("body", body)
    r = _as_batch_vectors("reference", reference)
    b, r = np.broadcast_arrays(b, r)
    a = np.ones(b.shape[:2]) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), b.shape[:2])
    a = a / a.sum(axis=1, keepdims=True)
    pred = np.einsum("nji,nkj->nki", np.asarray(R, dtype=float).reshape(-1, 3, 3), r)
    return 0.5 * np.sum(a * np.sum((b - pred) ** 2, axis=-1), axis=-1)
