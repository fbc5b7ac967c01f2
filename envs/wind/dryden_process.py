"""N independent Dryden gust processes, stepped by one compiled kernel that loops over the fields.

Each field (row) is the spatial Dryden filter of :mod:`.dryden` driven by its own white noise; a step of
length ``d = max(V, V_FLOOR) dt`` applies the exact step matrix of :mod:`.dryden_discrete`::

    [x+, y+] = [x, z] @ M(d),      z ~ N(0, I)      (x+ = Ad x + S z,  y+ = C x+)

Rows never interact: each row's step is written out as explicit sums over its own state and noise
(:func:`gust_row_step`), and the step matrix of its bin depends on its own ``d`` only, so row ``i`` of an
N-field run is bit for bit the run of that field alone with the same seed and airspeeds (tested).

Random streams: field ``i`` has its own generator (a ``numpy.random.SeedSequence`` child of the seed, or
the ``i``-th of a list of seeds), so field ``i`` is the same whatever ``N`` is.  A field's stream is read in
one order only: its stationary initial state (``n_states`` normals), then one ``n_states``-vector per step.
The step normals are drawn per field in blocks of ``block`` steps into ``noise`` (block, N, n_states), one
generator call per field per block (:func:`fawtgym.core.normals.standard_normals`); ``cursor[i]`` is field ``i``'s
next step of its block (its normals ``noise[cursor[i], i]``).  The layout is step-major so that a step of fields
that advance together reads one contiguous slab, which the hardware prefetches: in field-major order each of 512
fields read its own page and cache line per step, and the FAWT kernel cost ~175 instead of ~105 us a step in the
closed loop (docs/performance.md).  Fields restarted at different steps (:meth:`DrydenProcess.restart_rows`) each
read their own stream from its start, and a field of an N-field run is the field alone whatever the other fields do.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.checks import shown
from fawtgym.core.normals import standard_normals

from .base import WindModel, check_dt, check_n
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
def bin_filled(table: NDArray[np.float64], b: int) -> bool:
    """Whether bin ``b`` of a step-matrix table (:class:`.dryden_discrete.StepTable`) is computed (else NaN)."""
    return not math.isnan(table[b, 0, 0])


@njit(cache=True)
def gust_row_step(x: NDArray[np.float64], noise: NDArray[np.float64], step: int, table: NDArray[np.float64], b: int,
                  i: int, scratch: NDArray[np.float64]) -> None:
    """Row ``i``: ``[x_i, z] @ M = [x+, y+]`` (exact step, module docstring) with the row's normals
    ``z = noise[step, i]`` and the step matrix ``M = table[b]``, into ``scratch`` (ns + n_out,); ``x[i]`` is
    overwritten with ``x+``, the outputs ``y+`` are ``scratch[ns:]``.  Indexed in place: a view per row
    (``noise[step, i]``, ``table[b]``) would cost numba an atomic reference-count increment and decrement each."""
    ns = x.shape[1]
    n_col = table.shape[2]
    # output j is the sum 0 + x_0 m_0j + ... + x_(ns-1) m_(ns-1)j + z_0 m_(ns)j + ... + z_(ns-1) m_(2ns-1)j, in this
    # order; four outputs are summed side by side (independent sums the CPU overlaps), the rest one by one
    j = 0
    while j + 4 <= n_col:
        s0, s1, s2, s3 = 0.0, 0.0, 0.0, 0.0
        for col in range(2 * ns):  # [x, z] @ M: Ad x, then S z
            v = x[i, col] if col < ns else noise[step, i, col - ns]
            s0, s1 = s0 + v * table[b, col, j], s1 + v * table[b, col, j + 1]
            s2, s3 = s2 + v * table[b, col, j + 2], s3 + v * table[b, col, j + 3]
        scratch[j], scratch[j + 1], scratch[j + 2], scratch[j + 3] = s0, s1, s2, s3
        j += 4
    while j < n_col:
        acc = 0.0
        for col in range(ns):
            acc += x[i, col] * table[b, col, j]
        for col in range(ns):
            acc += noise[step, i, col] * table[b, ns + col, j]
        scratch[j] = acc
        j += 1
    for j in range(ns):
        x[i, j] = scratch[j]


@njit(cache=True)
def dryden_step_rows(x: NDArray[np.float64], noise: NDArray[np.float64], cursor: NDArray[np.int64],
                     airspeed: NDArray[np.float64], dt: float, table: NDArray[np.float64], k0: int,
                     y: NDArray[np.float64]) -> int:
    """Advance every row by ``dt`` at its airspeed (``airspeed`` (N,) or (1,) for all) with its next normals
    ``noise[cursor[i], i]`` (module docstring); outputs into ``y``.

    Returns -1, or (nothing changed) the index of a table bin a row needs that is not filled yet.
    """
    n, ns = x.shape
    shared = airspeed.shape[0] == 1
    bins = np.empty(n, dtype=np.int64)
    for i in range(n):
        v = airspeed[0] if shared else airspeed[i]
        b = step_bin((v if v > V_FLOOR else V_FLOOR) * dt, k0)  # d = max(V, V_FLOOR) dt
        if not bin_filled(table, b):
            return b
        bins[i] = b
    scratch = np.empty(table.shape[2])
    for i in range(n):
        gust_row_step(x, noise, cursor[i], table, bins[i], i, scratch)
        cursor[i] += 1
        for j in range(y.shape[1]):
            y[i, j] = scratch[ns + j]
    return -1


def first_child(seed: np.random.SeedSequence) -> np.random.SeedSequence:
    """The SeedSequence ``seed.spawn(1)[0]`` would return, without spawning (``seed`` is left unchanged): the seed
    of the one field of a process reset with ``seed`` (:func:`field_seeds`), so a row of an N-field run given
    ``first_child(s)`` is the field alone reset with ``s``."""
    return np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, seed.n_children_spawned),
                                  pool_size=seed.pool_size)


def field_seeds(n: int, seed: Seed) -> list[np.random.SeedSequence]:
    """One SeedSequence per field: children of ``seed`` (int, SeedSequence or None), or ``seed`` itself when it is
    a sequence of ``n`` SeedSequences (so a field can be run alone with the seed it has in a batch)."""
    if seed is None or isinstance(seed, (int, np.integer, np.random.SeedSequence)) and not isinstance(seed, bool):
        ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        return ss.spawn(n)
    if isinstance(seed, Sequence) and len(seed) == n and all(isinstance(s, np.random.SeedSequence) for s in seed):
        return list(seed)
    raise ValueError(f"seed must be an int >= 0, a SeedSequence, None or a list of {n} SeedSequences (one per "
                     f"field), got {shown(seed)}")


#: the step normals drawn ahead per process: at most this many bytes (:func:`noise_block`)
NOISE_BYTES = 32 * 2**20
BLOCK_MIN, BLOCK_MAX = 256, 4096  #: the bounds of :func:`noise_block`
STEPS_PER_FIELD = 4  #: :func:`noise_block` gives ``n`` fields a block of up to this many steps per field


def noise_block(n: int, n_states: int) -> int:
    """Steps of normals drawn ahead per field for ``n`` fields: ``STEPS_PER_FIELD n`` steps, at most
    :data:`NOISE_BYTES` of numbers, within [:data:`BLOCK_MIN`, :data:`BLOCK_MAX`].  Each field's block is one
    generator call, which costs ~5 us besides its numbers (:func:`fawtgym.core.normals.standard_normals`): ``n``
    fields pay ``n`` of them per block, ~1.25 us a step in blocks of ``4 n`` steps (512 fields: 1638 steps, 32 MiB,
    ~1.6 us a step, where blocks of 256 cost ~10 us), while a few fields (a single env, a cohort of one row) keep
    short blocks.  The block only chunks each field's stream: a field reads the same numbers whatever it is."""
    return int(min(BLOCK_MAX, max(BLOCK_MIN, min(STEPS_PER_FIELD * n, NOISE_BYTES // (8 * n * n_states)))))


class DrydenProcess:
    """N independent Dryden gust processes (the unit-free core of every turbulent wind model).

    ``step(dt, airspeed)`` advances all fields by ``dt`` at frozen-turbulence speed ``airspeed``
    (scalar or (N,)) and returns the outputs (N, 3) ``[u, v, w]`` (or (N, 6) with ``rates``).
    A wind model's kernel steps the fields itself: it calls :meth:`ready` first (every field has its next
    normals ``noise[cursor[i], i]``), advances ``cursor`` for the fields it stepped, then calls :meth:`stepped`.
    """

    def __init__(self, params: DrydenParams, rates: bool = False, discretization: str = "exact",
                 block: int | None = None) -> None:
        if block is not None and (isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1):
            raise ValueError(f"block must be None (chosen by the number of fields: noise_block) or a positive int, "
                             f"got {shown(block)}")
        self.params = params
        self.rates = rates
        self._block = None if block is None else int(block)
        self.block = self._block or BLOCK_MIN
        self.a, self.b, self.c = spatial_state_space(params, rates)
        self.n_states = self.a.shape[0]
        self.n_out = self.c.shape[0]
        self.p_stat = stationary_covariance(self.a, self.b)
        self._chol = psd_sqrt(self.p_stat)  # x0 = chol z, z ~ N(0, I): a draw from the stationary distribution
        self.table = StepTable(self.a, self.b, self.c, self.p_stat, discretization)
        self.discretization = discretization
        self.n = 0
        self._x = np.zeros((0, self.n_states))
        self._rngs: list[np.random.Generator] = []
        self.noise = np.zeros((self.block, 0, self.n_states))
        self.cursor = np.zeros(0, dtype=np.int64)
        self.refill_in = 0  # steps until some field's block is used up (block - max(cursor))

    # ---- state ---------------------------------------------------------------------------
    def reset(self, n: int, seed: Seed = None) -> None:
        """``n`` independent fields started from the stationary distribution (so statistics hold from t = 0).

        ``seed``: an int, a SeedSequence or None (field ``i`` draws from its ``i``-th child), or a list of ``n``
        SeedSequences (field ``i`` draws from the ``i``-th).
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"number of fields n must be a positive int, got {shown(n)}")
        n = int(n)
        seeds = field_seeds(n, seed)
        self.n = n
        self.block = self._block or noise_block(n, self.n_states)
        self._x = np.empty((n, self.n_states))
        self._rngs = [np.random.Generator(np.random.PCG64(s)) for s in seeds]
        self.noise = np.empty((self.block, n, self.n_states))
        self.cursor = np.zeros(n, dtype=np.int64)
        self._start(range(n))

    def restart_rows(self, rows: NDArray[np.intp], seeds: Sequence[np.random.SeedSequence]) -> None:
        """Fields ``rows`` (k,) start anew, field ``rows[j]`` from ``seeds[j]`` exactly as a field reset with it
        (its generator, stationary state and stream from the start); the other fields are untouched."""
        if len(seeds) != len(rows):
            raise ValueError(f"restart_rows needs one seed per row: {len(rows)} rows, {len(seeds)} seeds")
        row_list = [int(r) for r in rows]
        for row, s in zip(row_list, seeds, strict=True):
            self._rngs[row] = np.random.Generator(np.random.PCG64(s))
        self._start(row_list)

    def _start(self, rows: Sequence[int] | range) -> None:
        """Fields ``rows`` draw their stationary initial state and their first block of step normals: one generator
        call each, in the stream's order (``n_states`` normals for the state, then the block)."""
        chol, block = self._chol, self.block
        for row in rows:  # reset path: one generator per field (its own stream)
            draw = standard_normals(self._rngs[row], (block + 1, self.n_states))
            self._x[row] = chol @ draw[0]
            self.noise[:, row] = draw[1:]
            self.cursor[row] = 0
        self.refill_in = block - int(self.cursor.max())

    def ready(self) -> None:
        """Before a step: every field has its next normals (the fields whose block is used up draw the next one)."""
        if self.refill_in > 0:
            return
        block = self.block
        for row in np.flatnonzero(self.cursor >= block).tolist():  # each field from its own generator
            self.noise[:, row] = standard_normals(self._rngs[row], (block, self.n_states))
            self.cursor[row] = 0
        self.refill_in = block - int(self.cursor.max())

    def stepped(self) -> None:
        """After a step of every field (each kernel advanced ``cursor``)."""
        self.refill_in -= 1

    def take(self, rows: NDArray[np.intp]) -> DrydenProcess:
        """A k-field process of fields ``rows`` (k,) (their state, blocks and generators; the step table shared), to
        step those fields alone; :meth:`put` writes them back."""
        sub = copy.copy(self)
        sub.n = int(rows.size)
        sub._x = self._x[rows]
        sub._rngs = [self._rngs[r] for r in rows.tolist()]
        sub.noise = self.noise[:, rows]
        sub.cursor = self.cursor[rows]
        sub.refill_in = self.block - int(sub.cursor.max())
        return sub

    def put(self, rows: NDArray[np.intp], sub: DrydenProcess) -> None:
        """Write back the fields ``rows`` of :meth:`take`'s ``sub`` after it stepped them."""
        self._x[rows] = sub._x
        self.noise[:, rows] = sub.noise
        self.cursor[rows] = sub.cursor
        for row, rng in zip(rows.tolist(), sub._rngs, strict=True):
            self._rngs[row] = rng
        self.refill_in = self.block - int(self.cursor.max())

    @property
    def x(self) -> NDArray[np.float64]:
        """Filter state (N, n_states); assign an (N, n_states) array to set it (:meth:`restart_rows` restarts rows)."""
        return self._x

    @x.setter
    def x(self, value: NDArray[np.float64]) -> None:
        x = np.array(value, dtype=float)
        if x.shape != (self.n, self.n_states) or not np.all(np.isfinite(x)):
            raise ValueError(f"Dryden state must be finite with shape ({self.n}, {self.n_states}), got shape "
                             f"{x.shape}")
        self._x = x

    def discrete(self, d: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Ad, S)`` for a step of length ``d`` [m] (binned): ``x+ = Ad x + S z``, ``z ~ N(0, I)``."""
        return self.table.discrete(d)

    def step(self, dt: float, airspeed: float | NDArray[np.float64]) -> NDArray[np.float64]:
        """Advance every field by ``dt`` [s] at ``airspeed`` [m/s] (floored at ``V_FLOOR``); return outputs.

        ``airspeed`` is a scalar (all fields) or (N,).  Returns (N, 3) ``[u, v, w]`` or (N, 6) with rates.
        """
        if self.n == 0:
            raise RuntimeError("DrydenProcess.step before reset(n, seed)")
        dt = check_dt(dt)
        speed = np.array(airspeed, dtype=float, ndmin=1)
        if speed.shape not in ((1,), (self.n,)) or not np.all(np.isfinite(speed)):
            raise ValueError(f"airspeed must be a finite scalar or shape ({self.n},) [m/s], got {shown(airspeed)}")
        self.ready()
        y = np.empty((self.n, self.n_out))
        table = self.table
        while (missing := dryden_step_rows(self._x, self.noise, self.cursor, speed, float(dt), table.matrices,
                                           table.k0, y)) >= 0:
            table.fill(missing)
        self.stepped()
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


class GustWind(WindModel):
    """A wind model driven by one :class:`DrydenProcess` ``process`` (FAWT turbulence, outdoor Dryden): its reset,
    and the row operations :class:`~fawtgym.envs.wind_cohorts.BatchWind` uses to restart some rows while the
    others go on (each row's wind from its own seed, module docstring)."""

    process: DrydenProcess

    def reset(self, n: int, seed: Seed = None) -> None:
        self.process.reset(check_n(n), seed)
        self.n = int(n)

    def restart_rows(self, rows: NDArray[np.intp], seeds: Sequence[np.random.SeedSequence]) -> None:
        """Rows ``rows`` start anew, row ``rows[j]`` exactly as the one row of a model reset with ``seeds[j]``
        (:func:`first_child`: that row's field seed); the other rows are untouched."""
        self.process.restart_rows(rows, [first_child(s) for s in seeds])

    def take_rows(self, rows: NDArray[np.intp]) -> GustWind:
        """A copy of this model for rows ``rows`` (k,) alone (their fields, :meth:`DrydenProcess.take`)."""
        sub = copy.copy(self)
        sub.process = self.process.take(rows)
        sub.n = int(rows.size)
        return sub

    def put_rows(self, rows: NDArray[np.intp], sub: GustWind) -> None:
        """Write back the rows of :meth:`take_rows`'s ``sub`` after it stepped them."""
        self.process.put(rows, sub.process)
