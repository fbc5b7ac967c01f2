"""Dryden turbulence: MIL-F-8785C and MIL-HDBK-1797 shaping filters, exactly discretized, batched.

The gust velocities (u along the mean relative air flow, v lateral, w vertical) are white noise
passed through the Dryden shaping filters.  The filters are realized **in the spatial domain**
(Taylor's frozen turbulence: the field is a function of the distance ``xi`` the air has travelled
past the vehicle), with ``Omega`` the spatial frequency [rad/m] and ``s_x`` the spatial Laplace
variable [1/m].  With unit-intensity white noise ``n(xi)`` the filters are ``|H(j Omega)|^2 =
pi Phi(Omega)``, where ``Phi`` is the one-sided spatial PSD of the spec (``int_0^inf Phi dOmega =
sigma^2``):

* MIL-F-8785C (and MIL-HDBK-1797, same ``u``)::

      Phi_u = sigma_u^2 (2 L_u / pi) / (1 + (L_u Omega)^2)
      H_u   = sigma_u sqrt(2 L_u) / (1 + L_u s_x)
      Phi_v = sigma_v^2 (L_v / pi) (1 + 3 (L_v Omega)^2) / (1 + (L_v Omega)^2)^2
      H_v   = sigma_v sqrt(L_v) (1 + sqrt(3) L_v s_x) / (1 + L_v s_x)^2

* MIL-HDBK-1797 lateral/vertical (its ``L_v`` is half the 8785C one for the same field)::

      Phi_v = sigma_v^2 (2 L_v / pi) (1 + 12 (L_v Omega)^2) / (1 + 4 (L_v Omega)^2)^2
      H_v   = sigma_v sqrt(2 L_v) (1 + 2 sqrt(3) L_v s_x) / (1 + 2 L_v s_x)^2

  (``w`` as ``v`` with ``L_w``, ``sigma_w``.)

* Optional gust gradients (the "rotational" p, q, r components, MIL-F-8785C, span ``b``)::

      Phi_p = sigma_w^2 0.8 (pi / (4 b))^(1/3) L_w^(-2/3) / (1 + (4 b Omega / pi)^2)    (p = dw/dy)
      q = s_x / (1 + (4 b / pi) s_x) w          r = s_x / (1 + (3 b / pi) s_x) v        (dw/dxi, dv/dxi)

  These assume ``L >> b``; they are off by default.

Why the spatial domain: the filters then do not depend on the airspeed ``V``.  Over one time step
of length ``dt`` the air moves ``d = V dt`` and the exact discretization of ``dx/dxi = A x + B n``
is ``x+ = Ad x + e``, ``Ad = expm(A d)``, ``e ~ N(0, Qd)``, ``Qd = P - Ad P Ad^T`` with ``P`` the
stationary covariance (``A P + P A^T + B B^T = 0``, scipy's Lyapunov solver).  This is exact for
*any* ``dt``: the sampled process has the continuous model's variance and autocovariance at the
sample instants, so the realized sigma does not depend on the step (unlike the common practice of
scaling unit noise without ``sqrt(dt)``).  A changing airspeed (the frozen-turbulence speed
``V = |mean wind - vehicle velocity|``, floored at ``v_floor``) only changes ``d``; the matrices are
cached on a logarithmic grid of ``d`` (2 % bins: the step length, hence the gust time scale, is exact
to +-1 %, while the variance stays exact because ``Qd`` is built from the same ``Ad``; ``d`` is clipped
to [1e-5, 200] m; a vehicle whose airspeed wanders fills more bins, each costing one small ``expm``).

Option ``discretization="zoh"``: zero-order hold of the state space with the noise held over the
step at intensity ``1/dt`` (``scipy.signal.cont2discrete``), as many simulators do; its variance
error is ``O(d / L)``, small only for ``d << L``.  Kept for comparison; ``"exact"`` is the default.

Batch: ``N`` independent fields, each with its own random stream (``numpy.random.SeedSequence``
children), so field ``i`` is the same whatever ``N`` is.  Normals are drawn per field in blocks of
``block`` steps (one generator call per field per block) so the per-step cost stays vectorized.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

FORMS = ("8785c", "1797")
#: Lower bound of the frozen-turbulence speed [m/s].  Below ~1 m/s Taylor's hypothesis does not hold
#: and L/V would freeze the gusts of a vehicle hovering in still mean air; 1 m/s keeps the time
#: scale finite (MATLAB's Dryden block has no floor and divides by zero at V = 0).
V_FLOOR = 1.0
_BIN = 0.02  # log-bin width of the cached step length d = V dt
_D_MIN, _D_MAX = 1e-5, 200.0  # [m] range of d = V dt held in the table (clipped outside)


def _check_positive(name: str, value: float) -> float:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    return float(value)


def _check_nonneg(name: str, value: float) -> float:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and value >= 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class DrydenParams:
    """Intensities [m/s] and length scales [m] of the three gust components, in one spec form.

    ``form`` is ``"8785c"`` or ``"1797"``: the length scales are *that* form's (``L_v``, ``L_w`` of
    MIL-HDBK-1797 are half those of MIL-F-8785C for the same turbulence).  ``span`` [m] sets the
    gust-gradient filters (used only with ``rates=True``).
    """

    sigma: tuple[float, float, float]
    length: tuple[float, float, float]
    form: str = "8785c"
    span: float = 0.5

    def __post_init__(self) -> None:
        if self.form not in FORMS:
            raise ValueError(f"Dryden form must be one of {FORMS}, got {self.form!r}")
        sig = tuple(_check_nonneg(f"turbulence intensity sigma_{c}", s) for c, s in zip("uvw", self.sigma, strict=True))
        lens = tuple(_check_positive(f"length scale L_{c}", s) for c, s in zip("uvw", self.length, strict=True))
        object.__setattr__(self, "sigma", sig)
        object.__setattr__(self, "length", lens)
        object.__setattr__(self, "span", _check_positive("span", self.span))


def dryden_psd(params: DrydenParams, component: str, freq_hz: NDArray[np.float64] | float,
               airspeed: float) -> NDArray[np.float64]:
    """Analytic one-sided temporal PSD [(m/s)^2/Hz] of ``component`` in ``"uvw"`` at ``freq_hz``.

    ``G(f) = 2 pi Phi(Omega = 2 pi f / V) / V`` so that ``int_0^inf G df = sigma^2``; this is what
    ``scipy.signal.welch`` (``scaling="density"``, one-sided) estimates.
    """
    f = np.asarray(freq_hz, dtype=float)
    v = _check_positive("airspeed", airspeed)
    i = "uvw".index(component)
    sig, length = params.sigma[i], params.length[i]
    om = 2.0 * math.pi * f / v
    if component == "u":
        phi = sig**2 * 2.0 * length / math.pi / (1.0 + (length * om) ** 2)
    elif params.form == "8785c":
        x = (length * om) ** 2
        phi = sig**2 * length / math.pi * (1.0 + 3.0 * x) / (1.0 + x) ** 2
    else:
        x = (length * om) ** 2
        phi = sig**2 * 2.0 * length / math.pi * (1.0 + 12.0 * x) / (1.0 + 4.0 * x) ** 2
    return 2.0 * math.pi * phi / v


def _second_order(sig: float, gain_len: float, zero: float, pole: float) -> tuple[NDArray, NDArray, NDArray]:
    """Realization of ``sig sqrt(gain_len) (1 + zero s) / (1 + pole s)^2`` as two first-order lags in series.

    ``z1' = (n - z1) / pole``, ``z2' = (z1 - z2) / pole``, ``y = K ((1 - zero / pole) z2 + (zero / pole) z1)``:
    the entries of ``A`` are ``1 / pole`` (a companion form would have ``1 / pole^2`` and be badly scaled
    for the centimetre length scales of the FAWT).
    """
    a = np.array([[-1.0 / pole, 0.0], [1.0 / pole, -1.0 / pole]])
    b = np.array([[1.0 / pole], [0.0]])
    k = sig * math.sqrt(gain_len)
    c = np.array([[k * zero / pole, k * (1.0 - zero / pole)]])
    return a, b, c


def spatial_state_space(params: DrydenParams, rates: bool = False) -> tuple[NDArray, NDArray, NDArray]:
    """``(A, B, C)`` of the spatial-domain Dryden filters; outputs ``[u, v, w]`` (+ ``[p, dw/dxi, dv/dxi]``).

    Noise inputs are ``[n_u, n_v, n_w]`` (+ ``n_p``), each unit-intensity white in distance.
    """
    su, sv, sw = params.sigma
    lu, lv, lw = params.length
    blocks_a: list[NDArray] = []
    blocks_b: list[tuple[int, NDArray]] = []
    outs_c: list[NDArray] = []
    # u: first order
    blocks_a.append(np.array([[-1.0 / lu]]))
    blocks_b.append((0, np.array([[1.0 / lu]])))
    outs_c.append(np.array([[su * math.sqrt(2.0 * lu)]]))
    for sig, length, col in ((sv, lv, 1), (sw, lw, 2)):
        if params.form == "8785c":
            a, b, c = _second_order(sig, length, math.sqrt(3.0) * length, length)
        else:
            a, b, c = _second_order(sig, 2.0 * length, 2.0 * math.sqrt(3.0) * length, 2.0 * length)
        blocks_a.append(a)
        blocks_b.append((col, b))
        outs_c.append(c)
    n_in = 3
    if rates:
        n_in = 4
        span = params.span
        tp = 4.0 * span / math.pi
        gain_p = math.sqrt(math.pi * 0.8) * sw * (math.pi / (4.0 * span)) ** (1.0 / 6.0) * lw ** (-1.0 / 3.0)
        blocks_a.append(np.array([[-1.0 / tp]]))
        blocks_b.append((3, np.array([[1.0 / tp]])))
        outs_c.append(np.array([[gain_p]]))
    n = sum(a.shape[0] for a in blocks_a)
    big_a = scipy.linalg.block_diag(*blocks_a)
    big_b = np.zeros((n, n_in))
    n_out = 6 if rates else 3
    big_c = np.zeros((n_out, n + (2 if rates else 0)))
    idx = 0
    for k, (a, (col, b), c) in enumerate(zip(blocks_a, blocks_b, outs_c, strict=True)):
        m = a.shape[0]
        big_b[idx:idx + m, col:col + 1] = b
        out_row = k if k < 3 else 3
        big_c[out_row, idx:idx + m] = c
        idx += m
    if not rates:
        return big_a, big_b, big_c
    # gradient filters d/dxi low-passed: q = (w - z_q) / tq with z_q' = (w - z_q) / tq (same for r from v)
    tq, tr = 4.0 * params.span / math.pi, 3.0 * params.span / math.pi
    a_ext = np.zeros((n + 2, n + 2))
    a_ext[:n, :n] = big_a
    b_ext = np.zeros((n + 2, n_in))
    b_ext[:n] = big_b
    cw, cv = big_c[2, :n], big_c[1, :n]
    a_ext[n, :n] = cw / tq
    a_ext[n, n] = -1.0 / tq
    a_ext[n + 1, :n] = cv / tr
    a_ext[n + 1, n + 1] = -1.0 / tr
    big_c[4, :n] = cw / tq
    big_c[4, n] = -1.0 / tq
    big_c[5, :n] = cv / tr
    big_c[5, n + 1] = -1.0 / tr
    return a_ext, b_ext, big_c


def expm_small(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Matrix exponential of a small matrix by scaling and squaring of a degree-18 Taylor series.

    Used at run time instead of ``scipy.linalg.expm``, whose LAPACK path spends milliseconds of CPU in
    multi-threaded BLAS on a busy machine for a 5 x 5 matrix; for ``||m / 2^s||_1 <= 1/4`` the truncation
    error is below 1e-23 (tested against scipy).
    """
    norm = float(np.abs(m).sum(axis=0).max())
    s = max(0, int(math.ceil(math.log2(norm / 0.25)))) if norm > 0 else 0
    x = m / 2.0**s
    eye = np.eye(m.shape[0])
    e = eye.copy()
    for k in range(18, 0, -1):
        e = eye + (x @ e) / k
    for _ in range(s):
        e = e @ e
    return e


