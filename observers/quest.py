"""QUEST (Shuster and Oh, 1981): least-squares attitude from >= 2 weighted vector pairs, batch-first.

Source: Sec. 4.2, eqs. 56-66 (Wahba's loss (56), the K matrix
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
ill-conditioned (|g| > 10: rotation angle above 168.6 deg, g -> infinity at pi) the problem is solved again with
the reference vectors rotated by pi about x, y or z (Shuster and Oh's method of sequential rotations; one of the
three rotated attitudes is within 120 deg of identity) and the quaternion rotated back exactly; the eigenvector of
K (eq. 64) from ``numpy.linalg.eigh`` remains as the last resort, so every attitude is returned finitely.  For
N = 1 the same arithmetic runs on plain Python floats (:func:`quest_floats`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

_NEWTON_ITERS = 8
_EYE = np.eye(3)


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


_I1 = np.array([1, 2, 0])
_I2 = np.array([2, 0, 1])


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """a x b over the last axis, broadcasting (cheaper than np.cross for small arrays)."""
    if a.size <= 48 and b.size <= 48:  # few elements: 4 gathers beat 9 strided slices
        return a.take(_I1, -1) * b.take(_I2, -1) - a.take(_I2, -1) * b.take(_I1, -1)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
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
    a = np.ones(b.shape[:2]) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), b.shape[:2])
    if not (np.isfinite(a) & (a > 0)).all():
        raise ValueError(f"weights must be finite and > 0, got {weights!r}")
    for name, v in (("body", b), ("reference", r)):
        # largest |v_i x v_j|^2 over the pairs (n = 2: the one pair)
        c = _cross(v[:, 0], v[:, 1]) if n_obs == 2 else _cross(v[:, :, None, :], v[:, None, :, :])
        s2 = (c * c).sum(axis=-1)
        if (s2.reshape(s2.shape[0], -1).max(axis=1) < min_sin * min_sin).any():
            raise ValueError(f"{name} directions are collinear (|sin| < {min_sin}); attitude is not observable")
    return quest_unit(b, r, a)


def _sum3(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """p[..., 0] + p[..., 1] + p[..., 2] (the order of a length-3 sum; faster than .sum(-1) for large N)."""
    return p[..., 0] + p[..., 1] + p[..., 2]


def _cofactors(M: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cofactor rows (the rows of adj M^T; adj M for symmetric M) and det M of a batch (N, 3, 3)."""
    C = _cross(M[:, (1, 2, 0)], M[:, (2, 0, 1)])
    return C, _sum3(M[:, 0] * C[:, 0])


def _newton_lambda(lam, a1, b1, c1, rho, d1):  # type: ignore[no-untyped-def]
    """lambda_max by Newton-Raphson on the characteristic equation; arrays (N,), or plain floats (N = 1:
    the same arithmetic without the per-operation cost of 1-element arrays)."""
    scalar = isinstance(lam, float)
    for _ in range(_NEWTON_ITERS):
        l2 = lam * lam
        f = (l2 - a1) * (l2 - b1) - c1 * lam + c1 * rho - d1
        df = 2 * lam * (2 * l2 - a1 - b1) - c1
        if scalar:
            step = f / df if abs(df) > 1e-14 else 0.0
            lam = lam - step
            if abs(step) < 1e-15:
                break
        else:
            step = np.where(np.abs(df) > 1e-14, f / np.where(df == 0, 1.0, df), 0.0)
            lam = lam - step
            if np.abs(step).max() < 1e-15:  # quadratic convergence: usually 2-4 iterations
                break
    return lam


def quest_unit(b: NDArray[np.float64], r: NDArray[np.float64], a: NDArray[np.float64]) -> QuestResult:
    """QUEST core (eqs. 57-66) on validated input: unit vectors b, r (N, n, 3), weights a (N, n) > 0
    (normalized here, eq. 63).  :func:`quest` validates and calls this; callers that already
    guarantee the preconditions (finite unit vectors, >= 2 non-collinear pairs) may call it directly.
    N = 1 runs on plain floats (:func:`_quest_unit_single`) unless the eigenvector branch is needed."""
    if b.shape[0] == 1 and r.shape[0] == 1 and a.shape[0] == 1:
        res = _quest_unit_single(b[0].tolist(), r[0].tolist(), a[0].tolist())
        if res is not None:
            return res
    return _quest_unit_batch(b, r, a)


