"""The common agent API used by the leaderboard, the reproductions and the SITL hook.

An agent turns what the env reports into an action, with the same two calls for every controller
(PX4-style cascade, PX4 + observer feedforward, SB3 policy)::

    agent.reset(info, seed=None)              # after env.reset(): info = the reset info
    action = agent.act(observation, info)     # after every env.step(): info = that step's info
    agent.reset(info, rows=mask)              # rows of a batched env that started a new episode (bool (N,))

``info`` is the env's info dict; agents read only the *sensor* side of it:
``info["measurement"]`` (keys in :mod:`fawtgym.core.measurement`), ``info["applied"]`` (the
collective thrust [N] and body torque [N m] applied over the step just taken -- the known inputs of
an observer) and, if present, ``info["setpoint"]`` (NED position setpoint).  ``info["truth"]`` is for
metrics only and agents must not read it.

Batch-first: every array in ``info`` may carry a leading batch axis N (a vector of vehicles) or not
(a single env).  ``act`` returns actions of matching shape: ``(N, A)`` for batched input, ``(A,)`` for
a single env.  The helpers below do that bookkeeping.  Rows of a batched env end at different times
(``HoverBatchEnv`` resets a finished row on the next step): ``reset(info, rows=mask)`` must then give
the rows of ``mask`` exactly a fresh agent's state and leave the other rows untouched.

Agents are named by the grammar of :mod:`fawtgym.agents.spec` (``px4``, ``px4+ffts_eso``, a user's
``module:Class``) and built for an env by ``Class.for_env(env, **kwargs)``.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.arrays import REAL_KINDS, as_array
from fawtgym.core.checks import shown
from fawtgym.core.measurement import batch_measurement


class Agent(abc.ABC):
    """Base class of every agent: ``reset(info, seed)`` then ``act(observation, info)`` each step."""

    #: the env action type this agent emits (``"motors"`` or ``"ctbr"``)
    action_type: str = "motors"

    @classmethod
    def for_env(cls, env: Any, **kwargs: Any) -> Agent:
        """An agent matched to ``env`` (the plugin entry point of the agent grammar); default ``cls(**kwargs)``."""
        return cls(**kwargs)

    @abc.abstractmethod
    def reset(self, info: Mapping[str, Any], seed: int | None = None, rows: ArrayLike | None = None) -> None:
        """Start an episode from the env's reset ``info`` (``seed`` for any internal randomness).

        ``rows``: None for every row, or a bool mask (N,) of the rows that start a new episode (the others
        keep their state); ``info`` then holds all N rows.
        """

    @abc.abstractmethod
    def act(self, observation: Any, info: Mapping[str, Any]) -> NDArray[np.float64]:
        """The action for the current step: shape (A,) for a single env, (N, A) for N vehicles."""

    def disturbance_estimate(self) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        """The latest (force (N, 3) world NED [N], torque (N, 3) body FRD [N m]) disturbance estimates of
        the agent's observer, None for a channel it does not estimate (the default: no observer)."""
        return None, None

    def __call__(self, observation: Any, info: Mapping[str, Any]) -> NDArray[np.float64]:
        return self.act(observation, info)


def measurement_from_info(info: Mapping[str, Any], keys: tuple[str, ...] | None = None,
                          required: tuple[str, ...] = (), who: str = "agent") -> tuple[dict[str, NDArray[np.float64]],
                                                                                       bool]:
    """``(measurement with a batch axis, was_batched)`` from an env info dict (only ``keys``, if given: the keys
    an agent reads; those absent from the info are left out).

    Raises ValueError if ``info`` has no ``"measurement"`` mapping, or if it has no ``"position"``: with the keys
    the agent ``who`` needs, ``required`` (``"position"`` first), the observers' message
    (:func:`refuse_measurement`: ``"<who>: measurement needs the keys [...]; missing [...]"``).
    """
    # type(...) is dict first: the env's plain dicts skip the (slower) ABC isinstance check
    raw = info.get("measurement") if type(info) is dict or isinstance(info, Mapping) else None
    if type(raw) is not dict and not isinstance(raw, Mapping):
        raise ValueError("agent needs the env's info dict with an info['measurement'] mapping "
                         f"(keys: position, velocity, attitude, angular_velocity, ...); got {type(info).__name__}"
                         + (f" with keys {sorted(info)}" if isinstance(info, Mapping) else ""))
    if "position" not in raw:
        if required:
            refuse_measurement(raw, required, 1, who)
        raise ValueError(f"info['measurement'] has no 'position'; keys: {sorted(raw)}")
    pos = raw["position"]
    batched = (pos.ndim if type(pos) is np.ndarray else np.ndim(pos)) == 2
    return batch_measurement(raw, keys, who), batched


