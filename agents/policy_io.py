"""What a learned policy sees and does in the hover env: its action transforms and its observer features.

Batch-first *cores* (small classes holding only a law and its parameters), used by the training wrappers
(:mod:`fawtgym.train.wrappers`) and by the trained-policy agent (:mod:`fawtgym.agents.sb3_agent`), so a policy
flies with exactly the transforms it was trained with:

* :class:`ActionScale`: ``u`` in [-1, 1]^A -> env action, piecewise linear per entry through the hover command;
* :class:`ResidualScale`: ``clip(base + bound (high - low) / 2 u)`` on a base agent's action;
* :class:`EstimateFeatures`: an observer run on the env's infos, its force / (m g) and torque / tau_max estimates
  as features (``tau_max`` = :func:`torque_authority`), clipped to +-:data:`FEATURE_CLIP`.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import check_number, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.envs.motors import allocation_matrix
from fawtgym.envs.options import check_actions
from fawtgym.envs.vehicles import VehiclePreset

from .base import measurement_from_info, observer_step

#: features are clipped to +- this (5 m g of force, 5 times the rotors' torque authority)
FEATURE_CLIP = 5.0
#: entries appended to the observation by the observer features (force 3, torque 3)
N_FEATURES = 6


# ---- cores ----------------------------------------------------------------------------------------------------
class ActionScale:
    """Normalized action ``u`` in [-1, 1]^A -> env action, piecewise linear per entry through the hover command.

    ``a = c + u (high - c)`` for ``u >= 0`` and ``a = c + u (c - low)`` for ``u < 0``, written so that -1, 0 and +1
    give ``low``, ``center`` and ``high`` exactly; ``u`` is clipped to [-1, 1] first.  Batch-first: ``u`` (N, A) or
    (A,) for one vehicle.
    """

    def __init__(self, low: ArrayLike, high: ArrayLike, center: ArrayLike) -> None:
        self.low, self.high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        self.center = np.asarray(center, dtype=float)
        if not (np.all(self.low <= self.center) and np.all(self.center <= self.high)):
            raise ValueError(f"the centre {self.center.tolist()} must lie in the action bounds "
                             f"{self.low.tolist()} .. {self.high.tolist()}")

    def __call__(self, u: ArrayLike) -> NDArray[np.float64]:
        unit = np.clip(np.asarray(u, dtype=float), -1.0, 1.0)
        s = np.abs(unit)
        edge = np.where(unit >= 0.0, self.high, self.low)
        return self.center * (1.0 - s) + edge * s

    def inverse(self, a: ArrayLike) -> NDArray[np.float64]:
        """The normalized action of an env action (inside the bounds)."""
        d = np.asarray(a, dtype=float) - self.center
        span = np.where(d >= 0.0, self.high - self.center, self.center - self.low)
        return np.divide(d, span, out=np.zeros_like(d), where=span > 0)


class ResidualScale:
    """``a = clip(base + bound (high - low) / 2 u, low, high)`` with the policy output ``u`` clipped to [-1, 1].

    ``u = 0`` gives ``clip(base)``: exactly the base agent's action as the env applies it.
    """

    def __init__(self, low: ArrayLike, high: ArrayLike, bound: float) -> None:
        self.bound = check_number(bound, "residual bound (--residual-bound)", minimum=0.0, maximum=2.0,
                                  note="(a fraction of the action range)")
        self.low, self.high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        self.scale = self.bound * (self.high - self.low) / 2.0

    def __call__(self, base: ArrayLike, u: ArrayLike) -> NDArray[np.float64]:
        u = np.clip(np.asarray(u, dtype=float), -1.0, 1.0)
        return np.minimum(np.maximum(np.asarray(base, dtype=float) + self.scale * u, self.low), self.high)


def policy_actions(u: ArrayLike, shape: tuple[int, ...]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """A policy's normalized actions checked like the env's actions (exactly ``shape``, real, finite: NaN and inf
    refused naming the entry and the policy's [-1, 1] bounds); returns them as float64 and, per row (the last axis
    reduced), whether an entry lay outside [-1, 1] (:class:`ActionScale` and :class:`ResidualScale` clip it)."""
    ones = np.ones(shape[-1])
    checked = check_actions(u, shape, -ones, ones, name="policy actions")
    return checked, np.any(np.abs(checked) > 1.0, axis=-1)


def torque_authority(preset: VehiclePreset) -> NDArray[np.float64]:
    """Per body axis (FRD) the largest torque [N m] the rotors make, thrusts in [0, T_max] (module docstring)."""
    return preset.max_thrust_per_rotor * np.clip(allocation_matrix(preset)[1:], 0.0, None).sum(axis=1)


def observer_kwargs_for(name: str, overrides: Mapping[str, Any] | None) -> dict[str, Any]:
    """An observer's gains: the defaults the agent grammar uses for it (e.g. the FFTS-ESO flight gains), overridden."""
    from .spec import DEFAULT_OBSERVER_KWARGS

    return {**DEFAULT_OBSERVER_KWARGS.get(name, {}), **dict(overrides or {})}


