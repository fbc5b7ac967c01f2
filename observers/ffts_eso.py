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
:func:`fawtgym.core.so3_kernels.exp_so3_row`, so R_hat stays on SO(3)).  The whole step is one compiled kernel
over rows, :func:`ffts_eso_step` (the same code at N = 1 and N = 1024).  The time derivative of
the fractional power (the H-terms) is unbounded at e = 0, so the fractional power is regularised as
g(e) = max(e^T e, eps)^((1-p)/p) e (exact for |e| > sqrt(eps), linear inside) and its *exact* derivative
is used (:func:`fawtgym.observers.hc_ffts.frac_power_row`, batch forms ``frac_power`` / ``frac_power_rate``), so the
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
from typing import Any

import numpy as np
from numba import float64, int64, njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import check_number, check_positive, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.kernel_types import ROTATIONS, ROWS, TYPED_DISPATCH, VALUES, compile_only
from fawtgym.core.rows import write_rows
from fawtgym.core.so3 import project_so3
from fawtgym.core.so3_kernels import (
    cross_row,
    exp_so3_apply,
    exp_so3_coefficients,
    mat_mul_row,
    mat_t_vec_row,
    mat_vec_row,
    rotation_defect_row,
)
from fawtgym.observers._checks import (
    ROTATION_TOL,
)
from fawtgym.observers._obs_common import MAX_RATE_GAIN, batch_vec, real_vector
from fawtgym.observers.base import (
    BufferStates,
    Observer,
    ObserverEstimate,
    fast_inputs,
    input_shapes,
    register_observer,
)
from fawtgym.observers.hc_ffts import (
    DEFAULT_EPS,
    check_p,
    dot_row,
    euler_stable_eps,
    frac_power_power,
    frac_power_row,
    phi_power,
    phi_row,
)

_KEYS = ("position", "velocity", "attitude", "angular_velocity")
#: the largest floor eps of e^T e accepted [m^2 or rad^2 scale]: the regularised g(e) is linear inside |e| <
#: sqrt(eps) (:mod:`fawtgym.observers.hc_ffts`), so eps = 1 already makes the law linear for errors below 1 m
MAX_EPS = 1.0
#: the gains array the kernel reads, in this order
GAIN_NAMES = ("mass", "gravity", "p", "kt1", "kt2", "kt3", "kappa_t", "ka1", "ka2", "ka3", "kappa_a", "K1", "K2", "K3",
              "J (9, row-major)", "J^-1 (9, row-major)")
#: columns of the state (N, 24): b_hat, v_hat, phi_hat, Omega_hat, tau_hat, R_hat (row-major 9)
B, V, PHI, W, TAU, R = 0, 3, 6, 9, 12, 15
N_STATE = 24
#: columns of the estimate buffer (N, 24): force, torque, position, velocity, angular_velocity, attitude (9)
E_FORCE, E_TORQUE, E_POS, E_VEL, E_W, E_ATT = 0, 3, 6, 9, 12, 15