def _gibbs_batch(b: NDArray[np.float64], r: NDArray[np.float64], a: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_],
                            dict[str, NDArray[np.float64]]]:
    """Eqs. 57-65 on arrays: (g (N, 3), lambda_max (N,), det M (N,), ok (N,), {"S", "z", "rho"}); ok is False where
    eq. 65 is ill-conditioned (|det M| <= 1e-9 or |g| > 10; g is then meaningless)."""
    a = a / a.sum(axis=1, keepdims=True)  # eq. 63 normalization
    ab = a[:, :, None] * b
    # eq. 61: B = sum_i a_i b_i r_i^T and eq. 62: z = sum_i a_i b_i x r_i, summed in order over the n pairs
    # (no BLAS: no FMA; a loop over the observations, not over N, cheaper than an (N, n, 3, 3) reduction)
    B = ab[:, 0, :, None] * r[:, 0, None, :]
    z = _cross(ab[:, 0], r[:, 0])
    for i in range(1, ab.shape[1]):
        B = B + ab[:, i, :, None] * r[:, i, None, :]
        z = z + _cross(ab[:, i], r[:, i])
    S = B + np.swapaxes(B, -1, -2)  # eq. 59
    rho = B[:, 0, 0] + B[:, 1, 1] + B[:, 2, 2]  # eq. 60

    # Shuster's characteristic equation of K (58):
    # (l^2 - a1)(l^2 - b1) - c1 l + c1 rho - d1 = 0, with
    # a1 = rho^2 - tr adj S, b1 = rho^2 + z.z, c1 = det S + z.S z, d1 = z.S^2 z.
    CS, detS = _cofactors(S)
    Sz = _sum3(S * z[:, None, :])
    rho2 = rho * rho
    a1 = rho2 - (CS[:, 0, 0] + CS[:, 1, 1] + CS[:, 2, 2])
    b1 = rho2 + _sum3(z * z)
    c1 = detS + _sum3(z * Sz)
    d1 = _sum3(Sz * Sz)
    if rho.shape[0] == 1:
        lam = np.array([_newton_lambda(1.0, float(a1[0]), float(b1[0]), float(c1[0]), float(rho[0]),
                                       float(d1[0]))])
    else:
        lam = _newton_lambda(np.ones_like(rho), a1, b1, c1, rho, d1)

    # eq. 65: g = [(lambda + rho) I - S]^{-1} z = adj(M) z / det M (M symmetric)
    M = (lam + rho)[:, None, None] * _EYE - S
    CM, detM = _cofactors(M)
    good = np.abs(detM) > 1e-9
    g = _sum3(CM * z[:, None, :]) / np.where(good, detM, 1.0)[:, None]
    ok = good & (_sum3(g * g) <= _GIBBS_SWITCH * _GIBBS_SWITCH)  # also catches non-finite g
    return g, lam, detM, ok, {"S": S, "z": z, "rho": rho}


#: Shuster and Oh's method of sequential rotations: the reference vectors rotated by pi about x, y, z (two
#: components negated, exact), and the map of the rotated problem's quaternion q' = (w, x, y, z) back,
#: q = (0, e_k) (x) q' (Hamilton product; R = T_k R'), a permutation with signs (exact)
_FLIPS = ((1.0, -1.0, -1.0), (-1.0, 1.0, -1.0), (-1.0, -1.0, 1.0))
_UNFLIP = (((1, -1.0), (0, 1.0), (3, -1.0), (2, 1.0)),  # (-x, w, -z, y)
           ((2, -1.0), (3, 1.0), (0, 1.0), (1, -1.0)),  # (-y, z, w, -x)
           ((3, -1.0), (2, -1.0), (1, 1.0), (0, 1.0)))  # (-z, -y, x, w)


