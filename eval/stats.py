"""Uncertainty of leaderboard numbers: bootstrap intervals of means, paired differences, binomial intervals.

* :func:`mean_ci`: the mean of per-seed values with a 95 % bias-corrected and accelerated (BCa)
  bootstrap interval (``scipy.stats.bootstrap``; percentile bootstrap where BCa is degenerate, a point
  interval when every value is equal, no interval for one value).
* :func:`paired_difference`: the mean of per-seed differences ``agent - baseline`` over the seeds
  both flew to the end (same wind and sensor noise per seed: a paired comparison), with the same
  bootstrap interval; and the relative change of the means.
* :func:`failure_rate`: ``k`` failures in ``n`` episodes with the Wilson score interval
  (``scipy.stats.binomtest(...).proportion_ci(method="wilson")``).

Resampling uses a fixed generator, so the same values give the same interval, bitwise.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence

import numpy as np
from scipy import stats

CONFIDENCE = 0.95
N_RESAMPLES = 9999
_SEED = 20240


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A value with its confidence interval (``low``/``high`` None when the sample cannot give one)."""

    value: float | None
    low: float | None
    high: float | None
    n: int

    def to_dict(self) -> dict[str, float | int | None]:
        return dataclasses.asdict(self)


def _finite(values: Sequence[float | None]) -> np.ndarray:
    return np.array([v for v in values if v is not None and math.isfinite(v)], dtype=float)


def mean_ci(values: Sequence[float | None], confidence: float = CONFIDENCE) -> Estimate:
    """Mean of the finite values and its bootstrap interval (module docstring)."""
    x = _finite(values)
    if x.size == 0:
        return Estimate(None, None, None, 0)
    m = float(np.mean(x))
    if x.size == 1:
        return Estimate(m, None, None, 1)
    if np.all(x == x[0]):
        return Estimate(m, m, m, int(x.size))
    lo = hi = math.nan
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = stats.bootstrap((x,), np.mean, confidence_level=confidence, n_resamples=N_RESAMPLES,
                                  method=method, vectorized=True, rng=np.random.default_rng(_SEED))
        lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if math.isfinite(lo) and math.isfinite(hi):
            break
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return Estimate(m, None, None, int(x.size))
    return Estimate(m, min(lo, m), max(hi, m), int(x.size))


def paired_difference(agent: Sequence[float | None], baseline: Sequence[float | None],
                      confidence: float = CONFIDENCE) -> tuple[Estimate, float | None]:
    """(mean of ``agent - baseline`` over seeds both have, with its interval; relative change of the means).

    The relative change is ``mean(agent) / mean(baseline) - 1`` over the same seeds (negative = smaller).
    """
    if len(agent) != len(baseline):
        raise ValueError(f"paired values need the same seeds: {len(agent)} != {len(baseline)}")
    pairs = [(a, b) for a, b in zip(agent, baseline, strict=True)
             if a is not None and b is not None and math.isfinite(a) and math.isfinite(b)]
    if not pairs:
        return Estimate(None, None, None, 0), None
    a = np.array([p[0] for p in pairs])
    b = np.array([p[1] for p in pairs])
    rel = float(a.mean() / b.mean() - 1.0) if b.mean() != 0 else None
    return mean_ci(list(a - b), confidence), rel


def failure_rate(failures: int, n: int, confidence: float = CONFIDENCE) -> Estimate:
    """``failures / n`` with its Wilson score interval."""
    if n <= 0:
        return Estimate(None, None, None, 0)
    ci = stats.binomtest(int(failures), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return Estimate(failures / n, float(ci.low), float(ci.high), int(n))
