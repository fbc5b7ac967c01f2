"""The wind-model interface and the registry of named wind presets.

A wind model is a small class with one job: given time, the sample points (vehicle CoM and rotor
hubs) and the vehicle velocity, return the wind velocity at those points.  Batch-first: N
independent vehicles/fields, each with its own random stream.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray


class WindModel(abc.ABC):
    """Wind velocity field in world NED [m/s]."""

    @abc.abstractmethod
    def reset(self, n: int, seed: int | np.random.SeedSequence | None = None) -> None:
        """Start ``n`` independent realizations; ``seed`` makes them reproducible."""

    @abc.abstractmethod
    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        """Advance to time ``t`` (by ``dt``) and return the wind at ``points_ned`` (N, K, 3) as (N, K, 3).

        ``vehicle_velocity_ned`` (N, 3) sets the frozen-turbulence airspeed of the gust filters.
        """

    def step_floats(self, t: float, dt: float, points_ned: list[float], vehicle_velocity_ned: list[float]
                    ) -> list[float]:
        """:meth:`step` for one vehicle (``reset(1)``) on plain floats: K points flat (3 K) in, the wind flat out.

        The single env's hot path; models with a float fast path override it (tested equal to :meth:`step`).
        """
        pts = np.array(points_ned, dtype=float).reshape(1, -1, 3)
        return self.step(t, dt, pts, np.array([vehicle_velocity_ned], dtype=float)).ravel().tolist()


class CalmWind(WindModel):
    """Still air."""

    def reset(self, n: int, seed: int | np.random.SeedSequence | None = None) -> None:
        self.n = n

    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.zeros(np.shape(points_ned))

    def step_floats(self, t: float, dt: float, points_ned: list[float], vehicle_velocity_ned: list[float]
                    ) -> list[float]:
        return [0.0] * len(points_ned)


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
        name = options.pop("name", None)
        if name not in _WIND_REGISTRY:
            raise ValueError(f"unknown wind {name!r}; valid names: {wind_names()}")
        return _WIND_REGISTRY[name](**options)
    if isinstance(spec, str):
        if spec not in _WIND_REGISTRY:
            raise ValueError(f"unknown wind {spec!r}; valid names: {wind_names()}")
        return _WIND_REGISTRY[spec]()
    raise TypeError(f"wind must be a name, a WindModel or a mapping, got {type(spec).__name__}")