def _quest_unit_batch(b: NDArray[np.float64], r: NDArray[np.float64], a: NDArray[np.float64]) -> QuestResult:
    """:func:`quest_unit` on numpy arrays for any N (the reference implementation).

    Rows where eq. 65 is ill-conditioned (|g| > 10, rotation angle above 168.6 deg) are solved again with the
    references rotated by pi about x, then y, then z (Shuster and Oh's method of sequential rotations): for one
    of them the rotated attitude is within 120 deg of identity (|g'| <= sqrt 3).  The eigenvector of K
    (eq. 64, ``numpy.linalg.eigh``) is the last resort (a degenerate lambda_max)."""
    g, lam, _, ok, parts = _gibbs_batch(b, r, a)
    gg = _sum3(g * g)
    q = np.empty((g.shape[0], 4))  # (w, x, y, z) = (q4, q_vec) (see module docstring)
    denom = np.sqrt(1.0 + gg)
    q[:, 0] = 1.0 / denom
    q[:, 1:] = g / denom[:, None]
    if not ok.all():
        shape = np.broadcast_shapes(b.shape, r.shape)
        bb, rr = np.broadcast_to(b, shape), np.broadcast_to(r, shape)
        aa = np.broadcast_to(a, shape[:2])
        todo = np.nonzero(~ok)[0]
        for flip, unflip in zip(_FLIPS, _UNFLIP, strict=True):
            gk, lk, _, okk, _ = _gibbs_batch(bb[todo], rr[todo] * np.array(flip), aa[todo])
            rows = todo[okk]
            gk = gk[okk]
            dk = np.sqrt(1.0 + _sum3(gk * gk))
            qk = np.empty((rows.size, 4))
            qk[:, 0] = 1.0 / dk
            qk[:, 1:] = gk / dk[:, None]
            qr = np.stack([sign * qk[:, src] for src, sign in unflip], axis=-1)
            q[rows] = qr * np.where(qr[:, 0:1] < 0, -1.0, 1.0)
            lam[rows] = lk[okk]
            todo = todo[~okk]
            if todo.size == 0:
                break
        if todo.size:
            S, z, rho = parts["S"][todo], parts["z"][todo], parts["rho"][todo]
            K = np.zeros((todo.size, 4, 4))
            K[:, :3, :3] = S - rho[:, None, None] * np.eye(3)
            K[:, :3, 3] = z
            K[:, 3, :3] = z
            K[:, 3, 3] = rho
            w, v = np.linalg.eigh(K)  # eq. 64
            qs = v[:, :, -1]  # scalar-last, eigenvalue ascending
            qs = qs * np.where(qs[:, 3:4] < 0, -1.0, 1.0)
            q[todo, 0] = qs[:, 3]
            q[todo, 1:] = qs[:, :3]
            lam[todo] = w[:, -1]
        bad = ~ok
        g[bad] = q[bad, 1:] / np.maximum(q[bad, 0], 1.0 / GIBBS_MAX)[:, None]
    q /= np.sqrt((q * q).sum(axis=-1, keepdims=True))
    R = quat_wxyz_to_rot(q)
    return QuestResult(R=R, quaternion=q, gibbs=g, lambda_max=lam, loss=1.0 - lam)


# R (row-major, 9) = e + (q q^T flattened, 16) @ _QQ_TO_R: each entry a signed sum of two products, times 2
_QQ_TO_R = np.zeros((16, 9))
for _k, _terms in enumerate([((2, 2, -2), (3, 3, -2)), ((1, 2, 2), (0, 3, -2)), ((1, 3, 2), (0, 2, 2)),
                             ((1, 2, 2), (0, 3, 2)), ((1, 1, -2), (3, 3, -2)), ((2, 3, 2), (0, 1, -2)),
                             ((1, 3, 2), (0, 2, -2)), ((2, 3, 2), (0, 1, 2)), ((1, 1, -2), (2, 2, -2))]):
    for _i, _j, _c in _terms:
        _QQ_TO_R[4 * _i + _j, _k] = _c
_EYE_FLAT = np.eye(3).reshape(9)


def _quest_unit_single(b: list[list[float]], r: list[list[float]], a: list[float]) -> QuestResult | None:
    """:func:`quest_unit` for N = 1 on plain floats (see :func:`quest_floats`); None where the eigenvector
    branch (eq. 64) is needed."""
    res = quest_floats(b, r, a)
    if res is None:
        return None
    R, q, g, lam = res
    return QuestResult(R=np.array(R).reshape(1, 3, 3), quaternion=np.array([q]), gibbs=np.array([g]),
                       lambda_max=np.array([lam]), loss=np.array([1.0 - lam]))