def build_observer(name: Any, preset: VehiclePreset, observer_kwargs: Mapping[str, Any] | None = None) -> Any:
    """A registered observer by name for the nominal ``preset`` (default gains of :func:`observer_kwargs_for`), or an
    Observer instance as is; ValueError (one line) naming the observer for a bad name or gain."""
    import fawtgym.observers  # noqa: F401  (registers every observer)
    from fawtgym.observers.base import Observer, make_observer

    if isinstance(name, Observer):
        if observer_kwargs:
            raise ValueError("observer_kwargs is only used when the observer is given by name")
        return name
    if not isinstance(name, str):
        raise ValueError(f"observer must be a registered name or an Observer, got {type(name).__name__}")
    kwargs = observer_kwargs_for(name, observer_kwargs)
    try:
        return make_observer(name, preset.mass, preset.inertia_matrix, **kwargs)
    except TypeError as exc:
        from fawtgym.observers.base import observer_options

        gains = observer_options(name) or ()
        raise ValueError(f"observer {shown(name)}: {str(exc).splitlines()[0]}; its gains: {', '.join(gains)}") from exc


class EstimateFeatures:
    """An observer run on the env's infos and its estimates as scaled features (N, 6) float32 (module docstring).

    ``observer``: a registered name (built for the nominal ``preset`` with :func:`observer_kwargs_for`) or an
    Observer.  ``dt``: the observer's step, the env's control period.
    """

    def __init__(self, observer: Any, preset: VehiclePreset, dt: float,
                 observer_kwargs: Mapping[str, Any] | None = None, clip: float = FEATURE_CLIP) -> None:
        self.observer = build_observer(observer, preset, observer_kwargs)
        self.preset = preset
        self.dt = float(dt)
        self.clip = float(clip)
        self.weight = preset.mass * GRAVITY
        self.inv_scale = 1.0 / np.concatenate([[self.weight] * 3, torque_authority(preset)])
        #: the latest (force (N, 3), torque (N, 3)) estimates of :meth:`update`
        self.last: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def space(self) -> spaces.Box:
        """The features' box (6,) float32."""
        return spaces.Box(-self.clip, self.clip, shape=(N_FEATURES,), dtype=np.float32)

    def scale(self, force: ArrayLike, torque: ArrayLike) -> NDArray[np.float32]:
        """Features (N, 6) of force (N, 3) [N] and torque (N, 3) [N m] estimates."""
        x = np.concatenate([np.asarray(force, dtype=float).reshape(-1, 3),
                            np.asarray(torque, dtype=float).reshape(-1, 3)], axis=1) * self.inv_scale
        return np.clip(x, -self.clip, self.clip).astype(np.float32)

    def reset(self, info: Mapping[str, Any], rows: NDArray[np.bool_] | None = None) -> None:
        """Reset the observer from ``info``'s measurement: every row, or the rows of the bool mask ``rows``."""
        meas, _ = measurement_from_info(info)
        self.observer.reset(meas, rows=rows)

    def update(self, info: Mapping[str, Any], observer: Any = None) -> NDArray[np.float32]:
        """Update the observer (or ``observer``) with ``info`` (one step) and return the features (N, 6)."""
        meas, _ = measurement_from_info(info)
        force, tau = observer_step(self.observer if observer is None else observer, meas, info, self.dt, self.weight)
        if observer is None:
            self.last = (force, tau)
        return self.scale(force, tau)

    def peek(self, info: Mapping[str, Any]) -> NDArray[np.float32]:
        """The features an update with ``info`` would give, from a copy of the observer (its state not advanced)."""
        return self.update(info, copy.deepcopy(self.observer))


def shares_observer(residual_base: str, obs: str, observer: str, observer_kwargs: Mapping[str, Any] | None) -> bool:
    """Whether a residual policy's features come from its base agent's own observer: ``obs`` is ``state+eso`` and the
    base is ``px4+<observer>`` with the same observer and gains (one observer, not two)."""
    from .spec import observer_kwargs_of, parse_agent

    spec = parse_agent(residual_base)
    return (obs == "state+eso" and spec.kind == "px4+observer" and spec.observer == observer
            and dict(observer_kwargs_of(spec)) == observer_kwargs_for(observer, observer_kwargs))