def refuse_measurement(measurement: Mapping[str, Any], keys: tuple[str, ...], n: int, who: str) -> None:
    """Raise the one-line error the observers give for what is wrong with ``measurement`` (a key of ``keys``
    missing, a wrong shape or row count, a value not real, a non-finite entry, an attitude that is not a rotation):
    :func:`fawtgym.observers.base.check_measurement` with ``who`` (the agent's name), so the text is written once
    and reads the same at every N.  Returns if it finds nothing wrong.  For error paths only (a Python check of
    every key, ~1-2 us at N = 1): an agent's hot path reads a status code of its kernel and calls this to word it.
    """
    from fawtgym.observers.base import check_measurement  # agents -> observers; imported only when refusing

    check_measurement(measurement, keys, n, who)


_F64 = np.dtype(np.float64)
_MISSING = object()


def applied_from_info(info: Mapping[str, Any], n: int, default_thrust: float) -> tuple[NDArray[np.float64],
                                                                                       NDArray[np.float64]]:
    """Applied collective thrust (n,) [N] and body torque (n, 3) [N m] from ``info["applied"]``.

    Before the first step (or if the env does not report it) the hover thrust ``default_thrust`` and
    zero torque are returned.  The single env's scalar thrust and (3,) torque become (1,) / (1, 3) arrays (the
    torque a view, not a copy).
    """
    applied = info.get("applied") if type(info) is dict or isinstance(info, Mapping) else None
    if type(applied) is dict or isinstance(applied, Mapping):
        thrust, torque = applied.get("thrust", _MISSING), applied.get("torque", _MISSING)
    elif applied is None:
        thrust = torque = _MISSING
    else:
        raise ValueError(f"info['applied'] must be a mapping with 'thrust' (N,) [N] and 'torque' (N, 3) [N m], got "
                         f"{shown(applied)}")
    if thrust is _MISSING or torque is _MISSING:
        return np.full(n, float(default_thrust)), np.zeros((n, 3))
    if n == 1 and type(thrust) is float and type(torque) is np.ndarray and torque.dtype is _F64 \
            and torque.shape == (3,):  # the single env's (the common case): (1,) and a (1, 3) view
        return np.array((thrust,)), torque[None]
    thrust = _applied_array(thrust, "thrust", n, ())
    if type(torque) is not np.ndarray or torque.dtype is not _F64 or torque.shape != (n, 3):
        torque = _applied_array(torque, "torque", n, (3,))
    return thrust, torque


def _applied_array(value: Any, key: str, n: int, trailing: tuple[int, ...]) -> NDArray[np.float64]:
    """``info["applied"][key]`` as a float64 (n, *trailing) array: n rows, or one row for every vehicle (a view when
    it already holds n rows); ValueError / TypeError naming it if it is not real numbers of such a shape."""
    a = as_array(value)
    if a.dtype.kind not in REAL_KINDS:
        raise TypeError(f"info['applied'][{shown(key)}] must hold real numbers, got {shown(value)}")
    a = a.astype(float, copy=False)
    size = math.prod(trailing)
    if a.size == n * size:
        return a.reshape((n, *trailing))
    if a.size == size:
        return np.broadcast_to(a.reshape(trailing), (n, *trailing)).copy()
    what = "one value per vehicle (N = {n}) or one for all" if not trailing else \
        "3 values per vehicle (N = {n}) or 3 for all"
    raise ValueError(f"info['applied'][{shown(key)}] must hold {what.format(n=n)}, got shape {a.shape}")


def observer_step(observer: Any, meas: Mapping[str, NDArray[np.float64]], info: Mapping[str, Any], dt: float,
                  weight: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One update of ``observer`` with a batched measurement and the known inputs of ``info["applied"]`` (hover
    thrust ``weight`` [N] and zero torque before the first step); returns (force (N, 3), torque (N, 3)).

    Raises FloatingPointError naming the observer if an estimate is not finite.
    """
    n = meas["position"].shape[0]
    thrust, torque = applied_from_info(info, n, weight)
    est = observer.update(meas, thrust, torque, dt)
    force = np.asarray(est.force, dtype=float).reshape(n, 3)
    tau = np.asarray(est.torque, dtype=float).reshape(n, 3)
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(tau))):
        raise FloatingPointError(f"observer {shown(observer.name)} returned a non-finite estimate")
    return force, tau


def match_batch(action: NDArray[np.float64], batched: bool) -> NDArray[np.float64]:
    """Drop the batch axis of an (N, A) action when the input was not batched (N must then be 1)."""
    if batched:
        return action
    if action.shape[0] != 1:
        raise ValueError(f"unbatched input but {action.shape[0]} actions were computed")
    return action[0]