def quest_floats(b: list[list[float]], r: list[list[float]], a: list[float]
                 ) -> tuple[list[float], list[float], list[float], float] | None:
    """QUEST (eqs. 57-66) for one attitude on plain Python floats: unit vectors ``b``, ``r`` (n lists of 3),
    weights ``a`` (n) > 0.  Returns (R row-major (9), quaternion (w, x, y, z), Gibbs vector g, lambda_max), the
    same formulas in the same order as :func:`_quest_unit_batch` (1-element numpy arrays cost ~1 us per
    operation), including its sequential rotations where |g| > 10; None where those fail too and the batched
    path takes the eigenvector of K (eq. 64).  Preconditions as :func:`quest_unit` (not checked)."""
    res = _gibbs_floats(b, r, a)
    if res is not None:
        g0, g1, g2, lam = res
        gg = g0 * g0 + g1 * g1 + g2 * g2
        denom = math.sqrt(1.0 + gg)
        w, x, y, zz = 1.0 / denom, g0 / denom, g1 / denom, g2 / denom
    else:  # eq. 65 ill-conditioned: the method of sequential rotations, as _quest_unit_batch
        for k in range(3):
            f0, f1, f2 = _FLIPS[k]
            res = _gibbs_floats(b, [[f0 * ri[0], f1 * ri[1], f2 * ri[2]] for ri in r], a)
            if res is not None:
                break
        else:
            return None
        k0, k1, k2, lam = res
        dk = math.sqrt(1.0 + (k0 * k0 + k1 * k1 + k2 * k2))
        qk = (1.0 / dk, k0 / dk, k1 / dk, k2 / dk)
        w, x, y, zz = (sign * qk[src] for src, sign in _UNFLIP[k])
        if w < 0:
            w, x, y, zz = -w, -x, -y, -zz
        q4 = w if w > 1.0 / GIBBS_MAX else 1.0 / GIBBS_MAX
        g0, g1, g2 = x / q4, y / q4, zz / q4
    # eq. 66 (w, x, y, z), renormalized as the batched path, and R(q)
    qn = math.sqrt(w * w + x * x + y * y + zz * zz)
    w, x, y, zz = w / qn, x / qn, y / qn, zz / qn
    R = [1 - 2 * (y * y + zz * zz), 2 * (x * y - w * zz), 2 * (x * zz + w * y),
         2 * (x * y + w * zz), 1 - 2 * (x * x + zz * zz), 2 * (y * zz - w * x),
         2 * (x * zz - w * y), 2 * (y * zz + w * x), 1 - 2 * (x * x + y * y)]
    return R, [w, x, y, zz], [g0, g1, g2], lam


