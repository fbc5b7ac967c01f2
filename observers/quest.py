"""QUEST (Shuster and Oh, 1981): least-squares attitude from >= 2 weighted vector pairs, batch-first.

Source: ``pdt_sta_attitude_silva2023.txt`` Sec. 4.2, eqs. 56-66 (Wahba's loss (56), the K matrix
(57)-(63), its largest eigenvalue (64), the optimal Gibbs vector (65) and quaternion (66)), after
Shuster and Oh, J. Guidance and Control 4(1), 1981.

Frames.  The paper's attitude matrix D^{b/g} maps reference (S^g) components to body (S^b)
components, mu_b = D mu_g.  With world NED / body FRD this is D = R^T for the project's R (body ->
world).  The returned Gibbs vector ``gibbs`` is the paper's g of D (so R = D(g)^T, see
:func:`fawtgym.observers.gyroless_attitude.gibbs_to_rot`), and ``quaternion`` is the project's
(w, x, y, z) quaternion of R: Shuster's scalar-last q = [g; 1]/sqrt(1 + g^T g) of D reordered to
(q4, q1, q2, q3) (the same numbers: D(q) = R(q)^T).

Algorithm.  Vectors are normalized to unit length (QUEST's assumption; then lambda_max <= 1 with
normalized weights a_i / m, eq. 63).  lambda_max is found by Newton-Raphson on Shuster's
characteristic polynomial of K, started from 1; g from eq. 65 by a 3x3 solve.  Where that solve is
ill-conditioned (|g| > 10: rotation angle above 168.6 deg, g -> infinity at pi) the eigenvector of K (eq. 64) from
``numpy.linalg.eigh`` is used instead, so every attitude is returned finitely.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

_NEWTON_ITERS = 8


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


GIBBS_MAX = 1e8
#: beyond |g| = 10 (rotation angle > 168.6 deg) eq. 65 loses digits; use the eigenvector (eq. 64)
_GIBBS_SWITCH = 10.0


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """a x b over the last axis (cheaper than np.cross for small arrays)."""
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(a.shape)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _as_batch_vectors(name: str, v: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(v, dtype=float)
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (n, 3) or (N, n, 3), got {np.shape(v)}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values")
    norm = np.linalg.norm(a, axis=-1, keepdims=True)
    if np.any(norm <= 1e-12):
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
    a = np.ones(b.shape[:2]) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), b.shape[:2])
    if not (np.all(np.isfinite(a)) and np.all(a > 0)):
        raise ValueError(f"weights must be finite and > 0, got {weights!r}")
    for name, v in (("body", b), ("reference", r)):
        cross = np.linalg.norm(_cross(v[:, :, None, :], v[:, None, :, :]), axis=-1)
        if np.any(cross.max(axis=(1, 2)) < min_sin):
            raise ValueError(f"{name} directions are collinear (|sin| < {min_sin}); attitude is not observable")
    a = a / a.sum(axis=1, keepdims=True)  # eq. 63 normalization

    B = np.einsum("ni,nij,nik->njk", a, b, r)  # eq. 61
    S = B + np.swapaxes(B, -1, -2)  # eq. 59
    rho = np.trace(B, axis1=-2, axis2=-1)  # eq. 60
    z = np.einsum("ni,nij->nj", a, _cross(b, r))  # eq. 62

    # Shuster's characteristic equation of K (58):
    # (l^2 - a1)(l^2 - b1) - c1 l + c1 rho - d1 = 0, with
    # a1 = rho^2 - tr adj S, b1 = rho^2 + z.z, c1 = det S + z.S z, d1 = z.S^2 z.
    detS = np.linalg.det(S)
    adj_tr = 0.5 * (np.trace(S, axis1=-2, axis2=-1) ** 2 - np.trace(S @ S, axis1=-2, axis2=-1))
    Sz = np.einsum("nij,nj->ni", S, z)
    a1 = rho**2 - adj_tr
    b1 = rho**2 + np.sum(z * z, axis=-1)
    c1 = detS + np.sum(z * Sz, axis=-1)
    d1 = np.sum(Sz * Sz, axis=-1)
    lam = np.ones_like(rho)
    for _ in range(_NEWTON_ITERS):
        f = (lam**2 - a1) * (lam**2 - b1) - c1 * lam + c1 * rho - d1
        df = 2 * lam * (2 * lam**2 - a1 - b1) - c1
        step = np.where(np.abs(df) > 1e-14, f / np.where(df == 0, 1.0, df), 0.0)
        lam = lam - step
        if np.max(np.abs(step)) < 1e-15:  # quadratic convergence: usually 2-4 iterations
            break

    # eq. 65: g = [(lambda + rho) I - S]^{-1} z
    M = (lam + rho)[:, None, None] * np.eye(3) - S
    detM = np.linalg.det(M)
    good = np.abs(detM) > 1e-9
    g = np.zeros_like(z)
    if np.any(good):
        g[good] = np.linalg.solve(M[good], z[good][..., None])[..., 0]
    q = np.empty((b.shape[0], 4))  # (w, x, y, z) = (q4, q_vec) (see module docstring)
    denom = np.sqrt(1.0 + np.sum(g * g, axis=-1))
    q[:, 0] = 1.0 / denom
    q[:, 1:] = g / denom[:, None]
    bad = ~good | ~np.all(np.isfinite(g), axis=-1) | (np.linalg.norm(g, axis=-1) > _GIBBS_SWITCH)
    if np.any(bad):
        K = np.zeros((int(bad.sum()), 4, 4))
        K[:, :3, :3] = S[bad] - rho[bad][:, None, None] * np.eye(3)
        K[:, :3, 3] = z[bad]
        K[:, 3, :3] = z[bad]
        K[:, 3, 3] = rho[bad]
        w, v = np.linalg.eigh(K)  # eq. 64
        qs = v[:, :, -1]  # scalar-last, eigenvalue ascending
        qs = qs * np.where(qs[:, 3:4] < 0, -1.0, 1.0)
        q[bad, 0] = qs[:, 3]
        q[bad, 1:] = qs[:, :3]
        lam[bad] = w[:, -1]
        q4 = np.maximum(qs[:, 3], 1.0 / GIBBS_MAX)
        g[bad] = qs[:, :3] / q4[:, None]
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    R = quat_wxyz_to_rot(q)
    return QuestResult(R=R, quaternion=q, gibbs=g, lambda_max=lam, loss=1.0 - lam)


def quat_wxyz_to_rot(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix (body -> world) of a unit quaternion (..., 4) in (w, x, y, z) order (Hamilton)."""
    q = np.asarray(q, dtype=float)
    w, x, y, zz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + zz * zz), 2 * (x * y - w * zz), 2 * (x * zz + w * y)], axis=-1),
        np.stack([2 * (x * y + w * zz), 1 - 2 * (x * x + zz * zz), 2 * (y * zz - w * x)], axis=-1),
        np.stack([2 * (x * zz - w * y), 2 * (y * zz + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def wahba_loss(R: ArrayLike, body: ArrayLike, reference: ArrayLike, weights: ArrayLike | None = None) -> NDArray:
    """Eq. 56 with unit vectors and normalized weights: 1/2 sum a_i |b_i - R^T r_i|^2 per batch row."""
    b = _as_batch_vectors("body", body)
    r = _as_batch_vectors("reference", reference)
    b, r = np.broadcast_arrays(b, r)
    a = np.ones(b.shape[:2]) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), b.shape[:2])
    a = a / a.sum(axis=1, keepdims=True)
    pred = np.einsum("nji,nkj->nki", np.asarray(R, dtype=float).reshape(-1, 3, 3), r)
    return 0.5 * np.sum(a * np.sum((b - pred) ** 2, axis=-1), axis=-1)
