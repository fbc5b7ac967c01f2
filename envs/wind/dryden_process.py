"""N independent Dryden gust processes, stepped by one compiled kernel that loops over the fields.

Each field (row) is the spatial Dryden filter of :mod:`.dryden` driven by its own white noise; a step of
length ``d = max(V, V_FLOOR) dt`` applies the exact step matrix of :mod:`.dryden_discrete`::

    [x+, y+] = [x, z] @ M(d),      z ~ N(0, I)      (x+ = Ad x + S z,  y+ = C x+)

Rows never interact: each row's step is written out as explicit sums over its own state and noise
(:func:`gust_row_step`), and the step matrix of its bin depends on its own ``d`` only, so row ``i`` of an
N-field run is bit for bit the run of that field alone with the same seed and airspeeds (tested).

Random streams: field ``i`` has its own generator (a ``numpy.random.SeedSequence`` child of the seed, or
the ``i``-th of a list of seeds), so field ``i`` is the same whatever ``N`` is.  Normals are drawn per
field in blocks of ``block`` steps (one generator call per field per block).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .base import DT_MAX, is_real
from .dryden import V_FLOOR, DrydenParams, spatial_state_space
from .dryden_discrete import BIN, D_MAX, D_MIN, StepTable, psd_sqrt, stationary_covariance

Seed = int | np.random.SeedSequence | Sequence[np.random.SeedSequence] | None


@njit(cache=True)
def step_bin(d: float, k0: int) -> int:
    """Bin of the step length ``d`` [m] in the step-matrix table (``d`` clipped to [D_MIN, D_MAX])."""
    if d < D_MIN:
        d = D_MIN
    elif d > D_MAX:
        d = D_MAX
    return int(math.floor(math.log(d) / BIN + 0.5)) - k0


@njit(cache=True)
def gust_row_step(x: NDArray[np.float64], z: NDArray[np.float64], m: NDArray[np.float64],
                  y: NDArray[np.float64], i: int, scratch: NDArray[np.float64]) -> None:
    """Row ``i``: ``[x_i, z] @ M = [x+, y+]`` (exact step, module docstring); ``x[i]``, ``y[i]`` overwritten."""
    ns = x.shape[1]
    n_col = m.shape[1]
    for j in range(n_col):
        acc = 0.0
        for col in range(ns):
            acc += x[i, col] * m[col, j]  # Ad x
        for col in range(ns):
            acc += z[col] * m[ns + col, j]  # S z
        scratch[j] = acc
    for j in range(ns):
        x[i, j] = scratch[j]
    for j in range(n_col - ns):
        y[i, j] = scratch[ns + j]


@njit(cache=True)
def dryden_step_rows(x: NDArray[np.float64], noise: NDArray[np.float64], k: int, airspeed: NDArray[np.float64],
                     dt: float, table: NDArray[np.float64], filled: NDArray[np.bool_], k0: int,
                     bins: NDArray[np.int64], y: NDArray[np.float64]) -> int:
    """Advance every row by ``dt`` at its airspeed (``airspeed`` (N,) or (1,) for all); outputs into ``y``.

    Returns -1, or (nothing changed) the index of a table bin a row needs that is not filled yet.
    """
    n = x.shape[0]
    shared = airspeed.shape[0] == 1
    for i in range(n):
        v = airspeed[0] if shared else airspeed[i]
        b = step_bin((v if v > V_FLOOR else V_FLOOR) * dt, k0)  # d = max(V, V_FLOOR) dt
        if not filled[b]:
            return b
        bins[i] = b
    scratch = np.empty(table.shape[2])
    for i in range(n):
        gust_row_step(x, noise[i, k], table[bins[i]], y, i, scratch)
    return -1


def _field_seeds(n: int, seed: Seed) -> list[np.random.SeedSequence]:
    """One SeedSequence per field: children of ``seed`` (int, SeedSequence or None), or ``seed`` itself when it is
    a sequence of ``n`` SeedSequences (so a field can be run alone with the seed it has in a batch)."""
    if seed is None or isinstance(seed, (int, np.integer, np.random.SeedSequence)) and not isinstance(seed, bool):
        ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        return ss.spawn(n)
    if isinstance(seed, Sequence) and len(seed) == n and all(isinstance(s, np.random.SeedSequence) for s in seed):
        return list(seed)
    raise ValueError(f"seed must be an int >= 0, a SeedSequence, None or a list of {n} SeedSequences (one per "
                     f"field), got {seed!r}")


class DrydenProcess:
    """N independent Dryden gust processes (the unit-free core of every turbulent wind model).

    ``step(dt, airspeed)`` advances all fields by ``dt`` at frozen-turbulence speed ``airspeed``
    (scalar or (N,)) and returns the outputs (N, 3) ``[u, v, w]`` (or (N, 6) with ``rates``).
    """

    def __init__(self, params: DrydenParams, rates: bool = False, discretization: str = "exact",
                 block: int = 256) -> None:
        if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
            raise ValueError(f"block must be a positive int, got {block!r}")
        self.params = params
        self.rates = rates
        self.block = int(block)
        self.a, self.b, self.c = spatial_state_space(params, rates)
        self.n_states = self.a.shape[0]
        self.n_out = self.c.shape[0]
        self.p_stat = stationary_covariance(self.a, self.b)
        self.table = StepTable(self.a, self.b, self.c, self.p_stat, discretization)
        self.discretization = discretization
        self.n = 0
        self._x = np.zeros((0, self.n_states))
        self._k = self.block

    # ---- state ---------------------------------------------------------------------------
    def reset(self, n: int, seed: Seed = None) -> None:
        """``n`` independent fields started from the stationary distribution (so statistics hold from t = 0).

        ``seed``: an int, a SeedSequence or None (field ``i`` draws from its ``i``-th child), or a list of ``n``
        SeedSequences (field ``i`` draws from the ``i``-th).
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"number of fields n must be a positive int, got {n!r}")
        n = int(n)
        self._rngs = [np.random.Generator(np.random.PCG64(s)) for s in _field_seeds(n, seed)]
        self.n = n
        chol = psd_sqrt(self.p_stat)
        self._x = np.ascontiguousarray(np.stack([chol @ g.standard_normal(self.n_states) for g in self._rngs]))
        self.noise = np.empty((n, self.block, self.n_states))
        self._k = self.block
        self.bins = np.zeros(n, dtype=np.int64)

    @property
    def x(self) -> NDArray[np.float64]:
        """Filter state (N, n_states); assign an (N, n_states) array to set it (e.g. restart some rows)."""
        return self._x

    @x.setter
    def x(self, value: NDArray[np.float64]) -> None:
        x = np.array(value, dtype=float)
        if x.shape != (self.n, self.n_states) or not np.all(np.isfinite(x)):
            raise ValueError(f"Dryden state must be finite with shape ({self.n}, {self.n_states}), got shape "
                             f"{x.shape}")
        self._x = x

    def noise_index(self) -> int:
        """Index ``k`` of this step's normals :attr:`noise` ``[:, k]`` (drawing the next block first if this one is
        used up); :meth:`advance_noise` moves on once the step is taken."""
        if self._k >= self.block:
            for i, g in enumerate(self._rngs):
                self.noise[i] = g.standard_normal((self.block, self.n_states))
            self._k = 0
        return self._k

    def advance_noise(self) -> None:
        """The normals of :meth:`noise_index` were used: the next step takes the next ones."""
        self._k += 1

    def discrete(self, d: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Ad, S)`` for a step of length ``d`` [m] (binned): ``x+ = Ad x + S z``, ``z ~ N(0, I)``."""
        return self.table.discrete(d)

    def step(self, dt: float, airspeed: float | NDArray[np.float64]) -> NDArray[np.float64]:
        """Advance every field by ``dt`` [s] at ``airspeed`` [m/s] (floored at ``V_FLOOR``); return outputs.

        ``airspeed`` is a scalar (all fields) or (N,).  Returns (N, 3) ``[u, v, w]`` or (N, 6) with rates.
        """
        if self.n == 0:
            raise RuntimeError("DrydenProcess.step before reset(n, seed)")
        if not is_real(dt) or not 0.0 < dt <= DT_MAX:
            raise ValueError(f"dt must be a wind step in (0, {DT_MAX:g}] s, got {dt!r}")
        speed = np.array(airspeed, dtype=float, ndmin=1)
        if speed.shape not in ((1,), (self.n,)) or not np.all(np.isfinite(speed)):
            raise ValueError(f"airspeed must be a finite scalar or shape ({self.n},) [m/s], got {airspeed!r}")
        k = self.noise_index()
        y = np.empty((self.n, self.n_out))
        table = self.table
        while (missing := dryden_step_rows(self._x, self.noise, k, speed, float(dt), table.matrices, table.filled,
                                           table.k0, self.bins, y)) >= 0:
            table.fill(missing)
        self.advance_noise()
        return y

    def sample(self, n_steps: int, dt: float, airspeed: float) -> NDArray[np.float64]:
        """A time series (n_steps, N, n_out) at constant airspeed (for tests, plots and the CLI)."""
        out = np.empty((n_steps, self.n, self.n_out))
        for k in range(n_steps):
            out[k] = self.step(dt, airspeed)
        return out

    def stationary_std(self) -> NDArray[np.float64]:
        """Standard deviation of each output of the continuous model, from the Lyapunov solution."""
        return np.sqrt(np.diag(self.c @ self.p_stat @ self.c.T))
