"""Wind for N rows whose episodes start at different times: one model for all rows, or cohorts of rows.

:class:`BatchWind` runs one :class:`~fawtgym.envs.wind.WindModel` for the rows of
:class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv`.  A model whose output does not depend on time (``calm``,
steady ``fawt-*``, ``dryden-*``) is stepped once for all N rows; a row that resets restarts its own gust
field (a fresh stationary state and its stream from the start).  Any other model (a fan schedule,
``gust-1cos``, a user class) is run in cohorts: rows that reset at the same step share one copy of the model,
stepped with their episode time as each single env would; cost grows with the number of distinct reset times
alive.

Row independence: a gust model (:class:`~fawtgym.envs.wind.dryden_process.GustWind`: FAWT, Dryden) gives each
row the field seed the row alone would get from its wind seed (:func:`~.wind.dryden_process.first_child`), in
both modes, at a full reset and when some rows restart while others fly; each field reads its own stream
(:mod:`~fawtgym.envs.wind.dryden_process`).  So row i's wind in an N-row batch is the wind of the one-row batch
(the single env) with that row's seed, whatever N and the other rows do (its points and velocity being the
same).  A user model in a cohort of several rows gets one seed pooled from the rows' seed integers.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .wind import WindModel
from .wind.base import DT_MAX, CalmWind
from .wind.dryden_process import GustWind, first_child
from .wind.fawt import FawtWind
from .wind.outdoor import DrydenWind


def _time_invariant(wind: WindModel) -> bool:
    """Whether ``wind``'s output depends on the time argument (models known to ignore it)."""
    if type(wind) is CalmWind or type(wind) is DrydenWind:
        return True
    return type(wind) is FawtWind and wind.schedule.steady


