"""The wind-model interface, its input checks, and the registry of named wind presets.

A wind model is a small class with one job: given time, the sample points (vehicle CoM and rotor
hubs) and the vehicle velocity, return the wind velocity at those points.  Batch-first: N
independent vehicles/fields, each with its own random stream; N = 1 is a batch of one (one law).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.arrays import as_f64
from fawtgym.core.checks import check_number, listed, shown

#: Longest wind step [s].  The gust filters are exact at any step, but their step-matrix table holds air
#: travel ``V dt`` up to 200 m (:mod:`.dryden_discrete`): 1 s covers airspeeds up to 200 m/s.  A step of
#: seconds is no simulation step (the env's control step is 1-50 ms).
DT_MAX = 1.0


def check_dt(dt: Any) -> float:
    """A wind step ``0 < dt <=`` :data:`DT_MAX` [s] as a float (:func:`~fawtgym.core.checks.check_number`'s
    ValueError naming it otherwise)."""
    return check_number(dt, "dt", maximum=DT_MAX, minimum=0.0, note="s (a wind step)")


def check_step(t: float, dt: float) -> None:
    """ValueError naming the value unless ``t`` is a finite time [s] and ``dt`` a wind step (:func:`check_dt`)."""
    check_dt(dt)
    check_number(t, "t", note="(the time in s)")


def check_points(points_ned: Any, velocity_ned: Any, n: int, finite: bool = True
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(points (N, K, 3), velocities (N, 3))`` as float64; ValueError naming the bad value if malformed.

    ``finite=False`` skips the finiteness check (a kernel that checks it itself calls :func:`raise_not_finite`).
    """
    if n < 1:
        raise RuntimeError("wind step before reset(n, seed)")
    points = as_f64(points_ned, "points_ned")
    velocity = as_f64(velocity_ned, "vehicle_velocity_ned")
    if points.ndim != 3 or points.shape[0] != n or points.shape[2] != 3 or points.shape[1] < 1:
        raise ValueError(f"points_ned must have shape ({n}, K, 3), got {points.shape}")
    if velocity.shape != (n, 3):
        raise ValueError(f"vehicle_velocity_ned must have shape ({n}, 3), got {velocity.shape}")
    if finite and not math.isfinite(float(points.sum()) + float(velocity.sum())):
        raise_not_finite(points, velocity)
    return points, velocity


def raise_not_finite(points: NDArray[np.float64], velocity: NDArray[np.float64]) -> None:
    """ValueError naming the first non-finite point or velocity (the same text at every N)."""
    bad_p = ~np.isfinite(points)
    if bad_p.any():
        raise ValueError(f"points_ned must be finite, got {points[np.nonzero(bad_p.any(axis=-1))][0]}")
    row = np.nonzero(~np.isfinite(velocity))[0][0]
    raise ValueError(f"vehicle_velocity_ned must be finite, got {velocity[row]}")


class WindModel(abc.ABC):
    """Wind velocity field in world NED [m/s]."""

    n: int = 0

    @abc.abstractmethod
    def reset(self, n: int, seed: int | np.random.SeedSequence | None = None) -> None:
        """Start ``n`` independent realizations; ``seed`` makes them reproducible."""

    @abc.abstractmethod
    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        """Advance to time ``t`` (by ``dt``) and return the wind at ``points_ned`` (N, K, 3) as (N, K, 3).

        ``vehicle_velocity_ned`` (N, 3) sets the frozen-turbulence airspeed of the gust filters.
        """

    def step_trusted(self, t: float, dt: float, points_ned: NDArray[np.float64],
                     vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`step` for a caller whose inputs already pass :func:`check_step` and :func:`check_points` (float
        ``t`` and ``dt``, C-contiguous float64 arrays of the right shapes: the env's own state); a model may skip
        those checks here (the same law; non-finite values are still found by its kernel).  Default: :meth:`step`."""
        return self.step(t, dt, points_ned, vehicle_velocity_ned)


def check_n(n: Any) -> int:
    """The number of fields of ``reset``: a positive int (ValueError naming it otherwise)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"number of fields n must be a positive int, got {shown(n)}")
    return int(n)


class CalmWind(WindModel):
    """Still air."""

    def reset(self, n: int, seed: int | np.random.SeedSequence | None = None) -> None:
        self.n = check_n(n)

    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        check_step(t, dt)
        points, _ = check_points(points_ned, vehicle_velocity_ned, self.n)
        return np.zeros(points.shape)

    def step_trusted(self, t: float, dt: float, points_ned: NDArray[np.float64],
                     vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.zeros(points_ned.shape)


_WIND_REGISTRY: dict[str, Callable[..., WindModel]] = {"calm": CalmWind}


def register_wind(name: str, factory: Callable[..., WindModel]) -> None:
    """Register a named wind preset (a class or a factory taking keyword options)."""
    _WIND_REGISTRY[name] = factory


def wind_names() -> list[str]:
    return sorted(_WIND_REGISTRY)


def make_wind(spec: str | WindModel | Mapping[str, Any] | None) -> WindModel:
    """A wind model from a preset name, an instance, or ``{"name": ..., **options}``."""
    if spec is None:
        return CalmWind()
    if isinstance(spec, WindModel):
        return spec
    if isinstance(spec, Mapping):
        options = dict(spec)
        if "name" not in options:
            raise ValueError(f"a wind mapping needs its 'name' (one of {wind_names()}), got {shown(spec)}")
        name = options.pop("name")
        if not isinstance(name, str) or name not in _WIND_REGISTRY:
            raise ValueError(f"unknown wind {shown(name)}; valid names: {wind_names()}")
        odd = [k for k in options if not isinstance(k, str)]
        if odd:  # (a ** call would raise Python's "keywords must be strings")
            raise ValueError(f"unknown option(s) {listed(odd)} for wind {shown(name)}: option names are strings")
        return _WIND_REGISTRY[name](**options)
    if isinstance(spec, str):
        if spec not in _WIND_REGISTRY:
            raise ValueError(f"unknown wind {shown(spec)}; valid names: {wind_names()}")
        return _WIND_REGISTRY[spec]()
    raise ValueError(f"wind must be a name, a WindModel or a mapping, got {shown(spec)} ({type(spec).__name__})")


@njit(cache=True)
def row_inputs_finite(points: NDArray[np.float64], velocity: NDArray[np.float64], i: int) -> bool:
    """Inside a wind kernel: whether row ``i``'s sample points (N, K, 3) and velocity (N, 3) are all finite (the
    kernels then return -2 before changing anything, and Python raises :func:`raise_not_finite`'s message)."""
    zero = 0.0  # sum of x * 0: +-0 if every x is finite, NaN if any is NaN/inf (no overflow, no branch per entry)
    for p in range(points.shape[1]):
        for c in range(3):
            zero += float(points[i, p, c]) * 0.0  # float(): plain Python (no numba) multiplies silently
    for c in range(3):
        zero += float(velocity[i, c]) * 0.0
    return math.isfinite(zero)
