"""Modified super-twisting algorithm (STA) with a predefined convergence time, scalar theory.

Source: (Silva and Santos, "Attitude determination for multirotor
aerial vehicles using a predefined-time super twisting algorithm"), Section 3.

The modified STA (eqs. 20-22)::

    sigma(t, x) = eta / (t_c - t) * x1                     t in [t0, t_c)
                = kappa1 |x1|^(1/2) sign(x1)               t >= t_c
    x1' = -sigma(t, x) + x2
    x2' = -kappa2 sign(x1) + delta(t)

Between two zero crossings t_j < t_{j+1} of x1 (unperturbed, delta = 0) it has the closed form of
eqs. 23-25 (Theorem 1), implemented in :func:`analytic_segment` and chained over crossings in
:func:`zero_crossings` / :func:`analytic_solution`.  Theorem 2's predefined-time-convergence (PTC)
area X = {|x2(t)| <= kappa2 (t_c - t)} gives the gain conditions (30) and (36)
(:func:`kappa2_interval_36`), and Algorithm 1 tunes (eta, kappa2) until x2(t1) lies in X
(:func:`tune_algorithm1`).  Section 3.1's early switching for measurement noise uses eq. 43,
t_e = t_c - eta * ell (:func:`early_switch_time`), and sigma_e of eq. 44 (:func:`sigma`,
``t_switch=t_e``); eq. 39 bounds x1 (:func:`xi_bound`).

Two readings of eq. 44.  As printed, sigma_e = eta/(t_e - t) x1 on [t0, t_e): the singular instant
just moves to t_e, and the gain still goes to infinity there.  The text around it (eqs. 42-43: t_e is
where the gain eta/(t_c - t) reaches 1/ell; "the states will not converge to the origin at the
switching instant, but to a vicinity of it") describes keeping eta/(t_c - t) and switching to the
STA term at t_e, where the gain is the finite 1/ell.  ``early_form="tc"`` (default) implements the
text; ``early_form="eq44"`` the formula as printed.

The paper writes Theorem 2 with t0 = 0; here every time is measured from t0 (t -> t - t0), which is
the same result for any t0.  eta is an integer >= 3 in the paper; the formulas only need eta > 2,
but we keep the paper's eta >= 3 (Corollary 1) and accept any real value >= 3.

The same transition of the time-varying part, x1(t) = x1(s) ((t_c - t)/(t_c - s))^eta (eq. 7,
Proposition 1), gives :func:`exact_linear_step`, the discretization used by the observers: it stays
stable up to t_c for any step size, unlike a forward-Euler step of eta/(t_c - t), whose factor
1 - h eta/(t_c - t) leaves (-1, 1) in the last eta/2 steps before t_c.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from fawtgym.core.checks import check_number, shown


# --------------------------------------------------------------------------------------------------
# parameter checks
# --------------------------------------------------------------------------------------------------
def _finite(name: str, value: float) -> float:
    """``value`` as a float if a real, finite number (bool, complex, str, None refused), else ValueError naming it."""
    return check_number(value, name)


def check_params(t_c: float, eta: float, kappa2: float | None = None, kappa1: float | None = None,
                 t0: float = 0.0) -> None:
    """Raise ValueError unless t_c > t0, eta >= 3 (Corollary 1), kappa1 > 0 and kappa2 > 0 (eqs. 16-22)."""
    t0 = _finite("t0", t0)
    if not _finite("t_c", t_c) > t0:
        raise ValueError(f"t_c must be later than t0 = {t0}, got t_c = {shown(t_c)}")
    if not _finite("eta", eta) >= 3.0:
        raise ValueError(f"eta must be >= 3 (Corollary 1 of the paper), got {shown(eta)}")
    for name, val in (("kappa1", kappa1), ("kappa2", kappa2)):
        if val is not None and not _finite(name, val) > 0:
            raise ValueError(f"{name} must be > 0, got {shown(val)}")


# --------------------------------------------------------------------------------------------------
# right-hand side, eqs. 20-22 and 44
# --------------------------------------------------------------------------------------------------
def switch_and_gain_times(t_c: float, t_switch: float | None, early_form: str) -> tuple[float, float]:
    """(t_s, t_d): the switching instant and the instant in the gain eta/(t_d - t) (see module doc)."""
    if early_form not in ("tc", "eq44"):
        raise ValueError(f"early_form must be 'tc' (the text of Sec. 3.1) or 'eq44' (as printed), got "
                         f"{shown(early_form)}")
    t_s = t_c if t_switch is None else float(t_switch)
    if not t_s <= t_c:
        raise ValueError(f"t_switch must be <= t_c = {t_c}, got {shown(t_switch)}")
    return t_s, (t_c if early_form == "tc" else t_s)


def sigma(t: float, x1: ArrayLike, t_c: float, eta: float, kappa1: float,
          t_switch: float | None = None, early_form: str = "tc") -> NDArray[np.float64]:
    """The stabilizing function sigma of eq. 20, or sigma_e of eq. 44 when ``t_switch`` = t_e < t_c.

    For t < t_s (t_s = t_switch or t_c): eta / (t_d - t) * x1 with t_d = t_c (``early_form="tc"``) or
    t_d = t_s (``"eq44"``, eq. 44 as printed); afterwards the STA term kappa1 |x1|^(1/2) sign(x1).
    """
    t_s, t_d = switch_and_gain_times(t_c, t_switch, early_form)
    x1 = np.asarray(x1, dtype=float)
    if t < t_s:
        return eta / (t_d - t) * x1
    return kappa1 * np.sqrt(np.abs(x1)) * np.sign(x1)


def modified_sta_rhs(t_c: float, eta: float, kappa1: float, kappa2: float, t_switch: float | None = None,
                     delta: Callable[[float], float] | None = None,
                     early_form: str = "tc") -> Callable[[float, NDArray[np.float64]], NDArray]:
    """f(t, x) of eqs. 21-22 (scalar x = (x1, x2)) for :func:`scipy.integrate.solve_ivp`."""
    check_params(t_c, eta, kappa2, kappa1)

    def rhs(t: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
        x1, x2 = float(x[0]), float(x[1])
        d = 0.0 if delta is None else float(delta(t))
        return np.array([-float(sigma(t, x1, t_c, eta, kappa1, t_switch, early_form)) + x2,
                         -kappa2 * np.sign(x1) + d])

    return rhs


def exact_linear_step(x1: ArrayLike, x2: ArrayLike, target: ArrayLike, t: ArrayLike, h: ArrayLike,
                      t_s: ArrayLike, eta: float) -> NDArray[np.float64]:
    """Exact step of x1' = -eta/(t_s - t) (x1 - target) + x2 over [t, t + h], x2 and target held.

    The homogeneous transition is eq. 7 (Proposition 1): phi = ((t_s - t - h)/(t_s - t))^eta; the
    held input x2 adds psi x2 with psi = int phi(t + h, s) ds = tau1 (1 - (tau1/tau0)^(eta-1)) / (eta - 1),
    tau0 = t_s - t, tau1 = t_s - t - h.  Requires t + h <= t_s (broadcasts over a batch).
    """
    tau0 = np.asarray(t_s, dtype=float) - np.asarray(t, dtype=float)
    tau1 = tau0 - np.asarray(h, dtype=float)
    if np.any(tau1 < -1e-12 * np.maximum(1.0, np.abs(tau0))) or np.any(tau0 <= 0):
        raise ValueError("exact_linear_step needs t < t_s and t + h <= t_s")
    tau1 = np.maximum(tau1, 0.0)
    r = tau1 / tau0
    phi = r**eta
    psi = tau1 * (1.0 - r ** (eta - 1.0)) / (eta - 1.0)
    x1 = np.asarray(x1, dtype=float)
    if x1.ndim > phi.ndim:  # batch of vectors (N, 3) with per-row times (N,)
        phi, psi = phi[..., None], psi[..., None]
    target = np.asarray(target, dtype=float)
    return target + phi * (x1 - target) + psi * np.asarray(x2, dtype=float)


# --------------------------------------------------------------------------------------------------
# analytic solution, eqs. 23-25 (Theorem 1)
# --------------------------------------------------------------------------------------------------
def alpha_j(t_j: float, x1_j: float, x2_j: float, t_c: float, eta: float, kappa2: float,
            s: float | None = None) -> float:
    """alpha(t_j) of eq. 25; ``s`` = sign(x1) on the segment (default sign(x1_j))."""
    s = float(np.sign(x1_j)) if s is None else float(s)
    T = t_c - t_j
    return x1_j - T * (x2_j * (eta - 2.0) + s * kappa2 * T) / ((eta - 2.0) * (eta - 1.0))


def analytic_segment(t: ArrayLike, t_j: float, x1_j: float, x2_j: float, t_c: float, eta: float,
                     kappa2: float, s: float | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(x1(t), x2(t)) of eqs. 23-24 on [t_j, t_{j+1}) where sign(x1) = ``s`` stays constant.

    At a crossing x1_j = 0 the sign on the next segment is -sign before it: pass it as ``s``.
    """
    s = float(np.sign(x1_j)) if s is None else float(s)
    if s == 0.0:
        raise ValueError("the segment's sign s must be +1 or -1 (x1_j = 0 needs an explicit s)")
    t = np.asarray(t, dtype=float)
    tau = t_c - t
    a = alpha_j(t_j, x1_j, x2_j, t_c, eta, kappa2, s)
    x1 = tau / ((eta - 2.0) * (eta - 1.0)) * (s * kappa2 * (tau - (eta - 2.0) * (t - t_j)) + (eta - 2.0) * x2_j) \
        + a * (tau / (t_c - t_j)) ** eta
    x2 = x2_j - kappa2 * s * (t - t_j)
    return x1, x2


