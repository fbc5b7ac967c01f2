"""FFTS-ESO on TSE(3): fast finite-time stable extended state observer (Wang et al. (2024) Sec. 5).

Source:.  Model eq. (38) (world NED, body FRD)::

    b' = v,  m v' = m g e3 - f R e3 + phi_D,  R' = R Omega^,  J Omega' = J Omega x Omega + tau + tau_D

Translational ESO, Proposition 1 eqs. (48)-(50), errors eq. (45) (e_b = b^m - b_hat, e_v = v^m - v_hat)::

    b_hat'   = v_hat
    v_hat'   = g e3 - (f/m) R^m e3 + k_t1 phi1(psi_t) + kappa_t [ |e_b|^(2(1-p)/p) H(e_b, (p-1)/p) e_v + e_v ]
               + phi_hat / m
    phi_hat' = m k_t2 phi2(psi_t),     psi_t = e_v + kappa_t [ e_b + |e_b|^(2(1-p)/p) e_b ]

(eq. 49 prints the bracket's gain as ``k_t``; the error dynamics (51)-(52) only close with ``k_t = kappa_t``,
which is what is implemented.)  phi1/phi2 are eq. (9) with k3 := k_t3.

Rotational ESO, Proposition 2 eqs. (66)-(69), errors eqs. (46)-(47) (E_R = R_hat^T R^m,
e_Omega = Omega^m - E_R^T Omega_hat), e_R = s_K(E_R) (Lemma 5, eq. 41) and e_w = d/dt e_R (eq. 66)::

    R_hat'     = R_hat Omega_hat^
    Omega_hat' = E_R J^-1 [J Om^m x Om^m + tau_hat + tau] + E_R [k_a1 phi1(psi_a)
                 + kappa_a (|e_R|^(2(1-p)/p) H(e_R, (p-1)/p) e_w + e_w)] + E_R e_Omega^ E_R^T Omega_hat
    tau_hat'   = J k_a2 phi2(psi_a),    psi_a = e_Omega + kappa_a [ e_R + |e_R|^(2(1-p)/p) e_R ]

(eq. 68 with J^-1 J cancelled).  Closed forms used (checked in tests against the sums of eqs. 41/66):
``s_K(E) = vee(K E - E^T K)`` and ``e_w = tr(K E) e_Omega - E^T K e_Omega``.

Discretisation: the measurement and the applied thrust/torque are held over ``dt`` (zero-order hold);
the vector states are advanced by explicit Euler, the kinematic chains b_hat' = v_hat and
R_hat' = R_hat Omega_hat^ exactly for the held accelerations (R_hat by the exponential map,
:func:`fawtgym.core.so3.integrate_rotation`, so R_hat stays on SO(3)).  The time derivative of
the fractional power (the H-terms) is unbounded at e = 0, so the fractional power is regularised as
g(e) = max(e^T e, eps)^((1-p)/p) e (exact for |e| > sqrt(eps), linear inside) and its *exact* derivative
is used (:func:`fawtgym.observers.hc_ffts.frac_power` / :func:`~fawtgym.observers.hc_ffts.frac_power_rate`), so the
implemented observer is the paper's with psi's fractional term replaced by g; finite at e = 0.

The floor eps depends on p and dt.  g's largest slope is eps^((1-p)/p) (at the ball's edge), and the
H-terms feed it back into the error's own rate, so the stiffest error mode near e = 0 decays at
lambda = kappa eps^((1-p)/p) (times tr(K) - min K for the rotational ESO, eq. 66); explicit Euler is
unstable once lambda dt > 2.  With a fixed eps = 1e-12 and dt = 1 ms that happens for p > 1.395 (p = 1.5:
force errors of 1.5 N, p = 1.9: tens of N).  Each update therefore uses, per ESO half,
eps = max(``eps``, (gain dt / 1.5)^(p/(p-1))) (:func:`fawtgym.observers.hc_ffts.euler_stable_eps`, with the
derivation), which keeps lambda dt <= 1.5 for every p in (1, 2) and leaves eps at ``eps`` wherever the fixed
floor was already stable (p = 1.2 with the paper's gains at dt <= 10 ms: unchanged results).

Default gains: the paper's Sec. 6 simulation gains, p = 1.2, k_t1 = 3, k_t2 = 2, k_t3 = 6, kappa_t = 0.8,
k_a1 = 3, k_a2 = 2, k_a3 = 4, kappa_a = 0.6.  The paper does not give K of the Morse function; the
default K = diag(1.2, 1.1, 1.0) is our choice (satisfies K1 > K2 > K3 >= 1 of Lemma 5).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.rows import write_rows
from fawtgym.core.so3 import integrate_rotation, project_so3, vee
from fawtgym.observers._obs_common import (
    batch_vec,
    cross,
    require,
)
from fawtgym.observers.base import Observer, ObserverEstimate, register_observer
from fawtgym.observers.hc_ffts import DEFAULT_EPS, check_p, euler_stable_eps, hurwitz_matrix

_E3 = np.array([0.0, 0.0, 1.0])
_TINY = 1e-300          # floor inside the fractional powers of phi1/phi2: x**neg * 0 stays 0, never inf*0
_ONES = np.ones((3, 1))   # row sums as a BLAS product (cheaper than np.sum on small batches)
_VA = np.array([2, 0, 1])
_VB = np.array([1, 2, 0])
_KEYS = ("position", "velocity", "attitude", "angular_velocity")


def s_k(r: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """s_K(R) = sum_i K_i (R^T e_i) x e_i (eq. 41) = vee(K R - R^T K); R (..., 3, 3), K the 3 diagonal entries."""
    r = np.asarray(r, dtype=float)
    km = np.diag(np.asarray(k, dtype=float))
    return vee(km @ r - np.swapaxes(r, -1, -2) @ km)


def s_k_rate(r: ArrayLike, omega: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """d/dt s_K(E) for E' = E omega^: sum_i K_i e_i x (omega x E^T e_i) (eq. 66) = tr(K E) w - E^T K w."""
    r = np.asarray(r, dtype=float)
    w = np.asarray(omega, dtype=float)
    kv = np.asarray(k, dtype=float)
    tr = np.einsum("i,...ii->...", kv, r)
    return tr[..., None] * w - np.einsum("...ji,...j->...i", r, kv * w)


