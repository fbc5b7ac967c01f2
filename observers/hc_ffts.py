"""Hölder-continuous fast finite-time stable differentiator (HC-FFTSD), Wang et al. (2024) Theorem 1.

Source: (Wang, Hamrah, Sanyal, Glauser 2024), Sec. 3.

* :func:`phi1`, :func:`phi2` -- the output-injection maps of eq. (9); both are continuous at 0 and
  evaluated without NaN/inf there (the fractional power of ``e^T e`` is only taken where it is > 0).
  Each law of eqs. (9)/(49)/(50) is written once, on one row, as a compiled helper (:func:`phi_row`: phi_1 and
  phi_2; :func:`frac_power_row`: g and its rate) that the ESO kernels call per row, given its one fractional
  power (:func:`phi_power`, :func:`frac_power_power`: a kernel takes those of all rows in a loop of their own,
  where the rows' powers overlap); the batch functions here
  loop them over the rows.
* :func:`phi1_jacobian` -- eq. (12), so that eq. (13) ``phi2 = phi1' phi1`` can be checked.
* :func:`frac_power` / :func:`frac_power_rate` -- the term ``(e^T e)^((1-p)/p) e`` of eqs. (50)/(69)
  and its time derivative ``(e^T e)^((1-p)/p) H(e, (p-1)/p) e'`` (Def. 1, eq. 8) used by the ESOs.
  The derivative is unbounded as e -> 0 (exponent (2-p)/p - 1 < 0), so the ESOs use the regularised
  g(e) = max(e^T e, eps)^((1-p)/p) e (exact for |e| > sqrt(eps), linear inside) and g's exact,
  bounded derivative.  This is the one numerical regularisation of the continuous-time law; it is
  documented wherever it is used.
* :func:`euler_stable_eps` -- the floor eps a discrete-time ESO must use at step dt so that explicit
  Euler stays stable inside the ball (derivation in its docstring).
* :class:`HCFFTSD` -- gains (k1, k2, k3, p), the Lyapunov matrix P of eq. (17) from scipy,
  gamma_1, gamma_2 of eq. (32), the Lyapunov function (19) and the settling-time bound of Lemma 2,
  eq. (5) with lambda_1 = gamma_1, lambda_2 = gamma_2, alpha = 1/p.

Everything is batch-first over leading axes: ``e`` has shape (..., n).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import check_number, shown

#: floor on e^T e in the *derivative* terms (frac_power_rate, phi1_jacobian); see module docstring
DEFAULT_EPS = 1e-12


def check_p(p: float) -> float:
    """Validate the Hölder exponent parameter p in ]1, 2[ (Theorem 1): a real number (bool, complex, str refused)."""
    return check_number(p, "p", minimum=1.0, maximum=2.0, inclusive_maximum=False,
                        note="(the open interval of Wang et al. (2024) Theorem 1)")


def _sq(e: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.sum(e * e, axis=-1, keepdims=True)


# ---- the laws of eqs. (9), (49)/(68) on one row (compiled; the ESO kernels call them per row) ----------------
@njit(cache=True, inline="always")
def dot_row(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """a . b of two rows (k,)."""
    acc = 0.0
    for j in range(a.shape[0]):
        acc += a[j] * b[j]
    return acc


@njit(cache=True, inline="always")
def _pow_or_zero(r2: float, a: float) -> float:
    """r2**a for r2 > 0, 0 at r2 = 0 (a < 0 here; the power only ever multiplies e, whose limit is 0)."""
    return r2**a if r2 > 0.0 else 0.0


@njit(cache=True, inline="always")
def phi_power(e2: float, p: float) -> float:
    """q = (e^T e)^a, a = (1-p)/(3p-2), of eq. (9) from ``e2`` = e^T e (0 at e = 0): the one fractional power of
    :func:`phi_row`, a function of its own so that a kernel can take the powers of many rows in one loop (a power
    costs ~26 ns of latency but ~11 ns of throughput: independent rows overlap)."""
    return _pow_or_zero(e2, (1.0 - p) / (3.0 * p - 2.0))


@njit(cache=True, inline="always")
def phi_row(e: NDArray[np.float64], k3: float, p: float, q: float, phi1_out: NDArray[np.float64],
            phi2_out: NDArray[np.float64]) -> None:
    """phi_1(e) and phi_2(e) of eq. (9), a = (1-p)/(3p-2), q = |e|^(2a) = :func:`phi_power` (e^T e, p)::

        phi_1 = (k3 + q) e,     phi_2 = (k3^2 + 2 k3 (2p-1)/(3p-2) q + p/(3p-2) q^2) e

    (one fractional power for both: the ESOs need the pair)."""
    gain1 = k3 + q
    gain2 = k3 * k3 + 2.0 * k3 * (2.0 * p - 1.0) / (3.0 * p - 2.0) * q + p / (3.0 * p - 2.0) * q * q
    for j in range(e.shape[0]):
        phi1_out[j] = gain1 * e[j]
        phi2_out[j] = gain2 * e[j]


@njit(cache=True, inline="always")
def frac_power_power(e2: float, p: float, eps: float) -> float:
    """r^c, c = (1-p)/p, r = max(e^T e, eps) (``eps`` > 0) or e^T e (``eps`` <= 0; 0 at e = 0), from ``e2`` = e^T e:
    the one fractional power of :func:`frac_power_row` (a function of its own for the reason of :func:`phi_power`)."""
    c = (1.0 - p) / p
    if eps > 0.0:
        return max(e2, eps) ** c
    return _pow_or_zero(e2, c)


@njit(cache=True, inline="always")
def frac_power_row(e: NDArray[np.float64], edot: NDArray[np.float64], p: float, eps: float, pw: float,
                   g_out: NDArray[np.float64], rate_out: NDArray[np.float64]) -> None:
    """g(e) = max(e^T e, eps)^c e (eqs. 50/69, regularised) and its time derivative along e' = edot (eqs. 49/68)::

        r = max(e^T e, eps),  c = (1-p)/p,  k = (p-1)/p
        g = r^c e,   g' = r^c (e' - 2k (e.e') e / r)  for e^T e > eps  (H(e, k) e' of Def. 1, eq. 8),
                     g' = eps^c e'                    inside the ball

    with ``pw`` = r^c = :func:`frac_power_power` (e^T e, p, eps) (one fractional power for both).  ``eps`` <= 0: the
    exact power (e^T e)^c e, 0 at e = 0; its rate is then only meaningful away from e = 0."""
    r2 = dot_row(e, e)
    r = max(r2, eps) if eps > 0.0 else r2
    coef = 2.0 * (p - 1.0) / p * dot_row(e, edot) / r if r2 > eps and r > 0.0 else 0.0
    for j in range(e.shape[0]):
        g_out[j] = pw * e[j]
        rate_out[j] = pw * (edot[j] - coef * e[j])


@njit(cache=True)
def _phi_rows(e: NDArray[np.float64], k3: float, p: float, out1: NDArray[np.float64],
              out2: NDArray[np.float64]) -> None:
    for i in range(e.shape[0]):
        phi_row(e[i], k3, p, phi_power(dot_row(e[i], e[i]), p), out1[i], out2[i])


@njit(cache=True)
def _frac_power_rows(e: NDArray[np.float64], edot: NDArray[np.float64], p: float, eps: float,
                     g_out: NDArray[np.float64], rate_out: NDArray[np.float64]) -> None:
    for i in range(e.shape[0]):
        frac_power_row(e[i], edot[i], p, eps, frac_power_power(dot_row(e[i], e[i]), p, eps), g_out[i], rate_out[i])


def _rows_2d(e: ArrayLike) -> tuple[NDArray[np.float64], tuple[int, ...]]:
    a = np.asarray(e, dtype=float)
    return np.ascontiguousarray(a.reshape(-1, a.shape[-1])), a.shape


def phi1(e: ArrayLike, k3: float, p: float) -> NDArray[np.float64]:
    """phi_1(e) = k3 e + (e^T e)^((1-p)/(3p-2)) e, eq. (9), over leading axes (:func:`phi_row`).  phi_1(0) = 0."""
    rows, shape = _rows_2d(e)
    out1, out2 = np.empty_like(rows), np.empty_like(rows)
    _phi_rows(rows, float(k3), float(p), out1, out2)
    return out1.reshape(shape)


def phi2(e: ArrayLike, k3: float, p: float) -> NDArray[np.float64]:
    """phi_2(e) of eq. (9): k3^2 e + 2 k3 (2p-1)/(3p-2) |e|^(2a) e + p/(3p-2) |e|^(4a) e, a=(1-p)/(3p-2)
    (:func:`phi_row`)."""
    rows, shape = _rows_2d(e)
    out1, out2 = np.empty_like(rows), np.empty_like(rows)
    _phi_rows(rows, float(k3), float(p), out1, out2)
    return out2.reshape(shape)


def phi1_jacobian(e: ArrayLike, k3: float, p: float, eps: float = DEFAULT_EPS) -> NDArray[np.float64]:
    """phi_1'(e) of eq. (12), shape (..., n, n).

    The exact Jacobian is unbounded at e = 0; ``e^T e`` is floored at ``eps`` so the result is finite
    everywhere and exact for |e| > sqrt(eps).
    """
    e = np.asarray(e, dtype=float)
    n = e.shape[-1]
    a = (1.0 - p) / (3.0 * p - 2.0)
    r2 = np.maximum(_sq(e), eps)[..., None]
    outer = e[..., :, None] * e[..., None, :]
    eye = np.eye(n)
    return k3 * eye + r2**a * (eye - 2.0 * (p - 1.0) / (3.0 * p - 2.0) * outer / r2)


def h_matrix(x: ArrayLike, k: float, eps: float = 0.0) -> NDArray[np.float64]:
    """H(x, k) = I - 2k x x^T / (x^T x), Definition 1 eq. (8), shape (..., 3, 3).

    At x = 0 (undefined in the paper) the outer-product term is taken as 0, i.e. H = I; with
    ``eps`` > 0 the denominator is max(x^T x, eps).
    """
    x = np.asarray(x, dtype=float)
    r2 = _sq(x)[..., None]
    den = np.maximum(r2, eps) if eps > 0 else r2
    safe = np.where(den > 0, den, 1.0)
    outer = x[..., :, None] * x[..., None, :]
    return np.eye(x.shape[-1]) - 2.0 * k * np.where(den > 0, outer / safe, 0.0)


def frac_power(e: ArrayLike, p: float, eps: float = 0.0) -> NDArray[np.float64]:
    """g(e) = max(e^T e, eps)^((1-p)/p) e, the fractional term of eqs. (50)/(69) (:func:`frac_power_row`).

    With eps = 0 this is exactly (e^T e)^((1-p)/p) e (continuous, 0 at e = 0).  With eps > 0 it is exact for
    |e| > sqrt(eps) and linear inside that ball -- the regularisation used by the ESOs, whose derivative
    :func:`frac_power_rate` is bounded.  Its slope inside the ball is eps^((1-p)/p); an ESO integrated by
    explicit Euler at step dt must take eps from :func:`euler_stable_eps` (a fixed 1e-12 diverges for p > 1.4).
    """
    rows, shape = _rows_2d(e)
    out, rate = np.empty_like(rows), np.empty_like(rows)
    _frac_power_rows(rows, rows, float(p), float(eps), out, rate)
    return out.reshape(shape)


def frac_power_rate(e: ArrayLike, edot: ArrayLike, p: float, eps: float = DEFAULT_EPS) -> NDArray[np.float64]:
    """Exact time derivative of :func:`frac_power` (same eps > 0) along e' = edot (:func:`frac_power_row`).

    For |e| > sqrt(eps): (e^T e)^((1-p)/p) H(e, (p-1)/p) e' as in eqs. (49)/(68) (Definition 1), computed as
    r^c (e' - 2k (e.e') e / r) with r = e^T e, c = (1-p)/p, k = (p-1)/p.  Inside the ball: eps^c e'.
    The unregularised derivative is unbounded at e = 0, hence eps must be > 0.
    """
    if not (np.isfinite(eps) and eps > 0):
        raise ValueError(f"eps must be > 0 (the exact derivative is unbounded at e = 0), got {shown(eps)}")
    e_arr, edot_arr = np.broadcast_arrays(np.asarray(e, dtype=float), np.asarray(edot, dtype=float))
    rows, shape = _rows_2d(e_arr)
    rates, _ = _rows_2d(edot_arr)
    g, out = np.empty_like(rows), np.empty_like(rows)
    _frac_power_rows(rows, rates, float(p), float(eps), g, out)
    return out.reshape(shape)


#: |Euler factor - 1| allowed for the stiffest mode of the regularised fractional term (< 2 is stable; see
#: :func:`euler_stable_eps`).  1.5 keeps every p = 1.2 run of the project at dt <= 10 ms on the fixed floor
#: DEFAULT_EPS (there kappa eps^c dt <= 1.38), so those results do not change.
EULER_MARGIN = 1.5


def euler_stable_eps(p: float, gain: float, dt: float, floor: float = DEFAULT_EPS,
                     margin: float = EULER_MARGIN) -> float:
    """The floor eps of :func:`frac_power` for an ESO integrated by explicit Euler at step ``dt``.

    Derivation.  With c = (1-p)/p < 0, g(e) = max(e^T e, eps)^c e has the Jacobian eps^c I inside the ball
    |e| <= sqrt(eps) and |e|^(2c) (I + 2c e e^T / e^T e) outside it, whose eigenvalues |e|^(2c) and
    |e|^(2c) (2-p)/p are largest at the ball's edge: the largest slope of g is eps^c.  The ESOs feed the
    derivative of kappa g(e) back into the rate of the error it differentiates (eqs. 49/68 of Wang et al.
    2024: e_v' = -kappa (g'(e_b) + I) e_v + slower terms), so near e = 0 the stiffest mode of the error
    dynamics is e' = -lambda e with lambda = gain eps^c, ``gain`` = kappa times the largest gain from the
    observer's error rate to e's rate (kappa_t for the translational ESO; kappa_a (K1 + K2 + K3 - min K)
    for the rotational one, since e_R' = (tr(K) I - K) e_Omega at E = I, eq. 66).  Explicit Euler maps it
    to e <- (1 - lambda dt) e: stable only while lambda dt < 2, i.e. gain eps^c dt < 2.  With the fixed
    eps = 1e-12 this fails for p > 1.395 at kappa = 0.8, dt = 1 ms (eps^c = 10^(12 (p-1)/p) reaches 1e4 at
    p = 1.5), and a smaller dt does not help enough because eps^c grows as fast as 10^(12 (p-1)/p).

    So eps is raised until gain eps^c dt <= ``margin`` (< 2):
    eps = max(floor, (gain dt / margin)^(p / (p-1))), since eps^c = (gain dt / margin)^(-1) then.
    The regularisation changes the law only inside a ball of radius sqrt(eps) (for p = 1.9, dt = 1 ms,
    gain 1.4: about 0.7e-3 in the error's units), where it replaces a gain the step cannot resolve by the
    largest one it can.  Where the fixed floor already satisfies the bound (p = 1.2 at dt <= 10 ms for the
    project's gains) eps stays ``floor`` and nothing changes.
    """
    check_p(p)
    if not (np.isfinite(gain) and gain > 0 and np.isfinite(dt) and dt > 0):
        raise ValueError(f"gain and dt must be finite positive numbers, got gain={shown(gain)}, dt={shown(dt)}")
    if not (0.0 < margin < 2.0):
        raise ValueError(f"margin must lie in (0, 2) (explicit Euler is unstable beyond 2), got {shown(margin)}")
    return max(float(floor), (gain * dt / margin) ** (p / (p - 1.0)))


def lyapunov_p(k1: float, k2: float, q: ArrayLike | None = None) -> NDArray[np.float64]:
    """P* solving (A*)^T P* + P* A* = -Q*, eq. (17), with A* of eq. (10) (Q* = I by default).

    Raises ValueError if A* is not Hurwitz (k1, k2 > 0) or Q* is not symmetric positive definite.
    """
    a = hurwitz_matrix(k1, k2)
    qm = np.eye(2) if q is None else np.asarray(q, dtype=float)
    if qm.shape != (2, 2) or not np.allclose(qm, qm.T) or np.linalg.eigvalsh(qm).min() <= 0:
        raise ValueError(f"Q* must be a symmetric positive-definite 2x2 matrix, got {qm.tolist()}")
    # scipy solves A X + X A^H = Q; with A := (A*)^T and Q := -Q* this is eq. (17).
    pm = scipy.linalg.solve_continuous_lyapunov(a.T, -qm)
    return 0.5 * (pm + pm.T)


def hurwitz_matrix(k1: float, k2: float, label: str = "A*") -> NDArray[np.float64]:
    """A = [[-k1, 1], [-k2, 0]] (eqs. 10, 48, 67); raises ValueError unless it is Hurwitz."""
    a = np.array([[-check_number(k1, "k1"), 1.0], [-check_number(k2, "k2"), 0.0]])
    eig = np.linalg.eigvals(a)
    if not (np.all(np.isfinite(a)) and np.all(eig.real < 0)):
        raise ValueError(f"{label} = [[-k1, 1], [-k2, 0]] must be Hurwitz (needs k1 > 0 and k2 > 0); "
                         f"got k1={shown(k1)}, k2={shown(k2)} with eigenvalues {eig}")
    return a


@dataclasses.dataclass(frozen=True)
class HCFFTSD:
    """The differentiator (11): e1' = -k1 phi1(e1) + e2, e2' = -k2 phi2(e1) (+ perturbation, eq. 33).

    Construction validates p in ]1, 2[, k3 > 0 and the Hurwitz condition of eq. (10).
    """

    k1: float
    k2: float
    k3: float
    p: float
    q: tuple[tuple[float, float], tuple[float, float]] = ((1.0, 0.0), (0.0, 1.0))
    #: P* of eq. (17) and (gamma_1, gamma_2) of eq. (32), computed at construction
    _pm: NDArray[np.float64] = dataclasses.field(init=False, repr=False, compare=False)
    _gammas: tuple[float, float] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        check_p(self.p)
        if not (np.isfinite(self.k3) and self.k3 > 0):
            raise ValueError(f"k3 must be a finite positive number (Theorem 1), got k3={shown(self.k3)}")
        hurwitz_matrix(self.k1, self.k2)
        pm = lyapunov_p(self.k1, self.k2, np.asarray(self.q))
        object.__setattr__(self, "_pm", pm)
        lp = np.linalg.eigvalsh(pm)
        lq = np.linalg.eigvalsh(np.asarray(self.q, dtype=float))
        p = self.p
        g1 = self.k3 * lq[0] / lp[-1]
        g2 = lq[0] * lp[0] ** ((p - 1.0) / p) / lp[-1] * p / (3.0 * p - 2.0)
        object.__setattr__(self, "_gammas", (float(g1), float(g2)))

    # ---- dynamics ----------------------------------------------------------------------
    def rhs(self, e1: ArrayLike, e2: ArrayLike, perturbation: ArrayLike | float = 0.0
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Right-hand side of eq. (11) (eq. 33 with a perturbation Delta^D)."""
        e1 = np.asarray(e1, dtype=float)
        e2 = np.asarray(e2, dtype=float)
        return (-self.k1 * phi1(e1, self.k3, self.p) + e2,
                -self.k2 * phi2(e1, self.k3, self.p) + np.asarray(perturbation, dtype=float))

    # ---- Lyapunov analysis ---------------------------------------------------------------
    @property
    def p_matrix(self) -> NDArray[np.float64]:
        """P* of eq. (17) for this A* and Q* (solved once, at construction)."""
        return self._pm.copy()

    def gammas(self) -> tuple[float, float]:
        """(gamma_1, gamma_2) of eq. (32): k3 lmin(Q)/lmax(P) and lmin(Q) lmin(P)^((p-1)/p) / lmax(P) p/(3p-2)."""
        return self._gammas

    def lyapunov(self, e1: ArrayLike, e2: ArrayLike) -> NDArray[np.float64]:
        """V = zeta^T P zeta with zeta = [phi1(e1), e2], eq. (19); shape (...,)."""
        z1 = phi1(e1, self.k3, self.p)
        z2 = np.asarray(e2, dtype=float)
        pm = self._pm
        return (pm[0, 0] * np.sum(z1 * z1, -1) + 2 * pm[0, 1] * np.sum(z1 * z2, -1)
                + pm[1, 1] * np.sum(z2 * z2, -1))

    def settling_time_bound(self, e1: ArrayLike, e2: ArrayLike) -> NDArray[np.float64]:
        """Upper bound on the settling time, eq. (5) with lambda_1, lambda_2 = gamma_1, gamma_2 and alpha = 1/p."""
        g1, g2 = self.gammas()
        alpha = 1.0 / self.p
        v0 = self.lyapunov(e1, e2)
        return np.log((g1 * v0 ** (1.0 - alpha) + g2) / g2) / (g1 * (1.0 - alpha))

    def comparison_bound(self, v0: float, t: ArrayLike) -> NDArray[np.float64]:
        """Solution of the comparison ODE V' = -g1 V - g2 V^(1/p) (eq. 31 with equality), V(0) = v0.

        With W = V^(1-alpha): W' = -(1-alpha)(g1 W + g2), so W(t) = (W0 + g2/g1) e^{-(1-alpha) g1 t} - g2/g1,
        clipped at 0 (reached exactly at the time of eq. 5).
        """
        g1, g2 = self.gammas()
        alpha = 1.0 / self.p
        t = np.asarray(t, dtype=float)
        w = (v0 ** (1 - alpha) + g2 / g1) * np.exp(-(1 - alpha) * g1 * t) - g2 / g1
        return np.maximum(w, 0.0) ** (1.0 / (1.0 - alpha))