def _next_crossing(t_j: float, x1_j: float, x2_j: float, s: float, t_c: float, eta: float,
                   kappa2: float) -> float | None:
    """First zero of x1 (eq. 23) in (t_j, t_c), or None.

    With tau = t_c - t, x1 = tau h(tau), h(tau) = c1 + c2 tau + c3 tau^(eta-1); h'' has one sign
    on tau > 0, so h has at most two zeros, separated by the one zero of h'.  Each monotone piece is
    bracketed and solved with Brent's method, so no crossing is skipped.
    """
    T = t_c - t_j
    a = alpha_j(t_j, x1_j, x2_j, t_c, eta, kappa2, s)
    b = -kappa2 * s
    c1 = (x2_j + b * T) / (eta - 1.0)
    c2 = -b / (eta - 2.0)
    c3 = a / T**eta

    def h(tau: float) -> float:
        return c1 + c2 * tau + c3 * tau ** (eta - 1.0)

    # stationary point of h: c2 + c3 (eta - 1) tau^(eta-2) = 0
    knots = [0.0, T]
    if c3 != 0.0:
        ratio = -c2 / (c3 * (eta - 1.0))
        if ratio > 0:
            tau_star = ratio ** (1.0 / (eta - 2.0))
            if 0.0 < tau_star < T:
                knots = [0.0, tau_star, T]
    tol = 1e-12 * max(1.0, abs(c1), abs(c2) * T, abs(c3) * T ** (eta - 1.0))
    roots = []
    for lo, hi in zip(knots[:-1], knots[1:], strict=True):
        h_lo, h_hi = h(lo), h(hi)
        if hi == T and abs(h_hi) <= tol:
            continue  # the segment's own start (x1_j = 0); h is monotone here, so no other zero
        if h_lo == 0.0:
            continue  # tau = 0 is t_c itself
        if h_lo * h_hi < 0:
            roots.append(brentq(h, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=200))
    if not roots:
        return None
    return t_c - max(roots)  # largest tau = earliest time