def _gibbs_floats(b: list[list[float]], r: list[list[float]], a: list[float]
                  ) -> tuple[float, float, float, float] | None:
    """Eqs. 57-65 for one attitude on plain floats, as :func:`_gibbs_batch`: (g, lambda_max), or None where eq. 65
    is ill-conditioned (|det M| <= 1e-9 or |g| > 10)."""
    sa = sum(a)
    if len(a) == 2:  # the accelerometer + magnetometer case, unrolled
        (p0, p1, p2), (s0, s1, s2) = b
        (r00, r01, r02), (r10, r11, r12) = r
        w0, w1 = a[0] / sa, a[1] / sa  # eq. 63
        p0, p1, p2, s0, s1, s2 = w0 * p0, w0 * p1, w0 * p2, w1 * s0, w1 * s1, w1 * s2  # a_i b_i
        # eq. 61: B = sum_i a_i b_i r_i^T
        B00, B01, B02 = p0 * r00 + s0 * r10, p0 * r01 + s0 * r11, p0 * r02 + s0 * r12
        B10, B11, B12 = p1 * r00 + s1 * r10, p1 * r01 + s1 * r11, p1 * r02 + s1 * r12
        B20, B21, B22 = p2 * r00 + s2 * r10, p2 * r01 + s2 * r11, p2 * r02 + s2 * r12
        # eq. 62: z = sum_i a_i b_i x r_i
        z0 = (p1 * r02 - p2 * r01) + (s1 * r12 - s2 * r11)
        z1 = (p2 * r00 - p0 * r02) + (s2 * r10 - s0 * r12)
        z2 = (p0 * r01 - p1 * r00) + (s0 * r11 - s1 * r10)
    else:
        ab = [[ai / sa * x for x in bi] for ai, bi in zip(a, b, strict=True)]  # a_i b_i, eq. 63 weights
        (B00, B01, B02), (B10, B11, B12), (B20, B21, B22) = (
            [sum(abi[j] * ri[k] for abi, ri in zip(ab, r, strict=True)) for k in range(3)] for j in range(3))
        z0, z1, z2 = (sum(c) for c in zip(*(_cross3(abi, ri) for abi, ri in zip(ab, r, strict=True)), strict=True))
    # eq. 59 S = B + B^T, eq. 60 rho = tr B
    S00, S01, S02, S11, S12, S22 = B00 + B00, B01 + B10, B02 + B20, B11 + B11, B12 + B21, B22 + B22
    S10, S20, S21 = S01, S02, S12  # B10 + B01 == B01 + B10 exactly
    rho = B00 + B11 + B22
    # cofactors of S (rows S1 x S2, S2 x S0, S0 x S1) and det S, as _cofactors
    C00, C01, C02 = S11 * S22 - S12 * S21, S12 * S20 - S10 * S22, S10 * S21 - S11 * S20
    C11 = S22 * S00 - S20 * S02
    C22 = S00 * S11 - S01 * S10
    detS = S00 * C00 + S01 * C01 + S02 * C02
    Sz0 = S00 * z0 + S01 * z1 + S02 * z2
    Sz1 = S10 * z0 + S11 * z1 + S12 * z2
    Sz2 = S20 * z0 + S21 * z1 + S22 * z2
    # Shuster's characteristic equation of K (58), see _quest_unit_batch
    rho2 = rho * rho
    a1 = rho2 - (C00 + C11 + C22)
    b1 = rho2 + (z0 * z0 + z1 * z1 + z2 * z2)
    c1 = detS + (z0 * Sz0 + z1 * Sz1 + z2 * Sz2)
    d1 = Sz0 * Sz0 + Sz1 * Sz1 + Sz2 * Sz2
    lam = 1.0  # _newton_lambda's scalar branch, inlined
    for _ in range(_NEWTON_ITERS):
        l2 = lam * lam
        f = (l2 - a1) * (l2 - b1) - c1 * lam + c1 * rho - d1
        df = 2 * lam * (2 * l2 - a1 - b1) - c1
        step = f / df if abs(df) > 1e-14 else 0.0
        lam = lam - step
        if abs(step) < 1e-15:
            break
    # eq. 65: g = adj(M) z / det M, M = (lambda + rho) I - S
    lr = lam + rho
    M00, M11, M22 = lr - S00, lr - S11, lr - S22
    M01, M02, M10, M12, M20, M21 = 0.0 - S01, 0.0 - S02, 0.0 - S10, 0.0 - S12, 0.0 - S20, 0.0 - S21
    D00, D01, D02 = M11 * M22 - M12 * M21, M12 * M20 - M10 * M22, M10 * M21 - M11 * M20
    D10, D11, D12 = M21 * M02 - M22 * M01, M22 * M00 - M20 * M02, M20 * M01 - M21 * M00
    D20, D21, D22 = M01 * M12 - M02 * M11, M02 * M10 - M00 * M12, M00 * M11 - M01 * M10
    detM = M00 * D00 + M01 * D01 + M02 * D02
    if not abs(detM) > 1e-9:
        return None
    g0 = (D00 * z0 + D01 * z1 + D02 * z2) / detM
    g1 = (D10 * z0 + D11 * z1 + D12 * z2) / detM
    g2 = (D20 * z0 + D21 * z1 + D22 * z2) / detM
    if not g0 * g0 + g1 * g1 + g2 * g2 <= _GIBBS_SWITCH * _GIBBS_SWITCH:
        return None
    return g0, g1, g2, lam


def _cross3(a: list[float], b: list[float]) -> list[float]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def quat_wxyz_to_rot(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix (body -> world) of a unit quaternion (..., 4) in (w, x, y, z) order (Hamilton):
    R = [[1 - 2(y^2 + z^2), 2(xy - wz), 2(xz + wy)], [2(xy + wz), 1 - 2(x^2 + z^2), 2(yz - wx)],
    [2(xz - wy), 2(yz + wx), 1 - 2(x^2 + y^2)]], evaluated as one product with the outer product q q^T."""
    q = np.asarray(q, dtype=float)
    qq = (q[..., :, None] * q[..., None, :]).reshape(q.shape[:-1] + (16,))
    return (qq @ _QQ_TO_R + _EYE_FLAT).reshape(q.shape[:-1] + (3, 3))


def wahba_loss(R: ArrayLike, body: ArrayLike, reference: ArrayLike, weights: ArrayLike | None = None) -> NDArray:
    """Eq. 56 with unit vectors and normalized weights: 1/2 sum a_i |b_i - R^T r_i|^2 per batch row."""
    b = _as_batch_vectors("body", body)
    r = _as_batch_vectors("reference", reference)
    b, r = np.broadcast_arrays(b, r)
    a = np.ones(b.shape[:2]) if weights is None else np.broadcast_to(np.asarray(weights, dtype=float), b.shape[:2])
    a = a / a.sum(axis=1, keepdims=True)
    pred = np.einsum("nji,nkj->nki", np.asarray(R, dtype=float).reshape(-1, 3, 3), r)
    return 0.5 * np.sum(a * np.sum((b - pred) ** 2, axis=-1), axis=-1)