def _psd_sqrt(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """S with S S^T = q for a symmetric positive semi-definite q (Cholesky, else clipped eigen-decomposition)."""
    q = 0.5 * (q + q.T)
    try:
        return np.linalg.cholesky(q)
    except np.linalg.LinAlgError:
        pass
    w, v = np.linalg.eigh(q)
    return v * np.sqrt(np.clip(w, 0.0, None))


class DrydenProcess:
    """N independent Dryden gust processes (unit-free core used by every turbulent wind model).

    ``step(dt, airspeed)`` advances all fields by ``dt`` at frozen-turbulence speed ``airspeed``
    (scalar or (N,)) and returns the outputs (N, 3) ``[u, v, w]`` (or (N, 6) with ``rates``).
    """

    def __init__(self, params: DrydenParams, rates: bool = False, discretization: str = "exact",
                 block: int = 256) -> None:
        if discretization not in ("exact", "zoh"):
            raise ValueError(f"discretization must be 'exact' or 'zoh', got {discretization!r}")
        if not (isinstance(block, int) and block >= 1):
            raise ValueError(f"block must be a positive int, got {block!r}")
        self.params = params
        self.rates = rates
        self.discretization = discretization
        self.block = block
        self.a, self.b, self.c = spatial_state_space(params, rates)
        self.n_states = self.a.shape[0]
        self.p_stat = scipy.linalg.solve_continuous_lyapunov(self.a, -self.b @ self.b.T)
        self.p_stat = 0.5 * (self.p_stat + self.p_stat.T)
        # dense lazily-filled table of step matrices on the log grid of d (2 % bins)
        self._k0 = int(math.floor(math.log(_D_MIN) / _BIN + 0.5))
        n_keys = int(math.floor(math.log(_D_MAX) / _BIN + 0.5)) - self._k0 + 1
        self._dense = np.zeros((n_keys, 2 * self.n_states, self.n_states + self.c.shape[0]))
        self._filled = np.zeros(n_keys, dtype=bool)
        self._last_d, self._last_m = -1.0, self._dense[0]
        self._bin1, self._step_fn = (1.0, 0.0), None  # d range of the float path's current bin (empty at first)
        self._step_fn_cache: dict[int, Callable[[list[float]], tuple[list[float], list[float]]]] = {}
        self._n_out_total = self.n_states + self.c.shape[0]
        self._x, self._xl = np.zeros((0, self.n_states)), None
        self._ct = np.ascontiguousarray(self.c.T)
        self.n = 0

    # ---- discretization ------------------------------------------------------------------
    def discrete(self, d: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Ad, S)`` for a step of length ``d`` [m] (binned): ``x+ = Ad x + S z``, ``z ~ N(0, I)``."""
        m = self._matrix(d)
        ns = self.n_states
        return m[:ns, :ns].T.copy(), m[ns:, :ns].T.copy()

    def _matrix(self, d: float) -> NDArray[np.float64]:
        """Cached ``M = [[Ad^T, Ad^T C^T], [S^T, S^T C^T]]`` so that ``[x, z] @ M = [x+, y+]``."""
        return self._fill(int(math.floor(math.log(min(max(d, _D_MIN), _D_MAX)) / _BIN + 0.5)) - self._k0)

    def _fill(self, idx: int) -> NDArray[np.float64]:
        if self._filled[idx]:
            return self._dense[idx]
        dq = math.exp((idx + self._k0) * _BIN)
        ad = expm_small(self.a * dq)
        if self.discretization == "exact":
            s = _psd_sqrt(self.p_stat - ad @ self.p_stat @ ad.T)
        else:
            # noise held over the step at intensity 1/dq, zero-order-hold input matrix Bd
            import scipy.signal  # only this comparison option needs it (slow to import)

            ns = self.n_states
            sysd = scipy.signal.cont2discrete((self.a, self.b, np.eye(ns), np.zeros((ns, self.b.shape[1]))), dq,
                                              method="zoh")
            s = np.zeros((ns, ns))
            s[:, :self.b.shape[1]] = sysd[1] / math.sqrt(dq)
        top = np.vstack([ad.T, s.T])
        self._dense[idx] = np.hstack([top, top @ self._ct])
        self._filled[idx] = True
        return self._dense[idx]

    # ---- state ---------------------------------------------------------------------------
    def reset(self, n: int, seed: int | np.random.SeedSequence | None = None) -> None:
        """``n`` independent fields started from the stationary distribution (so statistics hold from t = 0)."""
        if not (isinstance(n, (int, np.integer)) and n >= 1):
            raise ValueError(f"number of fields n must be a positive int, got {n!r}")
        n = int(n)
        ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self._rngs = [np.random.Generator(np.random.PCG64(child)) for child in ss.spawn(n)]
        self.n = n
        chol = _psd_sqrt(self.p_stat)
        self.x = np.stack([chol @ g.standard_normal(self.n_states) for g in self._rngs])
        self._buf = np.zeros((self.block, n, 2 * self.n_states))
        self._k = self.block
        self._zl = None
        self.y = self.x @ self._ct

    @property
    def x(self) -> NDArray[np.float64]:
        """Filter state (N, n_states)."""
        if self._xl is not None:  # the float path holds the newest state
            self._x = np.array([self._xl])
            self._xl = None
        return self._x

    @x.setter
    def x(self, value: NDArray[np.float64]) -> None:
        self._x = value
        self._xl = None

    def _refill(self) -> None:
        ns = self.n_states
        for i, g in enumerate(self._rngs):
            self._buf[:, i, ns:] = g.standard_normal((self.block, ns))
        self._k = 0
        self._zl = self._buf[:, 0, ns:].tolist() if self.n == 1 else None

    def _sparse(self, d: float) -> list[tuple[int, int, float]]:
        """Non-zero entries ``(i, j, M_ij)`` of the step matrix for the float path (|M_ij| > 1e-14 max|M|)."""
        m = self._matrix(d)
        tol = 1e-14 * float(np.abs(m).max())
        rows, cols = np.nonzero(np.abs(m) > tol)
        return [(int(i), int(j), float(m[i, j])) for i, j in zip(rows, cols, strict=True)]

    def __getstate__(self) -> dict[str, Any]:
        """Picklable state: the generated step functions are dropped (rebuilt from the table on demand)."""
        state = self.__dict__.copy()
        state["_step_fn_cache"], state["_step_fn"], state["_bin1"] = {}, None, (1.0, 0.0)
        return state

    def _compile(self, d: float) -> Callable[[list[float]], tuple[list[float], list[float]]]:
        """The float path's step for this bin as one straight-line function ``[x, z] -> (x+, y+)``.

        Generated from :meth:`_sparse` (every non-zero entry written out as ``z[i] * M_ij``, terms in the
        order of increasing ``i`` as a loop over the entries would add them, so the sums are the same); a
        loop over the entries costs several times more interpreter work per step.  The source holds only
        indices and ``repr`` of floats (exact round trip).
        """
        ns, n_out = self.n_states, self._n_out_total
        terms: list[list[str]] = [[] for _ in range(n_out)]
        for i, j, v in self._sparse(d):
            terms[j].append(f"z[{i}] * {v!r}")
        sums = [" + ".join(t) if t else "0.0" for t in terms]
        src = f"def step(z):\n    return [{', '.join(sums[:ns])}], [{', '.join(sums[ns:])}]\n"
        namespace: dict[str, Any] = {}
        exec(compile(src, f"<dryden step d={d:.6g}>", "exec"), namespace)  # generated from numbers only
        return namespace["step"]

    def step1(self, dt: float, airspeed: float) -> list[float]:
        """N = 1 :meth:`step` in float arithmetic (same update, sparse step matrix); outputs as a list."""
        if self.n != 1:
            raise ValueError(f"step1 needs n = 1 field, have {self.n}")
        if self._k >= self.block:
            self._refill()
        d = (airspeed if airspeed > V_FLOOR else V_FLOOR) * dt
        lo, hi = self._bin1
        if not lo < d < hi:  # left the current bin (or near its edge): find the bin as _matrix does
            idx = int(math.floor(math.log(min(max(d, _D_MIN), _D_MAX)) / _BIN + 0.5)) - self._k0
            fn = self._step_fn_cache.get(idx)
            if fn is None:
                fn = self._step_fn_cache[idx] = self._compile(d)
            self._step_fn = fn
            # the bin's d range, shrunk by 1e-12 so that a d the test passes maps to idx by the formula above too
            k = idx + self._k0
            inner = _D_MIN < d < _D_MAX
            self._bin1 = ((math.exp((k - 0.5) * _BIN) * (1 + 1e-12), math.exp((k + 0.5) * _BIN) * (1 - 1e-12))
                          if inner else (1.0, 0.0))
        xz = (self._xl if self._xl is not None else self._x[0].tolist()) + self._zl[self._k]
        self._k += 1
        self._xl, y = self._step_fn(xz)
        return y

    def step(self, dt: float, airspeed: float | NDArray[np.float64]) -> NDArray[np.float64]:
        """Advance every field by ``dt`` [s] at ``airspeed`` [m/s] (floored at ``V_FLOOR``); return outputs.

        ``airspeed`` is a scalar (all fields) or (N,).  Returns (N, 3) ``[u, v, w]`` or (N, 6) with rates.
        """
        if self._k >= self.block:
            self._refill()
        ns = self.n_states
        row = self._buf[self._k]
        self._k += 1
        row[:, :ns] = self.x
        if isinstance(airspeed, (float, int)) or np.ndim(airspeed) == 0:
            d = max(float(airspeed), V_FLOOR) * dt
            if d != self._last_d:  # same step length as last time: reuse the matrix
                self._last_d, self._last_m = d, self._matrix(d)
            out = row @ self._last_m
        else:
            d = np.clip(np.maximum(np.asarray(airspeed, dtype=float), V_FLOOR) * dt, _D_MIN, _D_MAX)
            idx = np.floor(np.log(d) / _BIN + 0.5).astype(np.intp) - self._k0
            lo, hi = idx.min(), idx.max()
            if lo == hi:
                out = row @ self._fill(int(lo))
            else:
                missing = idx[~self._filled[idx]]
                for k in np.unique(missing):
                    self._fill(int(k))
                out = (row[:, None, :] @ self._dense[idx])[:, 0, :]
        self.x = out[:, :ns]
        self.y = out[:, ns:]
        return self.y

    def sample(self, n_steps: int, dt: float, airspeed: float) -> NDArray[np.float64]:
        """A time series (n_steps, N, n_out) at constant airspeed (for tests, plots and the CLI)."""
        out = np.empty((n_steps, self.n, self.c.shape[0]))
        for k in range(n_steps):
            out[k] = self.step(dt, airspeed)
        return out

    def stationary_std(self) -> NDArray[np.float64]:
        """Standard deviation of each output of the continuous model, from the Lyapunov solution."""
        return np.sqrt(np.diag(self.c @ self.p_stat @ self.c.T))