@dataclasses.dataclass(frozen=True)
class Crossing:
    """A zero crossing t_j of x1 with x2(t_j) and the sign of x1 just before it."""

    t: float
    x2: float
    sign_before: float


def zero_crossings(x0: tuple[float, float], t_c: float, eta: float, kappa2: float, t0: float = 0.0,
                   max_crossings: int = 200) -> list[Crossing]:
    """The zero crossings t_1 < t_2 < ... < t_c of x1 (Theorem 1), chaining eqs. 23-25.

    They accumulate at t_c when the state slides into the origin; at most ``max_crossings`` are returned.
    """
    check_params(t_c, eta, kappa2, t0=t0)
    x1_j, x2_j = float(x0[0]), float(x0[1])
    if x1_j == 0.0:
        raise ValueError("x1(t0) must be nonzero (sign(x1(t0)) fixes the first segment)")
    t_j, s = float(t0), float(np.sign(x1_j))
    out: list[Crossing] = []
    while len(out) < max_crossings:
        t_next = _next_crossing(t_j, x1_j, x2_j, s, t_c, eta, kappa2)
        if t_next is None or t_next <= t_j or t_c - t_next < 1e-13 * max(1.0, t_c):
            break
        x2_next = x2_j - kappa2 * s * (t_next - t_j)
        out.append(Crossing(t_next, x2_next, s))
        t_j, x1_j, x2_j, s = t_next, 0.0, x2_next, -s
    return out


