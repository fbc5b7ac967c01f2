"""Optimal quadratic-boundedness (QB) observer design by semidefinite programming.

Seed: (Cayero, Rotondo, Morcego, Puig 2019), Sec. 2.

For a linear system (eq. 1)::

    x' = A x + B u + W1 eta1,   y = C x + D u + W2 eta2,   z = E1 x,   [eta1; eta2]^T Q [eta1; eta2] <= 1  (2)

and the observer (eq. 3) ``xhat' = (A + L C) xhat + (B + L D) u - L y``, the error ``e = x - xhat``
obeys eq. 4.  For a fixed decay parameter ``alpha > 0`` the design is the convex problem (eq. 31)::

    max log det X   over  X > 0, P > 0, Y
    s.t.  [[Psi + alpha P, P W1, Y W2], [W1^T P, -alpha Q], [W2^T Y^T, ...]] <= 0     (7), Psi of (8)
          P - E1^T X E1 >= 0                                                          (30)

with ``L = P^{-1} Y`` (eq. 9).  The error converges exponentially (rate ``alpha``, eq. 18) into the
ellipsoid ``e^T P e <= 1``, whose projection onto ``<E1>`` is ``P_z`` (eq. 19, Appendix) with volume
``B_q / sqrt(det P_z)`` (eq. 20); at the optimum ``X = P_z``.  The trade-off between ``alpha`` and
the volume is scalarized by the normalized objective ``J_mu`` (eqs. 21-23) and minimized by a line
search over ``alpha`` (eq. 25).

cvxpy (optional extra ``fawtgym[design]``) is imported only inside :func:`solve_qb_lmi`, so the
runtime observer (:mod:`fawtgym.observers.qb`) never needs it.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import null_space

from fawtgym.core.checks import shown

__all__ = [
    "AlphaSweep", "ParetoAnchors", "QBInfeasibleError", "QBProblem", "QBSolution",
    "anchors_from_sweep", "ellipsoid_log_volume", "ellipsoid_volume", "j_mu", "lmi_residuals",
    "optimal_alpha", "orthogonal_complement", "projection_matrix", "solve_qb_lmi", "sweep_alpha",
    "unit_ball_volume",
]

_DESIGN_HINT = "pip install 'fawtgym[design]'"


class QBInfeasibleError(ValueError):
    """The LMI problem (7) + (30) of Cayero et al. (2019) has no solution (or the solver failed on it)."""


def _mat(name: str, value: ArrayLike, rows: int | None = None, cols: int | None = None) -> NDArray[np.float64]:
    a = np.atleast_2d(np.asarray(value, dtype=float))
    if a.ndim != 2:
        raise ValueError(f"{name} must be a 2-D matrix, got shape {a.shape}")
    if rows is not None and a.shape[0] != rows:
        raise ValueError(f"{name} must have {rows} rows, got shape {a.shape}")
    if cols is not None and a.shape[1] != cols:
        raise ValueError(f"{name} must have {cols} columns, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite entries")
    return a


@dataclasses.dataclass(frozen=True, eq=False)
class QBProblem:
    """The data (A, B, C, D, W1, W2, Q, E1) of Cayero et al. (2019) eqs. 1-2; validated on construction.

    ``Q`` bounds ``eta_bar = (eta1, eta2)`` (eq. 2) and must be symmetric positive definite of size
    ``l1 + l2``.  ``E1`` (q x n) must have orthonormal rows (a part of a permutation matrix in the
    paper; orthonormal rows are what eqs. 19 and 30 need).
    """

    A: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    D: NDArray[np.float64]
    W1: NDArray[np.float64]
    W2: NDArray[np.float64]
    Q: NDArray[np.float64]
    E1: NDArray[np.float64]

    def __post_init__(self) -> None:
        a = _mat("A", self.A)
        n = a.shape[0]
        if a.shape != (n, n):
            raise ValueError(f"A must be square, got shape {a.shape}")
        b = _mat("B", self.B, rows=n)
        c = _mat("C", self.C, cols=n)
        p = c.shape[0]
        d = _mat("D", self.D, rows=p, cols=b.shape[1])
        w1 = _mat("W1", self.W1, rows=n)
        w2 = _mat("W2", self.W2, rows=p)
        q = _mat("Q", self.Q)
        nl = w1.shape[1] + w2.shape[1]
        if q.shape != (nl, nl):
            raise ValueError(f"Q must be ({nl}, {nl}) = (l1 + l2) square, got shape {q.shape}")
        if not np.allclose(q, q.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(q).max())):
            raise ValueError("Q must be symmetric")
        qmin = np.linalg.eigvalsh(q).min()
        if qmin <= 0:
            raise ValueError(f"Q must be positive definite, smallest eigenvalue {qmin:.3e}")
        e1 = _mat("E1", self.E1, cols=n)
        if e1.shape[0] >= n:
            raise ValueError(f"E1 must have fewer rows than n = {n} (a proper part of the state), got {e1.shape}")
        if not np.allclose(e1 @ e1.T, np.eye(e1.shape[0]), atol=1e-10):
            raise ValueError("E1 must have orthonormal rows (Cayero et al. (2019) Appendix, eq. A2-A4)")
        for name, val in (("A", a), ("B", b), ("C", c), ("D", d), ("W1", w1), ("W2", w2), ("Q", (q + q.T) / 2),
                          ("E1", e1)):
            object.__setattr__(self, name, val)

    @property
    def n(self) -> int:
        return int(self.A.shape[0])

    @property
    def q(self) -> int:
        return int(self.E1.shape[0])

    def as_arrays(self) -> dict[str, NDArray[np.float64]]:
        return {k: getattr(self, k) for k in ("A", "B", "C", "D", "W1", "W2", "Q", "E1")}


@dataclasses.dataclass(frozen=True, eq=False)
class QBSolution:
    """Solution of eq. 31 at one ``alpha``: P, Y, X, the gain L = P^{-1} Y (eq. 9) and P_z (eq. 19)."""

    alpha: float
    P: NDArray[np.float64]
    Y: NDArray[np.float64]
    X: NDArray[np.float64]
    L: NDArray[np.float64]
    Pz: NDArray[np.float64]
    log_volume: float  #: log Vol(eps_{P_z}) (eq. 20), from P_z
    status: str
    solver: str
    solve_seconds: float

    @property
    def volume(self) -> float:
        return float(math.exp(self.log_volume))


# ---------------------------------------------------------------- geometry (eqs. 19, 20) ----
def orthogonal_complement(E1: ArrayLike) -> NDArray[np.float64]:
    """E2 with orthonormal rows spanning the orthogonal complement of the rows of E1 (E1 E2^T = 0)."""
    e1 = _mat("E1", E1)
    return null_space(e1).T


def projection_matrix(P: ArrayLike, E1: ArrayLike) -> NDArray[np.float64]:
    """P_z of Cayero et al. (2019) eq. 19: the projection of ``e^T P e <= 1`` onto the row space of E1.

    ``P_z = E1 P E1^T - E1 P E2^T (E2 P E2^T)^{-1} E2 P E1^T`` with E2 any orthonormal complement
    (equal to ``(E1 P^{-1} E1^T)^{-1}``).  Raises ValueError if P is not symmetric positive definite.
    """
    p = _mat("P", P)
    e1 = _mat("E1", E1, cols=p.shape[0])
    if p.shape[0] != p.shape[1]:
        raise ValueError(f"P must be square, got {p.shape}")
    p = (p + p.T) / 2
    if np.linalg.eigvalsh(p).min() <= 0:
        raise ValueError("P must be positive definite to define the ellipsoid e^T P e <= 1")
    e2 = orthogonal_complement(e1)
    p11 = e1 @ p @ e1.T
    if e2.shape[0] == 0:
        return p11
    p12 = e1 @ p @ e2.T
    p22 = e2 @ p @ e2.T
    pz = p11 - p12 @ np.linalg.solve(p22, p12.T)
    return (pz + pz.T) / 2


def unit_ball_volume(q: int) -> float:
    """B_q: volume of the unit ball of dimension q (Cayero et al. (2019) eq. 20)."""
    if q < 1:
        raise ValueError(f"dimension q must be >= 1, got {q}")
    return math.pi ** (q / 2) / math.gamma(q / 2 + 1)


def ellipsoid_log_volume(M: ArrayLike) -> float:
    """log Vol(eps_M) = log B_q - 0.5 log det M (eq. 20), computed stably."""
    m = _mat("M", M)
    sign, logdet = np.linalg.slogdet((m + m.T) / 2)
    if sign <= 0 or not np.isfinite(logdet):
        raise ValueError("ellipsoid matrix must be positive definite")
    return math.log(unit_ball_volume(m.shape[0])) - 0.5 * float(logdet)


def ellipsoid_volume(M: ArrayLike) -> float:
    """Vol(eps_M) = B_q / sqrt(det M) (Cayero et al. (2019) eq. 20)."""
    return float(math.exp(ellipsoid_log_volume(M)))


# ---------------------------------------------------------------------- the SDP (eq. 31) ----
def _lmi7_blocks(problem: QBProblem, alpha: float, P: NDArray[np.float64], Y: NDArray[np.float64]
                 ) -> NDArray[np.float64]:
    """The matrix of LMI (7) evaluated numerically (for checks)."""
    pr = problem
    psi = pr.A.T @ P + P @ pr.A + Y @ pr.C + pr.C.T @ Y.T  # eq. 8
    top = np.hstack([psi + alpha * P, P @ pr.W1, Y @ pr.W2])
    bottom = np.hstack([np.vstack([pr.W1.T @ P, pr.W2.T @ Y.T]), -alpha * pr.Q])
    m = np.vstack([top, bottom])
    return (m + m.T) / 2


def lmi_residuals(problem: QBProblem, sol: QBSolution) -> dict[str, float]:
    """Eigenvalue checks of a solution (for tests and reports), all relative to the matrices' scale.

    ``lmi7_max_eig``: largest eigenvalue of (7) (must be <= ~0); ``lmi30_min_eig``: smallest of
    P - E1^T X E1 (>= ~0); ``P_min_eig``, ``X_min_eig`` (> 0); ``decay_margin``: max real part of
    eig(A + L C) + alpha / 2 (<= ~0, since (7) implies (A+LC)^T P + P (A+LC) + alpha P <= 0).
    """
    m7 = _lmi7_blocks(problem, sol.alpha, sol.P, sol.Y)
    m30 = sol.P - problem.E1.T @ sol.X @ problem.E1
    eig_acl = np.linalg.eigvals(problem.A + sol.L @ problem.C)
    return {
        "lmi7_max_eig": float(np.linalg.eigvalsh(m7).max()),
        "lmi7_scale": float(np.abs(m7).max()),
        "lmi30_min_eig": float(np.linalg.eigvalsh((m30 + m30.T) / 2).min()),
        "lmi30_scale": float(np.abs(sol.P).max()),
        "P_min_eig": float(np.linalg.eigvalsh(sol.P).min()),
        "X_min_eig": float(np.linalg.eigvalsh(sol.X).min()),
        "decay_margin": float(eig_acl.real.max() + sol.alpha / 2),
    }


def _auto_scaling(problem: QBProblem, alpha: float) -> NDArray[np.float64]:
    """Diagonal state scaling t (x_s = diag(t) x) from the alpha-shifted Kalman-filter Riccati equation.

    The QB ellipsoid and the steady-state error covariance Sigma of a Kalman filter with process
    noise W1 Q11^{-1} W1^T and measurement noise W2 Q22^{-1} W2^T have similar shapes, so
    t = diag(Sigma)^{-1/2} makes P well scaled.  Falls back to ones if the Riccati equation fails.
    """
    from scipy.linalg import solve_continuous_are

    pr = problem
    l1 = pr.W1.shape[1]
    try:
        qinv = np.linalg.inv(pr.Q)
        qn = pr.W1 @ qinv[:l1, :l1] @ pr.W1.T
        rn = pr.W2 @ qinv[l1:, l1:] @ pr.W2.T
        a = pr.A + 0.5 * alpha * np.eye(pr.n)
        qn = qn + 1e-12 * np.abs(qn).max() * np.eye(pr.n)
        sigma = solve_continuous_are(a.T, pr.C.T, qn, rn)
        d = np.diag(sigma)
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise ValueError("non-positive Riccati diagonal")
        t = 1.0 / np.sqrt(d)
    except (ValueError, np.linalg.LinAlgError):
        return np.ones(pr.n)
    return t


def solve_qb_lmi(problem: QBProblem, alpha: float, solver: str | None = None, p_min: float = 0.0,
                 scale: bool = True, verbose: bool = False) -> QBSolution:
    """Solve Cayero et al. (2019) eq. 31 (max log det X s.t. LMIs (7) and (30)) at a fixed ``alpha > 0``.

    ``solver``: a cvxpy solver name supporting SDP + exponential cone (``"CLARABEL"`` default, or
    ``"SCS"``).  ``scale=True`` solves the same problem in scaled coordinates (a diagonal congruence
    of the state from :func:`_auto_scaling` and of eta by sqrt(diag Q); exact equivalence, only the
    conditioning changes; used only when E1 is a row selection).  P > 0 is imposed as
    ``P_s >= p_min I`` in the scaled coordinates.  Raises :class:`QBInfeasibleError` naming alpha,
    the solver and its status when the problem is infeasible or the solver fails, and ImportError
    with the install hint when cvxpy is missing.
    """
    try:
        import cvxpy as cp
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(f"QB observer design needs cvxpy and an SDP solver: {_DESIGN_HINT}") from exc
    if not (np.isfinite(alpha) and alpha > 0):
        raise ValueError(f"alpha must be a finite positive number (eq. 7), got {shown(alpha)}")
    solver = solver or "CLARABEL"
    if solver not in cp.installed_solvers():
        raise ImportError(f"SDP solver {shown(solver)} is not installed (installed: {cp.installed_solvers()}); "
                          f"{_DESIGN_HINT}")
    pr = problem
    n, p, q, l1 = pr.n, pr.C.shape[0], pr.q, pr.W1.shape[1]
    is_selection = bool(np.all((np.abs(pr.E1) < 1e-12) | (np.abs(pr.E1 - 1.0) < 1e-12)))
    t = _auto_scaling(pr, alpha) if (scale and is_selection) else np.ones(n)
    dq = np.sqrt(np.diag(pr.Q))
    # scaled data: x_s = T x, eta_s = Dq eta  ->  A_s = T A T^-1, C_s = C T^-1, W_s = T W Dq^-1, Q_s = Dq^-1 Q Dq^-1
    A_s = t[:, None] * pr.A / t[None, :]
    C_s = pr.C / t[None, :]
    W1_s = t[:, None] * pr.W1 / dq[None, :l1]
    W2_s = pr.W2 / dq[None, l1:]
    Q_s = pr.Q / np.outer(dq, dq)
    s_z = pr.E1 @ t  # E1 T^-1 = diag(1/s_z) E1 for a selection E1
    E1_s = pr.E1
    P = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, p))
    X = cp.Variable((q, q), symmetric=True)
    psi = A_s.T @ P + P @ A_s + Y @ C_s + C_s.T @ Y.T  # eq. 8
    m7 = cp.bmat([
        [psi + alpha * P, P @ W1_s, Y @ W2_s],
        [W1_s.T @ P, -alpha * Q_s[:l1, :l1], -alpha * Q_s[:l1, l1:]],
        [W2_s.T @ Y.T, -alpha * Q_s[l1:, :l1], -alpha * Q_s[l1:, l1:]],
    ])
    constraints = [(m7 + m7.T) / 2 << 0,  # eq. 7
                   P - E1_s.T @ X @ E1_s >> 0,  # eq. 30 (X_s = S^-1 X S^-1)
                   ] + ([P >> p_min * np.eye(n)] if p_min > 0 else [])
    prob = cp.Problem(cp.Maximize(cp.log_det(X)), constraints)  # eq. 31
    t0 = time.perf_counter()
    try:
        prob.solve(solver=solver, verbose=verbose)
    except cp.error.SolverError as exc:
        raise QBInfeasibleError(f"QB design LMI (7)+(30) at alpha={alpha:g}: solver {solver} failed ({exc})") from exc
    seconds = time.perf_counter() - t0
    status = str(prob.status)
    if status not in ("optimal", "optimal_inaccurate") or P.value is None or X.value is None:
        raise QBInfeasibleError(
            f"QB design LMI (7)+(30) at alpha={alpha:g} (n={n}, p={p}, q={q}) has no solution: "
            f"solver {solver} returned status {shown(status)}. Check that (A, C) is detectable with decay "
            f"alpha/2 and that Q is the bound of (eta1, eta2).")
    # back to the original coordinates: P = T P_s T, Y = T Y_s, X = S X_s S with S = diag(s_z)
    Pv = t[:, None] * ((P.value + P.value.T) / 2) * t[None, :]
    Yv = t[:, None] * np.asarray(Y.value)
    Xv = s_z[:, None] * ((X.value + X.value.T) / 2) * s_z[None, :]
    try:
        pz = projection_matrix(Pv, pr.E1)
        log_vol = ellipsoid_log_volume(pz)
    except ValueError as exc:
        raise QBInfeasibleError(f"QB design at alpha={alpha:g}: solver {solver} returned a P that is not "
                                f"positive definite (status {shown(status)})") from exc
    L = np.linalg.solve(Pv, Yv)  # eq. 9
    sol = QBSolution(alpha=float(alpha), P=Pv, Y=Yv, X=Xv, L=L, Pz=pz, log_volume=log_vol, status=status,
                     solver=solver, solve_seconds=seconds)
    res = lmi_residuals(pr, sol)
    if res["lmi7_max_eig"] > 1e-5 * res["lmi7_scale"] or res["decay_margin"] > 1e-5 * max(alpha, 1.0):
        raise QBInfeasibleError(f"QB design at alpha={alpha:g}: solver {solver} ({status}) returned a point "
                                f"violating LMI (7): max eig {res['lmi7_max_eig']:.3g} (scale "
                                f"{res['lmi7_scale']:.3g}), decay margin {res['decay_margin']:.3g}")
    return sol


# ------------------------------------------------------- trade-off (eqs. 21-25) ----
@dataclasses.dataclass(frozen=True, eq=False)
class AlphaSweep:
    """Vol(eps_X^+)(alpha) over a grid (Cayero et al. (2019) Fig. 4); grid points where eq. 31 failed are listed in
    ``failed`` and left out of the arrays (never NaN)."""

    alphas: NDArray[np.float64]
    log_volumes: NDArray[np.float64]
    solutions: tuple[QBSolution, ...]
    failed: tuple[tuple[float, str], ...]

    @property
    def volumes(self) -> NDArray[np.float64]:
        return np.exp(self.log_volumes)


def sweep_alpha(problem: QBProblem, alphas: Sequence[float] | NDArray[np.float64], solver: str | None = None,
                progress: Callable[[int], Any] | None = None) -> AlphaSweep:
    """Solve eq. 31 at each alpha (Fig. 4).  Points that fail are reported in ``failed``; raises
    :class:`QBInfeasibleError` if none is feasible.  ``progress``, if given, is called with 1 after each alpha."""
    sols: list[QBSolution] = []
    failed: list[tuple[float, str]] = []
    for a in np.asarray(alphas, dtype=float):
        try:
            sols.append(solve_qb_lmi(problem, float(a), solver=solver))
        except QBInfeasibleError as exc:
            failed.append((float(a), str(exc)))
        if progress is not None:
            progress(1)
    if not sols:
        raise QBInfeasibleError(f"QB design infeasible at every alpha of the sweep {list(alphas)}: {failed[0][1]}")
    return AlphaSweep(alphas=np.array([s.alpha for s in sols]), log_volumes=np.array([s.log_volume for s in sols]),
                      solutions=tuple(sols), failed=tuple(failed))


@dataclasses.dataclass(frozen=True)
class ParetoAnchors:
    """Ideal (*) and nadir (dagger) values of the two objectives (Cayero et al. (2019) eqs. 22-23, Miettinen 1999).

    Objective 1 (volume) is best at ``alpha_nadir`` with ``vol_star``; objective 2 (alpha) is best
    at ``alpha_star`` (largest alpha considered) with volume ``vol_nadir``.
    """

    alpha_star: float
    alpha_nadir: float
    vol_star: float
    vol_nadir: float


def anchors_from_sweep(sweep: AlphaSweep) -> ParetoAnchors:
    """Payoff table of the two single-objective optima over the swept range of alpha."""
    i_vol = int(np.argmin(sweep.log_volumes))
    i_alpha = int(np.argmax(sweep.alphas))
    a = ParetoAnchors(alpha_star=float(sweep.alphas[i_alpha]), alpha_nadir=float(sweep.alphas[i_vol]),
                      vol_star=float(sweep.volumes[i_vol]), vol_nadir=float(sweep.volumes[i_alpha]))
    if not (a.alpha_star > a.alpha_nadir and a.vol_nadir > a.vol_star):
        raise ValueError(f"no trade-off in the swept range: the smallest volume is at the largest alpha "
                         f"({a}); extend the alpha range")
    return a


def j_mu(mu: float, alpha: float | NDArray[np.float64], volume: float | NDArray[np.float64],
         anchors: ParetoAnchors) -> NDArray[np.float64]:
    """J_mu = mu J1 + (1 - mu) J2 (Cayero et al. 2019, eqs. 21-23): J1 the normalized volume, J2 the alpha."""
    if not (0.0 <= mu <= 1.0):
        raise ValueError(f"mu must be in [0, 1], got {shown(mu)}")
    j1 = (np.asarray(volume) - anchors.vol_star) / (anchors.vol_nadir - anchors.vol_star)  # eq. 22
    j2 = (np.asarray(alpha) - anchors.alpha_star) / (anchors.alpha_nadir - anchors.alpha_star)  # eq. 23
    return mu * j1 + (1.0 - mu) * j2


def optimal_alpha(problem: QBProblem, mu: float, sweep: AlphaSweep, solver: str | None = None,
                  rtol: float = 5e-3) -> QBSolution:
    """Line search of eq. 25: minimize J_mu(alpha, Vol(eps_X^+(alpha))) over the Pareto range.

    Starts from the best grid point of ``sweep`` in [alpha_nadir, alpha_star] and refines it with a
    bounded Brent search between its grid neighbours (each evaluation solves eq. 31), to an
    absolute tolerance ``rtol * alpha_upper``.
    """
    anchors = anchors_from_sweep(sweep)
    from scipy.optimize import minimize_scalar

    mask = (sweep.alphas >= anchors.alpha_nadir) & (sweep.alphas <= anchors.alpha_star)
    idx = np.flatnonzero(mask)
    jv = j_mu(mu, sweep.alphas[idx], sweep.volumes[idx], anchors)
    k = int(idx[int(np.argmin(jv))])
    lo = float(sweep.alphas[max(k - 1, idx[0])])
    hi = float(sweep.alphas[min(k + 1, idx[-1])])
    best = sweep.solutions[k]
    xatol = rtol * hi
    if hi - lo <= xatol:
        return best
    cache: dict[float, QBSolution] = {}

    def f(a: float) -> float:
        s = cache.get(a) or solve_qb_lmi(problem, a, solver=solver)
        cache[a] = s
        return float(j_mu(mu, a, s.volume, anchors))

    res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": xatol})
    cand = cache.get(float(res.x)) or solve_qb_lmi(problem, float(res.x), solver=solver)
    if f(cand.alpha) <= float(j_mu(mu, best.alpha, best.volume, anchors)):
        return cand
    return best