class BatchWind:
    """Runs one :class:`WindModel` for N rows whose episodes start at different times (module docstring).

    ``shared``: one model steps every row (time-invariant models); else cohorts: one model copy per set of
    rows that started together (or per row, for rows given their own model by a randomizer).
    """

    def __init__(self, template: WindModel, n: int) -> None:
        self.template = copy.deepcopy(template)  # pristine copy: cohorts are copied from it
        self.n = n
        self.shared = _time_invariant(template)
        self.model: WindModel | None = None
        self.cohorts: list[list[Any]] = []  # [model, rows (k,), alive (k,) bool]
        self._started: list[list[Any]] = []  # the cohorts of the last reset_rows (cohort mode)
        self._scratch: WindModel | None = None  # shared mode, a model without a gust field: first_step's copy
        self._last = np.zeros(0, dtype=np.intp)  # the rows of the last reset_rows

    def _fresh(self) -> WindModel:
        """A pristine copy of the template that shares the template's gust-filter step-matrix table (a cache of
        matrices computed from the filter's constants only, :class:`~fawtgym.envs.wind.dryden_discrete.StepTable`):
        its bins are computed once per env instead of once per episode, with the same values."""
        table = getattr(getattr(self.template, "process", None), "table", None)
        return copy.deepcopy(self.template, {} if table is None else {id(table): table})

    @staticmethod
    def _reset(model: WindModel, ints: Sequence[int], seeds: Sequence[np.random.SeedSequence]) -> None:
        """``model.reset`` for the rows of ``seeds``: a gust model gives each row the field seed the row alone
        would get (module docstring); another model gets the one row's seed, or one pooled from the rows'."""
        if isinstance(model, GustWind):
            model.reset(len(seeds), seed=[first_child(s) for s in seeds])
        else:
            model.reset(len(seeds), seed=seeds[0] if len(seeds) == 1 else np.random.SeedSequence(
                [int(i) for i in ints]))

    def reset_rows(self, rows: NDArray[np.intp], ints: Sequence[int], seeds: Sequence[np.random.SeedSequence],
                   models: Sequence[WindModel] | None = None) -> None:
        """New episodes (time 0) for ``rows``; ``ints``/``seeds`` are the rows' wind seeds; ``models``: one own
        model per row (each then runs as a cohort of one row; a shared model becomes a cohort of its rows)."""
        self._last = rows
        if models is not None:
            if self.shared:
                if self.model is not None:  # the rows still flying keep the shared model, as a cohort
                    self.cohorts = [[self.model, np.arange(self.n), np.ones(self.n, dtype=bool)]]
                self.shared, self.model = False, None
            for c in self.cohorts:
                c[2] &= ~np.isin(c[1], rows)
            self.cohorts = [c for c in self.cohorts if c[2].any()]
            self._started = []
            for row, model, seed in zip(rows.tolist(), models, seeds, strict=True):
                model.reset(1, seed=seed)
                self._started.append([model, np.array([row]), np.ones(1, dtype=bool)])
            self.cohorts.extend(self._started)
            return
        if self.shared:
            if self.model is None or rows.size == self.n:
                self.model = self._fresh()
                self._reset(self.model, ints, seeds)
                return
            if isinstance(self.model, GustWind):  # the rows' own fields start anew, the others go on
                self.model.restart_rows(rows, seeds)
            return
        for c in self.cohorts:
            c[2] &= ~np.isin(c[1], rows)
        self.cohorts = [c for c in self.cohorts if c[2].any()]
        model = self._fresh()
        self._reset(model, ints, seeds)
        self._started = [[model, rows.copy(), np.ones(rows.size, dtype=bool)]]
        self.cohorts.append(self._started[0])

    def first_step(self, dt: float, points: NDArray[np.float64], velocity: NDArray[np.float64]) -> NDArray[np.float64]:
        """The first wind sample (k, K, 3) of the rows of the last :meth:`reset_rows` (at their ``points``
        (k, K, 3)), without stepping the other rows (same-step autoreset, module docstring)."""
        rows = self._last
        if not self.shared:  # the cohorts just started step alone, at episode time 0, as in step()
            out = np.empty(points.shape)
            pos = {row: j for j, row in enumerate(rows.tolist())}
            for model, crows, _ in self._started:
                idx = np.array([pos[r] for r in crows.tolist()])
                out[idx] = model.step(0.0, dt, points[idx], velocity[idx])
            return out
        assert self.model is not None  # shared mode: reset_rows made it
        if rows.size == self.n:  # a full restart: the fresh shared model steps every row
            return self.model.step(0.0, dt, points, velocity)
        # the shared model goes on for the other rows: a k-row copy of the restarted rows' fields (reset_rows
        # restarted them) takes them one step forward and hands them back
        if isinstance(self.model, GustWind):
            sub = self.model.take_rows(rows)
            out = sub.step(0.0, dt, points, velocity)
            self.model.put_rows(rows, sub)
            return out
        if self._scratch is None:  # a model without random state (calm)
            self._scratch = self._fresh()
        self._scratch.reset(rows.size)
        return self._scratch.step(0.0, dt, points, velocity)

    def step(self, times: NDArray[np.float64], dt: float, points: NDArray[np.float64],
             velocity: NDArray[np.float64]) -> NDArray[np.float64]:
        """Wind (N, K, 3) at ``points`` (N, K, 3); ``times`` (N,) are the rows' episode times."""
        if self.shared:
            assert self.model is not None  # reset_rows made it
            if 0.0 < dt <= DT_MAX:  # the env's own arrays (float64, shapes and time checked): no re-validation
                return self.model.step_trusted(float(times[0]), dt, points, velocity)
            return self.model.step(float(times[0]), dt, points, velocity)  # raises, naming dt
        out = np.empty(points.shape)
        for model, rows, alive in self.cohorts:  # one call per cohort (rows that reset together)
            live = rows[alive]
            got = model.step(float(times[live[0]]), dt, points[rows], velocity[rows])
            out[live] = got[alive]
        return out