def analytic_solution(t: ArrayLike, x0: tuple[float, float], t_c: float, eta: float, kappa2: float,
                      t0: float = 0.0, max_crossings: int = 200) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """x1(t), x2(t) of the unperturbed modified STA on [t0, t_c) by eqs. 23-25 chained over crossings."""
    t = np.asarray(t, dtype=float)
    if np.any(t < t0) or np.any(t >= t_c):
        raise ValueError(f"analytic_solution covers [t0, t_c) = [{t0}, {t_c}); got times outside it")
    cross = zero_crossings(x0, t_c, eta, kappa2, t0, max_crossings)
    starts = [(float(t0), float(x0[0]), float(x0[1]), float(np.sign(x0[0])))]
    starts += [(c.t, 0.0, c.x2, -c.sign_before) for c in cross]
    x1 = np.empty_like(t)
    x2 = np.empty_like(t)
    seg = np.searchsorted([s[0] for s in starts], t, side="right") - 1
    for k, (tj, x1j, x2j, s) in enumerate(starts):
        mask = seg == k
        if np.any(mask):
            x1[mask], x2[mask] = analytic_segment(t[mask], tj, x1j, x2j, t_c, eta, kappa2, s)
    return x1, x2


# --------------------------------------------------------------------------------------------------
# Theorem 2, Algorithm 1, early switching (Sec. 3.1)
# --------------------------------------------------------------------------------------------------
def in_ptc_area(t: ArrayLike, x2: ArrayLike, t_c: float, kappa2: float) -> NDArray[np.bool_]:
    """(t, x2) in X = {-kappa2 (t_c - t) <= x2 <= kappa2 (t_c - t)} (Theorem 2)."""
    bound = kappa2 * (t_c - np.asarray(t, dtype=float))
    return np.abs(np.asarray(x2, dtype=float)) <= bound


def kappa2_interval_36(x0: tuple[float, float], t1: float, t_c: float, t0: float = 0.0) -> tuple[float, float]:
    """Interval [lo, hi] of kappa2 satisfying (30) and (36) for a given first crossing t1.

    From (33): -kappa2 (t_c - t1) <= x2(t0) - kappa2 sign(x1(t0)) (t1 - t0) <= kappa2 (t_c - t1).
    With T = t_c - t0 and T1 = t1 - t0:
    opposite signs of x1(t0), x2(t0) (second row of 36): kappa2 >= |x2(t0)| / (T - 2 T1);
    same signs (first row): kappa2 >= |x2(t0)| / T (eq. 30) and, if 2 T1 > T, kappa2 <= |x2(t0)| / (2 T1 - T)
    (Algorithm 1's ``floor``).  Returns (lo, inf) when there is no upper bound; raises ValueError if
    the opposite-sign case has T <= 2 T1 (no kappa2 works for this t1: raise eta instead).
    """
    x10, x20 = float(x0[0]), float(x0[1])
    T, T1 = t_c - t0, t1 - t0
    if not 0 < T1 < T:
        raise ValueError(f"t1 must lie in (t0, t_c) = ({t0}, {t_c}), got {shown(t1)}")
    lo30 = abs(x20) / T
    if x20 == 0.0 or np.sign(x10) == np.sign(x20):
        hi = abs(x20) / (2 * T1 - T) if 2 * T1 > T else math.inf
        return lo30, hi
    if T - 2 * T1 <= 0:
        raise ValueError(f"no kappa2 satisfies (36): t_c - 2 t1 = {T - 2 * T1:.6g} <= 0; increase eta")
    return max(lo30, abs(x20) / (T - 2 * T1)), math.inf


