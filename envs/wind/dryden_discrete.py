"""Exact discretization of the spatial Dryden filters over a step of length ``d`` [m], tabulated.

Over one time step of length ``dt`` the air moves ``d = V dt`` past the vehicle, and the exact
discretization of the spatial filter ``dx/dxi = A x + B n`` (:func:`.dryden.spatial_state_space`) is
``x+ = Ad x + e``, ``Ad = expm(A d)``, ``e ~ N(0, Qd)``, ``Qd = P - Ad P Ad^T`` with ``P`` the stationary
covariance (``A P + P A^T + B B^T = 0``, scipy's Lyapunov solver).  This is exact for *any* ``dt``: the
sampled process has the continuous model's variance and autocovariance at the sample instants, so the
realized sigma does not depend on the step (unlike the common practice of scaling unit noise without
``sqrt(dt)``).

A changing airspeed (the frozen-turbulence speed ``V = |mean wind - vehicle velocity|``, floored at
:data:`.dryden.V_FLOOR`) only changes ``d``; the matrices are held on a logarithmic grid of ``d`` (2 %
bins: the step length, hence the gust time scale, is exact to +-1 %, while the variance stays exact
because ``Qd`` is built from the same ``Ad``; ``d`` is clipped to [1e-5, 200] m).  Bin ``k`` holds
``d_k = exp((k + k0) BIN)``; its entry depends on ``k`` only, so a field's step never depends on which
bins other fields use.  Bins are filled on first use (one small ``expm`` each).

Option ``discretization="zoh"``: zero-order hold of the state space with the noise held over the
step at intensity ``1/dt`` (``scipy.signal.cont2discrete``), as many simulators do; its variance
error is ``O(d / L)``, small only for ``d << L``.  Kept for comparison; ``"exact"`` is the default.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from fawtgym.core.checks import shown

BIN = 0.02  #: log-bin width of the tabulated step length d = V dt
D_MIN, D_MAX = 1e-5, 200.0  #: [m] range of d = V dt held in the table (clipped outside)
DISCRETIZATIONS = ("exact", "zoh")


def expm_small(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Matrix exponential of a small matrix by scaling and squaring of a degree-18 Taylor series.

    Used instead of ``scipy.linalg.expm``, whose LAPACK path spends milliseconds of CPU in
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


def psd_sqrt(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """S with S S^T = q for a symmetric positive semi-definite q (Cholesky, else clipped eigen-decomposition)."""
    q = 0.5 * (q + q.T)
    try:
        return np.asarray(np.linalg.cholesky(q), dtype=np.float64)
    except np.linalg.LinAlgError:
        pass
    w, v = np.linalg.eigh(q)
    return np.asarray(v * np.sqrt(np.clip(w, 0.0, None)), dtype=np.float64)


class StepTable:
    """Step matrices of the filter ``(A, B, C)`` on the log grid of ``d``, filled on first use.

    ``matrices[k]`` is ``M = [[Ad^T, Ad^T C^T], [S^T, S^T C^T]]`` (shape ``(2 ns, ns + n_out)``) for bin ``k``,
    so that the row ``[x, z] @ M = [x+, y+]`` with ``z ~ N(0, I)`` (``S S^T = Qd``); a bin not computed yet holds
    NaN (what the kernels test, :func:`.dryden_process.bin_filled`), ``filled[k]`` says whether it is computed.
    ``k0`` is the index offset of bin 0 (:func:`.dryden_process.step_bin`).
    """

    def __init__(self, a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64],
                 p_stat: NDArray[np.float64], discretization: str = "exact") -> None:
        if discretization not in DISCRETIZATIONS:
            raise ValueError(f"discretization must be one of {DISCRETIZATIONS}, got {shown(discretization)}")
        self.a, self.b, self.c, self.p_stat = a, b, c, p_stat
        self.discretization = discretization
        self.n_states = a.shape[0]
        self.k0 = int(math.floor(math.log(D_MIN) / BIN + 0.5))
        n_keys = int(math.floor(math.log(D_MAX) / BIN + 0.5)) - self.k0 + 1
        self.matrices = np.full((n_keys, 2 * self.n_states, self.n_states + c.shape[0]), np.nan)
        self._ct = np.ascontiguousarray(c.T)

    @property
    def filled(self) -> NDArray[np.bool_]:
        """Whether each bin is computed (a copy; an uncomputed bin holds NaN)."""
        return ~np.isnan(self.matrices[:, 0, 0])

    def bin_length(self, k: int) -> float:
        """The step length ``d`` [m] bin ``k`` stands for."""
        return math.exp((k + self.k0) * BIN)

    def bin_of(self, d: float) -> int:
        """The bin of a step length ``d`` [m] (clipped to [D_MIN, D_MAX]); the kernels use the same formula."""
        return int(math.floor(math.log(min(max(d, D_MIN), D_MAX)) / BIN + 0.5)) - self.k0

    def fill(self, k: int) -> NDArray[np.float64]:
        """The step matrix of bin ``k`` (computed now if it was not)."""
        if not math.isnan(self.matrices[k, 0, 0]):
            return self.matrices[k]
        d = self.bin_length(k)
        ad = expm_small(self.a * d)
        if self.discretization == "exact":
            s = psd_sqrt(self.p_stat - ad @ self.p_stat @ ad.T)
        else:
            # noise held over the step at intensity 1/d, zero-order-hold input matrix Bd
            import scipy.signal  # only this comparison option needs it (slow to import)

            ns = self.n_states
            sysd = scipy.signal.cont2discrete((self.a, self.b, np.eye(ns), np.zeros((ns, self.b.shape[1]))), d,
                                              method="zoh")
            s = np.zeros((ns, ns))
            s[:, :self.b.shape[1]] = sysd[1] / math.sqrt(d)
        top = np.vstack([ad.T, s.T])
        m = np.hstack([top, top @ self._ct])
        if not np.all(np.isfinite(m)):  # NaN marks an uncomputed bin: a computed one must be finite
            raise FloatingPointError(f"Dryden step matrix of bin {k} (d = {d:g} m) is not finite")
        self.matrices[k] = m
        return self.matrices[k]

    def discrete(self, d: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Ad, S)`` for a step of length ``d`` [m] (binned): ``x+ = Ad x + S z``, ``z ~ N(0, I)``."""
        m = self.fill(self.bin_of(d))
        ns = self.n_states
        return m[:ns, :ns].T.copy(), m[ns:, :ns].T.copy()


def stationary_covariance(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``P`` with ``A P + P A^T + B B^T = 0`` (symmetrized)."""
    p = scipy.linalg.solve_continuous_lyapunov(a, -b @ b.T)
    return 0.5 * (p + p.T)
