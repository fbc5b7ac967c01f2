"""One time grid at the observer rate, and sample-and-hold resampling without look-ahead.

Every signal is put on the grid ``t_k = t_0 + k / rate`` by **sample-and-hold**: the value at ``t_k`` is
the latest sample with timestamp ``<= t_k`` (zero-order hold).  Nothing after ``t_k`` is used, so an
estimate at ``t_k`` depends only on what the flight controller had logged by ``t_k`` -- the same causality
an observer running on board has (linear interpolation would read the next sample, a look-ahead of up
to one logging period).  Grid points before a signal's first sample have no value (``valid`` False) and
are not estimated.  Attitude is held as a rotation matrix (no interpolation on SO(3) needed).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import FlightLogError, log_number

#: the observers' rate on a log [Hz]: at least one estimate a second, at most 10 kHz (PX4 logs its fastest topics at
#: a few hundred Hz; a rate of 1e300 Hz asked numpy for a grid beyond any memory)
RATE_RANGE = (1.0, 1e4)


def check_rate(rate: object) -> float:
    """The observer rate [Hz] as a float in :data:`RATE_RANGE`; FlightLogError naming it otherwise."""
    return log_number(rate, "observer rate (--rate)", minimum=RATE_RANGE[0], inclusive_minimum=True,
                      maximum=RATE_RANGE[1], note="Hz")


def make_grid(t_start: float, t_end: float, rate: float) -> NDArray[np.float64]:
    """Grid times [s] from ``t_start`` to ``t_end`` (inclusive when on the grid) at ``rate`` Hz."""
    rate = check_rate(rate)
    span = "the log's usable time span: "
    t_start, t_end = log_number(t_start, span + "t_start"), log_number(t_end, span + "t_end")
    if t_end <= t_start:
        raise FlightLogError(f"the log's usable time span [{t_start:.3f}, {t_end:.3f}] s is empty")
    n = int(np.floor((t_end - t_start) * rate + 1e-9)) + 1
    return t_start + np.arange(n) / rate


def hold(t_samples: NDArray[np.float64], values: NDArray[Any],
         grid: NDArray[np.float64]) -> tuple[NDArray[Any], NDArray[np.bool_]]:
    """Sample-and-hold ``values`` (K, ...) taken at ``t_samples`` (K,) onto ``grid`` (M,).

    Returns (held values (M, ...), valid (M,)): ``valid`` is False before the first sample (those rows
    hold the first sample's value so that the array stays finite; callers mask them).
    """
    t = np.asarray(t_samples, dtype=float)
    if t.size == 0:
        return np.zeros((grid.size,) + values.shape[1:]), np.zeros(grid.size, dtype=bool)
    if np.any(np.diff(t) < 0):  # logs are ordered; a stable sort keeps equal stamps in logged order
        order = np.argsort(t, kind="stable")
        t, values = t[order], values[order]
    idx = np.searchsorted(t, grid, side="right") - 1
    valid = idx >= 0
    return values[np.maximum(idx, 0)], valid