@dataclasses.dataclass(frozen=True)
class Tuning:
    """Result of :func:`tune_algorithm1`."""

    eta: float
    kappa2: float
    t1: float | None
    x2_t1: float | None
    iterations: int


def first_crossing_in_ptc(x0: tuple[float, float], t_c: float, eta: float, kappa2: float,
                          t0: float = 0.0) -> tuple[bool, float | None, float | None]:
    """(x2(t1) in X, t1, x2(t1)); without a crossing before t_c, x2(t_c) must be 0 (X's apex)."""
    cross = zero_crossings(x0, t_c, eta, kappa2, t0, max_crossings=1)
    if not cross:
        _, x2_end = analytic_segment(t_c, t0, x0[0], x0[1], t_c, eta, kappa2)
        return bool(abs(float(x2_end)) <= 1e-12), None, None
    c = cross[0]
    return bool(in_ptc_area(c.t, c.x2, t_c, kappa2)), c.t, c.x2


def tune_algorithm1(x0: tuple[float, float], t_c: float, eta: float = 3.0, kappa2: float | None = None,
                    t0: float = 0.0, strategy: str = "gain", max_iter: int = 100) -> Tuning:
    """Algorithm 1: adjust kappa2 (``strategy="gain"``) or eta (``"rate"``) until x2(t1) is in X.

    Starts from kappa2 >= |x2(t0)| / (t_c - t0) (eq. 30; the default is ceil of that, at least 1).
    ``"gain"`` sets kappa2 to ceil (opposite signs) / floor (same signs) of |x2(t0)/(t_c - 2 t1)| as
    the paper's pseudo-code, but never below the eq.-30 value and always moving by at least 1 so the
    loop cannot stall; ``"rate"`` increases eta by 1.  t1 is recomputed from eq. 23 after each change.
    Raises ValueError when no admissible pair is found within ``max_iter`` changes.
    """
    if strategy not in ("gain", "rate"):
        raise ValueError(f"strategy must be 'gain' or 'rate', got {shown(strategy)}")
    x20 = abs(float(x0[1]))
    k30 = x20 / (t_c - t0)
    kappa2 = float(max(1.0, math.ceil(k30))) if kappa2 is None else float(kappa2)
    check_params(t_c, eta, kappa2, t0=t0)
    if kappa2 < k30:
        raise ValueError(f"kappa2 = {kappa2} violates (30): needs kappa2 >= |x2(t0)|/(t_c - t0) = {k30:.6g}")
    same = float(x0[1]) == 0.0 or np.sign(x0[0]) == np.sign(x0[1])
    for it in range(max_iter + 1):
        ok, t1, x2_t1 = first_crossing_in_ptc(x0, t_c, eta, kappa2, t0)
        if ok:
            return Tuning(float(eta), float(kappa2), t1, x2_t1, it)
        if strategy == "rate" or t1 is None or (not same and t_c - 2 * t1 <= t0):
            eta = eta + 1.0
            continue
        denom = abs(t_c - t0 - 2 * (t1 - t0))
        if same:
            new = float(math.floor(x20 / denom))
            new = min(new, kappa2 - 1.0)
            if new < k30:
                eta = eta + 1.0  # no admissible gain left: fall back to the rate
                continue
        else:
            new = max(float(math.ceil(x20 / denom)), kappa2 + 1.0)
        kappa2 = new
    raise ValueError(f"Algorithm 1 found no (eta, kappa2) within {max_iter} iterations "
                     f"(last eta = {eta}, kappa2 = {kappa2}) for x0 = {x0}, t_c = {t_c}")