@njit(cache=True, inline="always")
def s_k_row(e: NDArray[np.float64], k: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """out = s_K(E) = sum_i K_i (E^T e_i) x e_i (eq. 41) = vee(K E - E^T K), K = diag(k)."""
    out[0] = k[2] * e[2, 1] - k[1] * e[1, 2]
    out[1] = k[0] * e[0, 2] - k[2] * e[2, 0]
    out[2] = k[1] * e[1, 0] - k[0] * e[0, 1]


@njit(cache=True, inline="always")
def s_k_rate_row(e: NDArray[np.float64], w: NDArray[np.float64], k: NDArray[np.float64],
                 out: NDArray[np.float64]) -> None:
    """out = d/dt s_K(E) along E' = E w^: sum_i K_i e_i x (w x E^T e_i) (eq. 66) = tr(K E) w - E^T K w."""
    trace_ke = k[0] * e[0, 0] + k[1] * e[1, 1] + k[2] * e[2, 2]
    for j in range(3):
        out[j] = trace_ke * w[j] - (e[0, j] * k[0] * w[0] + e[1, j] * k[1] * w[1] + e[2, j] * k[2] * w[2])


@njit(cache=True)
def _s_k_rows(r: NDArray[np.float64], w: NDArray[np.float64], k: NDArray[np.float64], rate: bool,
              out: NDArray[np.float64]) -> None:
    for i in range(r.shape[0]):
        if rate:
            s_k_rate_row(r[i], w[i], k, out[i])
        else:
            s_k_row(r[i], k, out[i])


def s_k(r: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """s_K(R) = sum_i K_i (R^T e_i) x e_i (eq. 41) = vee(K R - R^T K); R (..., 3, 3), K the 3 diagonal entries."""
    r = np.asarray(r, dtype=float)
    rows = np.ascontiguousarray(r.reshape(-1, 3, 3))
    out = np.empty((rows.shape[0], 3))
    _s_k_rows(rows, out, np.asarray(k, dtype=float), False, out)
    return out.reshape(r.shape[:-2] + (3,))


def s_k_rate(r: ArrayLike, omega: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """d/dt s_K(E) for E' = E omega^: sum_i K_i e_i x (omega x E^T e_i) (eq. 66) = tr(K E) w - E^T K w."""
    r, w = np.asarray(r, dtype=float), np.asarray(omega, dtype=float)
    shape = np.broadcast_shapes(r.shape[:-2], w.shape[:-1])
    rows = np.ascontiguousarray(np.broadcast_to(r, shape + (3, 3)).reshape(-1, 3, 3))
    ws = np.ascontiguousarray(np.broadcast_to(w, shape + (3,)).reshape(-1, 3))
    out = np.empty_like(ws)
    _s_k_rows(rows, ws, np.asarray(k, dtype=float), True, out)
    return out.reshape(shape + (3,))


def morse(r: ArrayLike, k: ArrayLike) -> NDArray[np.float64]:
    """<K, I - R> = tr(K (I - R)), the Morse function of Lemma 5."""
    r = np.asarray(r, dtype=float)
    kv = np.asarray(k, dtype=float)
    return np.sum(kv) - np.einsum("i,...ii->...", kv, r)


def validate_gains(p: float, kt1: float, kt2: float, kt3: float, kappa_t: float, ka1: float, ka2: float,
                   ka3: float, kappa_a: float, morse_k: Sequence[float]) -> tuple[float, ...]:
    """Check the conditions of Theorem 1 and Propositions 1-2 / Lemma 5; ValueError explains which fails.

    Every gain a real, finite number at most :data:`~fawtgym.observers._obs_common.MAX_RATE_GAIN` (bool, complex,
    str refused; the max_dt of :class:`FFTSESO` is 1 / (k1 k3 + ...)); A_t / A_a = [[-k1, 1], [-k2, 0]] (eqs. 48, 67)
    are Hurwitz iff k1 > 0 and k2 > 0.  Returns (p, kt1, kt2, kt3, kappa_t, ka1, ka2, ka3, kappa_a) as floats."""
    p = check_p(p)
    out = [p]
    for half, eq, k1, k2, k3, kappa in (("t", 48, kt1, kt2, kt3, kappa_t), ("a", 67, ka1, ka2, ka3, kappa_a)):
        hurwitz = f"(A_{half} = [[-k{half}1, 1], [-k{half}2, 0]] of eq. {eq} is Hurwitz iff k{half}1, k{half}2 > 0)"
        out.append(check_positive(k1, f"ffts_eso: gain k{half}1", maximum=MAX_RATE_GAIN, note=hurwitz))
        out.append(check_positive(k2, f"ffts_eso: gain k{half}2", maximum=MAX_RATE_GAIN, note=hurwitz))
        out.append(check_positive(k3, f"ffts_eso: gain k{half}3", maximum=MAX_RATE_GAIN, note="(k3 > 0 in Theorem 1)"))
        out.append(check_number(kappa, f"ffts_eso: gain kappa_{half}", minimum=0.5, maximum=MAX_RATE_GAIN,
                                note=f"(kappa > 1/2, Wang et al. (2024) eq. {50 if half == 't' else 69})"))
    kk = real_vector(morse_k, 3)
    if kk is None or not (kk[0] > kk[1] > kk[2] >= 1.0) or not kk[0] <= MAX_RATE_GAIN:
        raise ValueError(f"ffts_eso: Morse gains morse_k = (K1, K2, K3) must be 3 finite real numbers with "
                         f"{MAX_RATE_GAIN:g} >= K1 > K2 > K3 >= 1 (Lemma 5, eq. 41), got {shown(morse_k)}")
    return tuple(out)


@register_observer("ffts_eso")
class FFTSESO(Observer):
    """FFTS-ESO on TSE(3) (Wang et al. (2024) Props. 1-2); estimates phi_D (world NED) and tau_D (body FRD).

    ``max_dt`` = 1 / max(k_t1 k_t3 + kappa_t, k_a1 k_a3 + kappa_a (tr K - min K)): far from e = 0 the output
    injections are linear (phi1(e) ~ k3 e, eq. 9) with these rates, and explicit Euler needs rate dt < 2
    (near e = 0 the floor of :func:`~fawtgym.observers.hc_ffts.euler_stable_eps` keeps the step stable);
    53 ms at the paper's gains.
    """

    required_keys = _KEYS

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = GRAVITY, *, p: float = 1.2,
                 kt1: float = 3.0, kt2: float = 2.0, kt3: float = 6.0, kappa_t: float = 0.8,
                 ka1: float = 3.0, ka2: float = 2.0, ka3: float = 4.0, kappa_a: float = 0.6,
                 morse_k: Sequence[float] = (1.2, 1.1, 1.0), eps: float = DEFAULT_EPS) -> None:
        super().__init__(mass, inertia, gravity)
        (self.p, self.kt1, self.kt2, self.kt3, self.kappa_t, self.ka1, self.ka2, self.ka3,
         self.kappa_a) = validate_gains(p, kt1, kt2, kt3, kappa_t, ka1, ka2, ka3, kappa_a, morse_k)
        self.eps = check_positive(eps, "ffts_eso: eps", maximum=MAX_EPS, note="(the floor of e^T e, eq. 50)")
        self.morse_k = np.asarray(morse_k, dtype=float)
        p, kt1, kt2, kt3, kappa_t = self.p, self.kt1, self.kt2, self.kt3, self.kappa_t
        ka1, ka2, ka3, kappa_a = self.ka1, self.ka2, self.ka3, self.kappa_a
        self._state: NDArray[np.float64] = np.empty((0, 0))      # (N, k) after reset
        self._gains = np.array([self.mass, self.gravity, p, kt1, kt2, kt3, kappa_t, ka1, ka2, ka3, kappa_a,
                                *self.morse_k, *self.inertia.ravel(), *self.inertia_inv.ravel()], dtype=float)
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
    def _reset(self, measurement: Mapping[str, NDArray[np.float64]], force: ArrayLike | None,
               torque: ArrayLike | None, rows: NDArray[np.bool_] | None) -> int:
        """b_hat, v_hat, R_hat, Omega_hat := measured values; phi_hat, tau_hat := given guesses (default 0).

        State: ``_state`` (N, 24), columns b_hat, v_hat, phi_hat, Omega_hat, tau_hat, R_hat (row-major)."""
        m = measurement        # checked by Observer.reset (required_keys)
        n = m["position"].shape[0]
        fresh = np.concatenate([m["position"], m["velocity"], batch_vec(force, n, "force", "ffts_eso"),
                                m["angular_velocity"], batch_vec(torque, n, "torque", "ffts_eso"),
                                project_so3(m["attitude"]).reshape(n, 9)], axis=1)
        self._state = write_rows(self._state, fresh, rows)
        return n

    def _update(self, m: dict[str, NDArray[np.float64]], f: NDArray[np.float64], tau: NDArray[np.float64],
                dt: float) -> tuple[ObserverEstimate, NDArray[np.float64]]:
        x = self._state
        eps_t, eps_a = self.eps_at(dt)
        out = np.empty((2, *x.shape))     # (new state, estimate): see _update_checked
        force_bound, torque_bound = self.estimate_bounds()
        # inputs checked by Observer.update; its _check_estimate words any bad estimate, so the status is not needed
        ffts_eso_step(x, m["position"], m["velocity"], m["attitude"], m["angular_velocity"], f, tau, dt, eps_t,
                      eps_a, self._gains, force_bound, torque_bound, out[0], out[1])
        return _estimate(out[1]), out[0]

    def _update_checked(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike, dt: float,
                        n: int) -> ObserverEstimate | None:
        """The checks and the law in one compiled call (:func:`ffts_eso_update`; :meth:`Observer._update_checked`).

        The new state and the estimate are the two halves of one fresh buffer (2, N, 24): no later update writes
        into either (each update makes a new buffer and a per-row reset a new state array)."""
        pos: Any
        vel: Any
        att: Any
        omega: Any
        f: Any
        tau: Any
        if TYPED_DISPATCH:    # the typed kernel refuses (TypeError) anything but C-contiguous float64 arrays
            if type(measurement) is not dict:
                return None
            if not _TYPED[0]:
                compile_only(ffts_eso_update, UPDATE_SIGNATURE)
                _TYPED[0] = True
            get = measurement.get
            pos, vel, att, omega, f, tau = (get("position"), get("velocity"), get("attitude"),
                                            get("angular_velocity"), thrust, torque)
        else:                 # plain Python kernels (NUMBA_DISABLE_JIT=1): the same types checked here
            arrays = fast_inputs(measurement, input_shapes(_KEYS, n), thrust, torque, n)
            if arrays is None:
                return None
            pos, vel, att, omega, f, tau = arrays
        x = self._state
        cache = self._eps_cache
        eps_t, eps_a = (cache[1], cache[2]) if dt == cache[0] else self.eps_at(dt)
        force_bound, torque_bound = self.estimate_bounds()
        out = np.empty((2, n, N_STATE))
        try:
            code = ffts_eso_update(x, pos, vel, att, omega, f, tau, dt, eps_t, eps_a, self._gains, force_bound,
                                   torque_bound, out)
        except TypeError:     # an input of another type, layout or ndim
            return None
        if code != CHECKS_PASSED:
            return None
        self._state = out[0]
        return _estimate(out[1])

    def estimate(self) -> ObserverEstimate:
        if self._n_rows is None:
            raise RuntimeError("ffts_eso: estimate() before reset(); call reset(measurement) first")
        est = np.empty_like(self._state)
        ffts_eso_estimate(self._state, est)
        return _estimate(est)


#: whether :func:`ffts_eso_update` was compiled for :data:`UPDATE_SIGNATURE` only (on the first checked update)
_TYPED = [False]
#: the estimate's states: columns of the estimate buffer and trailing shapes
_STATES = {"position": (E_POS, E_POS + 3, (3,)), "velocity": (E_VEL, E_VEL + 3, (3,)),
           "attitude": (E_ATT, E_ATT + 9, (3, 3)), "angular_velocity": (E_W, E_W + 3, (3,))}


#: the force and torque columns of the estimate buffer (index tuples made once: a slice per call costs ~60 ns more)
_FORCE_COLUMNS = (slice(None), slice(E_FORCE, E_FORCE + 3))
_TORQUE_COLUMNS = (slice(None), slice(E_TORQUE, E_TORQUE + 3))


def _estimate(est: NDArray[np.float64]) -> ObserverEstimate:
    """The estimate from the kernel's buffer (N, 24) (views of a fresh buffer, not of the state)."""
    return ObserverEstimate(est[_FORCE_COLUMNS], est[_TORQUE_COLUMNS], BufferStates(est, _STATES))


@njit(cache=True, inline="always")
def _estimate_row(x: NDArray[np.float64], est: NDArray[np.float64], i: int) -> None:
    """The estimate of state row ``i``: phi_hat, tau_hat, b_hat, v_hat, Omega_hat, R_hat (indexed, not through row
    views: a view made per row costs an atomic reference count in the row loop)."""
    for j in range(3):
        est[i, E_FORCE + j] = x[i, PHI + j]
        est[i, E_TORQUE + j] = x[i, TAU + j]
        est[i, E_POS + j] = x[i, B + j]
        est[i, E_VEL + j] = x[i, V + j]
        est[i, E_W + j] = x[i, W + j]
    for j in range(9):
        est[i, E_ATT + j] = x[i, R + j]


@njit(cache=True)
def ffts_eso_estimate(x: NDArray[np.float64], est: NDArray[np.float64]) -> None:
    """:func:`_estimate_row` of every row of the state ``x`` (N, 24) into ``est`` (N, 24)."""
    for i in range(x.shape[0]):
        _estimate_row(x, est, i)


#: :func:`ffts_eso_step` / :func:`ffts_eso_update` status codes
CHECKS_PASSED, BAD_INPUT, BAD_ESTIMATE = 0, 1, 2
#: columns of the per-call work buffer of :func:`ffts_eso_step` (N, N_WORK): e_b, e_v, e_Omega, e_R, e_w, E (9),
#: psi_t, psi_a, g'(e_b), g'(e_R), then the four fractional powers (each first holding its base, e^T e), ...
WK_EB, WK_EV, WK_EOM, WK_ER, WK_EW, WK_E, WK_PSI_T, WK_PSI_A, WK_RATE_B, WK_RATE_R = 0, 3, 6, 9, 12, 15, 24, 27, 30, 33
WK_POW_T, WK_POW_A, WK_Q_T, WK_Q_A = 36, 37, 38, 39
#: ... and the step rotation's vector dt (Omega_hat + dt/2 Omega_hat'), its |.|^2 and Rodrigues' coefficients
WK_STEP, WK_EXP_T2, WK_EXP_A, WK_EXP_B = 40, 43, 44, 45
N_WORK = 46


@njit(cache=True, inline="always")
def _put(work: NDArray[np.float64], i: int, col: int, v: NDArray[np.float64]) -> None:
    for j in range(v.shape[0]):
        work[i, col + j] = v[j]


@njit(cache=True, inline="always")
def _get(work: NDArray[np.float64], i: int, col: int, v: NDArray[np.float64]) -> None:
    for j in range(v.shape[0]):
        v[j] = work[i, col + j]


@njit(cache=True)
def ffts_eso_step(x: NDArray[np.float64], pos: NDArray[np.float64], vel: NDArray[np.float64],
                  att: NDArray[np.float64], omega: NDArray[np.float64], thrust: NDArray[np.float64],
                  torque: NDArray[np.float64], dt: float, eps_t: float, eps_a: float, gains: NDArray[np.float64],
                  force_bound: float, torque_bound: float, x_new: NDArray[np.float64], est: NDArray[np.float64]) -> int:
    """One FFTS-ESO step of every row: state ``x`` (N, 24) -> ``x_new``, estimate into ``est`` (N, 24).

    Measurement b^m (N, 3), v^m (N, 3), R^m (N, 3, 3), Omega^m (N, 3), applied thrust (N,) and torque (N, 3)
    held over ``dt``; ``eps_t`` / ``eps_a`` the floors of the two fractional terms at this dt; ``gains`` as
    :data:`GAIN_NAMES`.  Equations as in the module docstring (Wang et al. (2024) eqs. 45-50, 66-69).

    Row checks on the way (the compiled checks of :meth:`Observer.update`, in the rows' loops rather than passes of
    their own): returns ``BAD_INPUT`` as soon as a row's measurement or inputs are not finite or its attitude is not
    a rotation (:data:`~fawtgym.observers._checks.ROTATION_TOL`; nothing written to ``x_new`` / ``est`` then),
    ``BAD_ESTIMATE`` if an estimate row is not finite or its force / torque exceeds ``force_bound`` /
    ``torque_bound`` (NaN fails), else ``CHECKS_PASSED``.  The caller words the error.

    The row law runs in stages, each a loop over the rows: the errors, the fractional powers of g, psi, the powers
    of phi1/phi2, the update, Rodrigues' coefficients of R_hat's step, R_hat's step.  A power (``**``) costs ~26 ns
    of latency but ~11 ns of throughput (sin / cos alike): in a loop of their own the rows' powers overlap, inside
    one long row they wait for each other.  The loops read and write
    the (N, k) arrays by index and keep a row's intermediates in scratch vectors made once per call: an array view
    made inside a loop (``x[i]``, a slice) costs an atomic reference-count increment and decrement per row.
    """
    mass, g, p = gains[0], gains[1], gains[2]
    kt1, kt2, kt3, kappa_t = gains[3], gains[4], gains[5], gains[6]
    ka1, ka2, ka3, kappa_a = gains[7], gains[8], gains[9], gains[10]
    morse_k = gains[11:14]
    # J and J^-1 copied into a (2, 3, 3) array (a view made by reshape carries a reference count numba cannot pair
    # up with its parent's: every inlined helper called with one would cost an atomic increment/decrement per row)
    inertias = np.empty((2, 3, 3))
    for j in range(3):
        for k in range(3):
            inertias[0, j, k] = gains[14 + 3 * j + k]
            inertias[1, j, k] = gains[23 + 3 * j + k]
    inertia, inertia_inv = inertias[0], inertias[1]
    half_dt2 = 0.5 * dt * dt
    n = x.shape[0]
    work = np.empty((n, N_WORK))                                            # the rows' results between stages
    vec = np.empty((20, 3))                                                 # the row's 3-vector intermediates
    e_b, e_v, psi_t, g_b, rate_b, inj1, inj2 = vec[0], vec[1], vec[2], vec[3], vec[4], vec[5], vec[6]
    e_r, e_om, e_w, psi_a, g_r, rate_r = vec[7], vec[8], vec[9], vec[10], vec[11], vec[12]
    jw, gyro, body, t1, t2 = vec[13], vec[14], vec[15], vec[16], vec[17]
    w_hat, om = vec[18], vec[19]                                            # Omega_hat, Omega^m of the row
    mats = np.empty((5, 3, 3))
    e_mat, r_hat, step_rot, r_new, r_m = mats[0], mats[1], mats[2], mats[3], mats[4]
    # ---- 1. the row's inputs checked; errors: translational eq. (45), rotational eqs. (46)-(47), (41), (66)
    for i in range(n):
        finite = math.isfinite(thrust[i])
        for j in range(3):
            finite = (finite and math.isfinite(pos[i, j]) and math.isfinite(vel[i, j]) and math.isfinite(omega[i, j])
                      and math.isfinite(torque[i, j]))
            for k in range(3):
                r_m[j, k] = att[i, j, k]
        if not finite or rotation_defect_row(r_m) > ROTATION_TOL:
            return BAD_INPUT
        for j in range(3):
            w_hat[j] = x[i, W + j]
            e_b[j] = pos[i, j] - x[i, B + j]                                # e_b = b^m - b_hat
            e_v[j] = vel[i, j] - x[i, V + j]                                # e_v = v^m - v_hat
        for j in range(3):
            for k in range(3):                                              # E = R_hat^T R^m
                e_mat[j, k] = x[i, R + j] * r_m[0, k] + x[i, R + 3 + j] * r_m[1, k] + x[i, R + 6 + j] * r_m[2, k]
        mat_t_vec_row(e_mat, w_hat, t1)                                     # E^T Omega_hat
        for j in range(3):
            e_om[j] = omega[i, j] - t1[j]                                   # e_Omega, eq. (47)
        s_k_row(e_mat, morse_k, e_r)                                        # e_R = s_K(E), eq. (41)
        s_k_rate_row(e_mat, e_om, morse_k, e_w)                             # e_w = d/dt e_R, eq. (66)
        _put(work, i, WK_EB, e_b)
        _put(work, i, WK_EV, e_v)
        _put(work, i, WK_EOM, e_om)
        _put(work, i, WK_ER, e_r)
        _put(work, i, WK_EW, e_w)
        for j in range(3):
            for k in range(3):
                work[i, WK_E + 3 * j + k] = e_mat[j, k]
        work[i, WK_POW_T] = dot_row(e_b, e_b)
        work[i, WK_POW_A] = dot_row(e_r, e_r)
    # ---- 2. the fractional powers of g (eqs. 50/69)
    for i in range(n):
        work[i, WK_POW_T] = frac_power_power(work[i, WK_POW_T], p, eps_t)
        work[i, WK_POW_A] = frac_power_power(work[i, WK_POW_A], p, eps_a)
    # ---- 3. psi_t, psi_a (eqs. 50, 69) with g and its rate (the H-terms of eqs. 49, 68)
    for i in range(n):
        _get(work, i, WK_EB, e_b)
        _get(work, i, WK_EV, e_v)
        _get(work, i, WK_EOM, e_om)
        _get(work, i, WK_ER, e_r)
        _get(work, i, WK_EW, e_w)
        frac_power_row(e_b, e_v, p, eps_t, work[i, WK_POW_T], g_b, rate_b)  # |e_b|^(2(1-p)/p) e_b (regularised)
        frac_power_row(e_r, e_w, p, eps_a, work[i, WK_POW_A], g_r, rate_r)
        for j in range(3):
            psi_t[j] = e_v[j] + kappa_t * (e_b[j] + g_b[j])                 # psi_t, eq. (50)
            psi_a[j] = e_om[j] + kappa_a * (e_r[j] + g_r[j])                # psi_a, eq. (69)
        _put(work, i, WK_PSI_T, psi_t)
        _put(work, i, WK_PSI_A, psi_a)
        _put(work, i, WK_RATE_B, rate_b)
        _put(work, i, WK_RATE_R, rate_r)
        work[i, WK_Q_T] = dot_row(psi_t, psi_t)
        work[i, WK_Q_A] = dot_row(psi_a, psi_a)
    # ---- 4. the fractional powers of phi1, phi2 (eq. 9)
    for i in range(n):
        work[i, WK_Q_T] = phi_power(work[i, WK_Q_T], p)
        work[i, WK_Q_A] = phi_power(work[i, WK_Q_A], p)
    # ---- 5. the update (R_hat's step rotation in stages 6-7)
    for i in range(n):
        for j in range(3):
            w_hat[j] = x[i, W + j]
            om[j] = omega[i, j]
        _get(work, i, WK_EV, e_v)
        _get(work, i, WK_PSI_T, psi_t)
        _get(work, i, WK_RATE_B, rate_b)
        # translational ESO, eqs. (48)-(49)
        phi_row(psi_t, kt3, p, work[i, WK_Q_T], inj1, inj2)                 # phi1, phi2 of eq. (9)
        f_over_m = thrust[i] / mass
        for j in range(3):
            # v_hat' = g e3 - (f/m) R^m e3 + k_t1 phi1(psi_t) + kappa_t (g'(e_b) + e_v) + phi_hat / m, eq. (49)
            v_dot = ((g if j == 2 else 0.0) - f_over_m * att[i, j, 2] + kt1 * inj1[j]
                     + kappa_t * (rate_b[j] + e_v[j]) + x[i, PHI + j] / mass)
            x_new[i, B + j] = x[i, B + j] + dt * x[i, V + j] + half_dt2 * v_dot  # b' = v_hat, exact for held v_hat'
            x_new[i, V + j] = x[i, V + j] + dt * v_dot
            x_new[i, PHI + j] = x[i, PHI + j] + dt * (mass * kt2 * inj2[j])  # phi_hat' = m k_t2 phi2(psi_t)
        # rotational ESO, eqs. (66)-(68)
        _get(work, i, WK_EOM, e_om)
        _get(work, i, WK_EW, e_w)
        _get(work, i, WK_PSI_A, psi_a)
        _get(work, i, WK_RATE_R, rate_r)
        for j in range(3):
            for k in range(3):
                e_mat[j, k] = work[i, WK_E + 3 * j + k]
        phi_row(psi_a, ka3, p, work[i, WK_Q_A], inj1, inj2)
        mat_vec_row(inertia, om, jw)
        cross_row(jw, om, gyro)                                             # J Om^m x Om^m
        for j in range(3):
            t1[j] = gyro[j] + x[i, TAU + j] + torque[i, j]
        mat_vec_row(inertia_inv, t1, t2)                                    # J^-1 (J Om x Om + tau_hat + tau)
        for j in range(3):
            body[j] = t2[j] + ka1 * inj1[j] + kappa_a * (rate_r[j] + e_w[j])
        mat_vec_row(e_mat, body, t1)                                        # E [ ... ], eq. (68)
        mat_vec_row(e_mat, e_om, t2)                                        # E e_Omega
        cross_row(t2, w_hat, jw)                                            # E e_Om^ E^T Om_hat = (E e_Om) x Om_hat
        for j in range(3):
            t2[j] = ka2 * inj2[j]
        mat_vec_row(inertia, t2, gyro)                                      # tau_hat' = J k_a2 phi2(psi_a)
        for j in range(3):
            w_dot = t1[j] + jw[j]
            # R_hat' = R_hat Omega_hat^: exact for the held Omega_hat' (exponential map over the step)
            t2[j] = dt * (w_hat[j] + 0.5 * dt * w_dot)
            x_new[i, W + j] = w_hat[j] + dt * w_dot
            x_new[i, TAU + j] = x[i, TAU + j] + dt * gyro[j]
        _put(work, i, WK_STEP, t2)
        work[i, WK_EXP_T2] = dot_row(t2, t2)
    # ---- 6. Rodrigues' coefficients of the step's rotation
    for i in range(n):
        work[i, WK_EXP_A], work[i, WK_EXP_B] = exp_so3_coefficients(work[i, WK_EXP_T2])
    # ---- 7. R_hat <- R_hat exp(step^), the estimate checked
    status = CHECKS_PASSED
    for i in range(n):
        _get(work, i, WK_STEP, t2)
        exp_so3_apply(t2, work[i, WK_EXP_T2], work[i, WK_EXP_A], work[i, WK_EXP_B], step_rot)
        for j in range(3):
            for k in range(3):
                r_hat[j, k] = x[i, R + 3 * j + k]
        mat_mul_row(r_hat, step_rot, r_new)
        for j in range(3):
            for k in range(3):
                x_new[i, R + 3 * j + k] = r_new[j, k]
        _estimate_row(x_new, est, i)
        for j in range(3):  # NaN fails the comparisons
            if not (abs(est[i, E_FORCE + j]) <= force_bound and abs(est[i, E_TORQUE + j]) <= torque_bound):
                status = BAD_ESTIMATE
        for j in range(N_STATE):
            if not math.isfinite(est[i, j]):
                status = BAD_ESTIMATE
    return status



#: the only argument types :func:`ffts_eso_update` takes (:func:`~fawtgym.core.kernel_types.compile_only`)
UPDATE_SIGNATURE = int64(ROWS, ROWS, ROWS, ROTATIONS, ROWS, VALUES, ROWS, float64, float64, float64, VALUES, float64,
                         float64, ROTATIONS)


@njit(cache=True, nogil=True)
def ffts_eso_update(x: NDArray[np.float64], pos: NDArray[np.float64], vel: NDArray[np.float64],
                    att: NDArray[np.float64], omega: NDArray[np.float64], thrust: NDArray[np.float64],
                    torque: NDArray[np.float64], dt: float, eps_t: float, eps_a: float, gains: NDArray[np.float64],
                    force_bound: float, torque_bound: float, out: NDArray[np.float64]) -> int:
    """:meth:`Observer.update`'s checks and the law in one call: the shapes, then :func:`ffts_eso_step` into
    ``out[0]`` (new state) and ``out[1]`` (estimate), which checks in its row loops what
    :func:`~fawtgym.observers.base.check_measurement` (rows finite, the attitude a rotation),
    :func:`~fawtgym.observers.base.check_inputs` (thrust and torque finite) and
    :meth:`~fawtgym.observers.base.Observer._check_estimate` (bounded and finite) check.
    Returns ``CHECKS_PASSED``, ``BAD_INPUT`` or ``BAD_ESTIMATE``; the caller words the error.

    Compiled for C-contiguous float64 arrays only (a call with anything else raises TypeError, and the caller takes
    the Python checks); the shapes are checked here: N = the state's rows."""
    n = x.shape[0]
    if (pos.shape[0] != n or pos.shape[1] != 3 or vel.shape[0] != n or vel.shape[1] != 3 or att.shape[0] != n
            or att.shape[1] != 3 or att.shape[2] != 3 or omega.shape[0] != n or omega.shape[1] != 3
            or thrust.shape[0] != n or torque.shape[0] != n or torque.shape[1] != 3 or x.shape[1] != N_STATE
            or out.shape[0] != 2 or out.shape[1] != n or out.shape[2] != N_STATE):
        return BAD_INPUT
    return ffts_eso_step(x, pos, vel, att, omega, thrust, torque, dt, eps_t, eps_a, gains, force_bound, torque_bound,
                         out[0], out[1])