def morse(r: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """<K, I - R> = tr(K (I - R)), the Morse function of Lemma 5."""
    r = np.asarray(r, dtype=float)
    kv = np.asarray(k, dtype=float)
    return np.sum(kv) - np.einsum("i,...ii->...", kv, r)


def validate_gains(p: float, kt1: float, kt2: float, kt3: float, kappa_t: float, ka1: float, ka2: float,
                   ka3: float, kappa_a: float, morse_k: Sequence[float]) -> None:
    """Check the conditions of Theorem 1 and Propositions 1-2 / Lemma 5; ValueError explains which fails."""
    check_p(p)
    for name, val in (("kappa_t", kappa_t), ("kappa_a", kappa_a)):
        if not (np.isfinite(val) and val > 0.5):
            raise ValueError(f"{name} must be > 1/2 (Wang et al. (2024) eqs. 50/69), got {name}={val!r}")
    hurwitz_matrix(kt1, kt2, "A_t (eq. 48)")
    hurwitz_matrix(ka1, ka2, "A_a (eq. 67)")
    for name, val in (("kt3", kt3), ("ka3", ka3)):
        if not (np.isfinite(val) and val > 0):
            raise ValueError(f"{name} must be a finite positive number (k3 > 0 in Theorem 1), got {name}={val!r}")
    kk = np.asarray(morse_k, dtype=float)
    if kk.shape != (3,) or not np.all(np.isfinite(kk)) or not (kk[0] > kk[1] > kk[2] >= 1.0):
        raise ValueError(f"Morse gains K = diag(K1, K2, K3) must satisfy K1 > K2 > K3 >= 1 (Lemma 5, eq. 41), "
                         f"got K={np.asarray(morse_k).tolist()}")


@register_observer("ffts_eso")
class FFTSESO(Observer):
    """FFTS-ESO on TSE(3) (Wang et al. (2024) Props. 1-2); estimates phi_D (world NED) and tau_D (body FRD).

    ``max_dt`` = 1 / max(k_t1 k_t3 + kappa_t, k_a1 k_a3 + kappa_a (tr K - min K)): far from e = 0 the output
    injections are linear (phi1(e) ~ k3 e, eq. 9) with these rates, and explicit Euler needs rate dt < 2
    (near e = 0 the floor of :func:`~fawtgym.observers.hc_ffts.euler_stable_eps` keeps the step stable);
    53 ms at the paper's gains.
    """

    required_keys = _KEYS

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665, *, p: float = 1.2,
                 kt1: float = 3.0, kt2: float = 2.0, kt3: float = 6.0, kappa_t: float = 0.8,
                 ka1: float = 3.0, ka2: float = 2.0, ka3: float = 4.0, kappa_a: float = 0.6,
                 morse_k: Sequence[float] = (1.2, 1.1, 1.0), eps: float = DEFAULT_EPS) -> None:
        super().__init__(mass, inertia, gravity)
        validate_gains(p, kt1, kt2, kt3, kappa_t, ka1, ka2, ka3, kappa_a, morse_k)
        if not (np.isfinite(eps) and eps > 0):
            raise ValueError(f"eps must be a small positive number, got {eps!r}")
        self.p, self.kappa_t, self.kappa_a = float(p), float(kappa_t), float(kappa_a)
        self.kt1, self.kt2, self.kt3 = float(kt1), float(kt2), float(kt3)
        self.ka1, self.ka2, self.ka3 = float(ka1), float(ka2), float(ka3)
        self.morse_k = np.asarray(morse_k, dtype=float)
        self.eps = float(eps)
        self._state: dict[str, NDArray[np.float64]] | None = None
        # constants of eq. (9) and of the fractional power (1-p)/p, (p-1)/p
        self._a = (1.0 - p) / (3.0 * p - 2.0)
        self._c1t = 2.0 * kt3 * (2.0 * p - 1.0) / (3.0 * p - 2.0)
        self._c1a = 2.0 * ka3 * (2.0 * p - 1.0) / (3.0 * p - 2.0)
        self._c2 = p / (3.0 * p - 2.0)
        self._c = (1.0 - p) / p
        self._k = (p - 1.0) / p
        self._ge3 = self.gravity * _E3
        # stiffest-mode gains of the two halves (euler_stable_eps): e_v' ~ -kappa_t g' e_v, and
        # e_Omega' ~ -kappa_a g' (tr(K) I - K) e_Omega at E = I (eq. 66)
        self._stiff_t = self.kappa_t
        self._stiff_a = self.kappa_a * float(self.morse_k.sum() - self.morse_k.min())
        self._eps_cache: tuple[float, float, float] = (math.nan, self.eps, self.eps)
        # far from e = 0 the injections are linear (phi1 ~ k3 e), with rates up to k1 k3 + kappa (the kappa e_v
        # term) on each half; explicit Euler needs rate dt < 2, max_dt = 1 / rate keeps a margin of 2
        self.max_dt = 1.0 / max(self.kt1 * self.kt3 + self._stiff_t, self.ka1 * self.ka3 + self._stiff_a)

    def eps_at(self, dt: float) -> tuple[float, float]:
        """(eps_t, eps_a): the floors of the translational and rotational fractional terms at step ``dt``
        (:func:`fawtgym.observers.hc_ffts.euler_stable_eps`; ``eps`` wherever that is already stable)."""
        if dt != self._eps_cache[0]:
            self._eps_cache = (dt, euler_stable_eps(self.p, self._stiff_t, dt, self.eps),
                               euler_stable_eps(self.p, self._stiff_a, dt, self.eps))
        return self._eps_cache[1], self._eps_cache[2]

    # ---- interface -------------------------------------------------------------------------
    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None) -> int:
        """b_hat, v_hat, R_hat, Omega_hat := measured values; phi_hat, tau_hat := given guesses (default 0).

        State: the dict ``_state`` of (N, 3) / (N, 3, 3) arrays."""
        m = require(measurement, _KEYS, "ffts_eso")
        n = m["position"].shape[0]
        fresh = {
            "b": m["position"].copy(), "v": m["velocity"].copy(), "phi": batch_vec(force, n, "force", "ffts_eso"),
            "R": project_so3(m["attitude"]), "w": m["angular_velocity"].copy(),
            "tau": batch_vec(torque, n, "torque", "ffts_eso"),
        }
        self._state = write_rows(self._state, fresh, rows)
        return n

    def _update(self, m: dict[str, NDArray[np.float64]], f: NDArray[np.float64], tau: NDArray[np.float64],
                dt: float) -> tuple[ObserverEstimate, dict[str, NDArray[np.float64]]]:
        s = self._state
        new = self._advance(s, self._rhs(s, m, f, tau, *self.eps_at(dt)), dt)
        return self._estimate_of(new), new

    def estimate(self) -> ObserverEstimate:
        if self._state is None:
            raise RuntimeError("ffts_eso: call reset(measurement) first")
        return self._estimate_of(self._state)

    def _estimate_of(self, s: dict[str, NDArray[np.float64]]) -> ObserverEstimate:
        return ObserverEstimate(force=s["phi"].copy(), torque=s["tau"].copy(), states={
            "position": s["b"].copy(), "velocity": s["v"].copy(), "attitude": s["R"].copy(),
            "angular_velocity": s["w"].copy()})

    # ---- internals ---------------------------------------------------------------------------
    @staticmethod
    def _advance(s: dict[str, NDArray[np.float64]], d: dict[str, NDArray[np.float64]], dt: float
                 ) -> dict[str, NDArray[np.float64]]:
        """One step with the derivatives held: the kinematic chains b' = v_hat, R' = R Omega_hat^ are integrated
        exactly for a held v_hat', Omega_hat' (b += dt v + dt^2/2 v', R <- R exp(dt w + dt^2/2 w')).

        Plain Euler on b would lag the sampled position by dt^2/2 b'' per step, which the fractional
        injection (|e_b|^(-1/3) near 0) turns into a force bias of ~0.1 N at 1 kHz.
        """
        h2 = 0.5 * dt * dt
        return {"b": s["b"] + dt * s["v"] + h2 * d["v"], "v": s["v"] + dt * d["v"], "phi": s["phi"] + dt * d["phi"],
                "R": integrate_rotation(s["R"], s["w"] + (0.5 * dt) * d["w"], dt), "w": s["w"] + dt * d["w"],
                "tau": s["tau"] + dt * d["tau"]}

    def _rhs(self, s: dict[str, NDArray[np.float64]], m: dict[str, NDArray[np.float64]],
             f: NDArray[np.float64], tau: NDArray[np.float64], eps: float | None = None,
             eps_a: float | None = None) -> dict[str, NDArray[np.float64]]:
        """Time derivatives of (b, v, phi, tau, w) and the body rate of R_hat (key "R").

        Fused forms of phi1/phi2 (eq. 9) and of the regularised fractional power g(e) = max(e^T e, eps)^c e,
        c = (1-p)/p, and its exact derivative (eqs. 49/68); equal to the hc_ffts functions (tested).
        ``eps`` / ``eps_a``: the translational / rotational floors (default ``self.eps``; :meth:`update` passes
        :meth:`eps_at` of its dt).
        """
        mass, c = self.mass, self._c
        eps = self.eps if eps is None else eps
        eps_a = self.eps if eps_a is None else eps_a
        # translational, eqs. (45), (49), (50)
        e_b = m["position"] - s["b"]
        e_v = m["velocity"] - s["v"]
        r2 = (e_b * e_b) @ _ONES
        rb = np.maximum(r2, eps)
        pw = rb**c
        inside = r2 > eps
        psi_t = e_v + self.kappa_t * (e_b + pw * e_b)
        rate_b = pw * (e_v - (2.0 * self._k * (e_b * e_v) @ _ONES * inside / rb) * e_b)
        pa = np.maximum((psi_t * psi_t) @ _ONES, _TINY) ** self._a
        rm = m["attitude"]
        v_dot = (self._ge3 - (f / mass)[:, None] * rm[:, :, 2] + (self.kt1 * (self.kt3 + pa)) * psi_t
                 + self.kappa_t * (rate_b + e_v) + s["phi"] / mass)
        phi_dot = (mass * self.kt2) * (self.kt3 * self.kt3 + self._c1t * pa + self._c2 * pa * pa) * psi_t
        # rotational, eqs. (46), (47), (66), (68), (69)
        om = m["angular_velocity"]
        e_mat = np.swapaxes(s["R"], -1, -2) @ rm
        kv = self.morse_k
        e_r = e_mat[:, _VA, _VB] * kv[_VA] - e_mat[:, _VB, _VA] * kv[_VB]      # s_K(E_R) = vee(K E - E^T K)
        e_om = om - (s["w"][:, None, :] @ e_mat)[:, 0]                           # Omega^m - E^T Omega_hat
        tr = e_mat[:, 0, 0] * kv[0] + e_mat[:, 1, 1] * kv[1] + e_mat[:, 2, 2] * kv[2]
        e_w = tr[:, None] * e_om - ((kv * e_om)[:, None, :] @ e_mat)[:, 0]      # eq. (66)
        r2a = (e_r * e_r) @ _ONES
        ra = np.maximum(r2a, eps_a)
        pwa = ra**c
        psi_a = e_om + self.kappa_a * (e_r + pwa * e_r)
        rate_r = pwa * (e_w - (2.0 * self._k * (e_r * e_w) @ _ONES * (r2a > eps_a) / ra) * e_r)
        qa = np.maximum((psi_a * psi_a) @ _ONES, _TINY) ** self._a
        body = ((cross(om @ self.inertia.T, om) + s["tau"] + tau) @ self.inertia_inv.T
                + (self.ka1 * (self.ka3 + qa)) * psi_a + self.kappa_a * (rate_r + e_w))
        w_dot = (e_mat @ body[:, :, None])[:, :, 0] + cross((e_mat @ e_om[:, :, None])[:, :, 0], s["w"])
        tau_dot = (self.ka2 * (self.ka3 * self.ka3 + self._c1a * qa + self._c2 * qa * qa) * psi_a) @ self.inertia.T
        return {"b": s["v"], "v": v_dot, "phi": phi_dot, "R": s["w"], "w": w_dot, "tau": tau_dot}