def early_switch_time(t_c: float, eta: float, noise_bound: float, t0: float = 0.0) -> float:
    """Eq. 43: t_e = t_c - eta * ell, the instant where eta/(t_c - t) * ell = 1 (eq. 42)."""
    check_params(t_c, eta, t0=t0)
    noise_bound = check_number(noise_bound, "noise_bound (ell)", minimum=0.0, inclusive_minimum=True)
    t_e = t_c - eta * noise_bound
    if t_e <= t0:
        raise ValueError(f"t_e = t_c - eta*ell = {t_e:.6g} is not after t0 = {t0}: reduce eta or ell, or raise t_c")
    return t_e


def xi_bound(t: ArrayLike, x1_0: float, t_c: float, eta: float, kappa2: float, t0: float = 0.0) -> NDArray[np.float64]:
    """Eq. 39: xi(t) bounding |x1(t)| on [t0, t_c) when x2 stays in X (Corollary 3)."""
    check_params(t_c, eta, kappa2, t0=t0)
    tau = t_c - np.asarray(t, dtype=float)
    T = t_c - t0
    return kappa2 * tau**2 / (eta - 2.0) + (abs(x1_0) - kappa2 * T**2 / (eta - 2.0)) * (tau / T) ** eta


def simulate_scalar(x0: tuple[float, float], t_end: float, h: float, t_c: float, eta: float, kappa1: float,
                    kappa2: float, t_switch: float | None = None, delta: Callable[[float], float] | None = None,
                    noise: NDArray[np.float64] | None = None,
                    early_form: str = "tc") -> tuple[NDArray, NDArray, NDArray]:
    """Fixed-step simulation of eqs. 21-22 (with eq. 40-41 noise on x1 inside sigma and sign, eq. 44).

    The time-varying phase uses :func:`exact_linear_step`; after the switch, forward Euler (as the
    paper's simulations).  ``noise`` (len = steps) is v of eq. 41.  Returns t, x1, x2.
    """
    check_params(t_c, eta, kappa2, kappa1)
    t_s, t_d = switch_and_gain_times(t_c, t_switch, early_form)
    n = int(round(t_end / h))
    if noise is not None and len(noise) < n:
        raise ValueError(f"noise needs at least {n} samples, got {len(noise)}")
    x1s = np.empty(n + 1)
    x2s = np.empty(n + 1)
    x1, x2 = float(x0[0]), float(x0[1])
    x1s[0], x2s[0] = x1, x2
    nz = [0.0] * n if noise is None else [float(v) for v in noise[:n]]
    for k in range(n):  # plain floats: a scalar reference simulation, not a batch hot path
        tk = k * h
        v = nz[k]
        xm = x1 + v
        sgn = (xm > 0) - (xm < 0)
        d = 0.0 if delta is None else float(delta(tk))
        h1 = min(h, max(t_s - tk, 0.0))
        if h1 > 0:
            # x1' = -eta/(t_d - t)(x1 + v) + x2: exact step towards -v (eq. 7 transition, see exact_linear_step)
            tau0 = t_d - tk
            tau1 = max(tau0 - h1, 0.0)
            r = tau1 / tau0
            x1 = -v + r**eta * (x1 + v) + tau1 * (1.0 - r ** (eta - 1.0)) / (eta - 1.0) * x2
        h2 = h - h1
        if h2 > 0:
            x1 = x1 + h2 * (-kappa1 * math.sqrt(abs(xm)) * sgn + x2)
        x2 = x2 + h * (-kappa2 * sgn + d)
        x1s[k + 1], x2s[k + 1] = x1, x2
    return np.arange(n + 1) * h, x1s, x2s
