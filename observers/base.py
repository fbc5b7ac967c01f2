"""The one interface every disturbance/state observer implements, and the observer registry.

Model (seed-000 eq. 38, ffts_eso_tse3_fawt_wang2024.txt)::

    b' = v,   m v' = m g e3 - f R e3 + phi_D,   R' = R Omega^x,   J Omega' = J Omega x Omega + tau + tau_D

with world NED / body FRD.  An observer is built from (m, J) and its gains, is reset from a
measurement and updated with the measurement and the *known applied* collective thrust ``f`` [N]
and body torque ``tau`` [N m] (``info["applied"]`` of the env).  Everything is batch-first: the
measurement arrays carry a leading axis N (see :mod:`fawtgym.envs.measurement`), ``thrust`` has
shape (N,), ``torque`` (N, 3); a single vehicle is N = 1.  No Python loop over N.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.envs.measurement import batch_measurement


@dataclasses.dataclass(frozen=True)
class ObserverEstimate:
    """What an observer reports after an update (all arrays batch-first).

    ``force``: disturbance force estimate phi_hat, world NED [N], shape (N, 3).
    ``torque``: disturbance torque estimate tau_hat, body FRD [N m], shape (N, 3).
    ``states``: the observer's own state estimates by name (e.g. ``"velocity"`` (N, 3),
    ``"attitude"`` (N, 3, 3), ``"angular_velocity"`` (N, 3)).  An observer that estimates only one
    channel reports zeros for the other; :attr:`Observer.channels` says which it estimates.
    """

    force: NDArray[np.float64]
    torque: NDArray[np.float64]
    states: Mapping[str, NDArray[np.float64]] = dataclasses.field(default_factory=dict)


class Observer(abc.ABC):
    """Base class: holds (m, J, g), validates inputs, defines reset/update."""

    #: registry name, set by :func:`register_observer`
    name: ClassVar[str] = ""
    #: which disturbance channels it estimates: subset of {"force", "torque"}
    channels: ClassVar[frozenset[str]] = frozenset({"force", "torque"})

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665) -> None:
        if not (np.isfinite(mass) and mass > 0):
            raise ValueError(f"mass must be a finite positive number, got {mass!r}")
        j = np.asarray(inertia, dtype=float)
        j = np.diag(j) if j.shape == (3,) else j
        if j.shape != (3, 3) or not np.all(np.isfinite(j)) or np.linalg.eigvalsh((j + j.T) / 2).min() <= 0:
            raise ValueError(f"inertia must be a positive-definite 3x3 matrix or 3 diagonal entries, got {inertia!r}")
        self.mass = float(mass)
        self.inertia = j
        self.inertia_inv = np.linalg.inv(j)
        self.gravity = float(gravity)

    @abc.abstractmethod
    def reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None = None,
              torque: ArrayLike | None = None) -> None:
        """Initialize the state estimates from a measurement (and optionally initial disturbance guesses)."""

    @abc.abstractmethod
    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        """Advance the observer by ``dt`` seconds and return the estimate."""

    # ---- shared input checks ----------------------------------------------------------
    @staticmethod
    def _inputs(measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
                dt: float) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.float64], NDArray[np.float64]]:
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite positive number of seconds, got {dt!r}")
        meas = batch_measurement(measurement)
        f = np.atleast_1d(np.asarray(thrust, dtype=float))
        tau = np.asarray(torque, dtype=float)
        tau = tau[None, :] if tau.ndim == 1 else tau
        if tau.shape[-1] != 3:
            raise ValueError(f"torque must have shape (3,) or (N, 3), got {tau.shape}")
        for label, arr in (("thrust", f), ("torque", tau)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{label} contains non-finite values: {arr}")
        return meas, f, tau


_REGISTRY: dict[str, type[Observer]] = {}


def register_observer(name: str) -> Callable[[type[Observer]], type[Observer]]:
    """Class decorator adding an observer to the registry under ``name``."""

    def deco(cls: type[Observer]) -> type[Observer]:
        if name in _REGISTRY and _REGISTRY[name] is not cls:
            raise ValueError(f"observer name {name!r} is already registered to {_REGISTRY[name].__name__}")
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return deco


def observer_names() -> list[str]:
    """Registered observer names (importing :mod:`fawtgym.observers` registers them all)."""
    return sorted(_REGISTRY)


def make_observer(name: str, mass: float, inertia: ArrayLike, **kwargs: Any) -> Observer:
    """Build a registered observer by name; unknown names raise ValueError listing the valid ones."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown observer {name!r}; valid names: {observer_names()}")
    return _REGISTRY[name](mass, inertia, **kwargs)
