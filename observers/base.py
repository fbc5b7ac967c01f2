"""The one interface every disturbance/state observer implements, and the observer registry.

Model (Wang et al. (2024) eq. 38)::

    b' = v,   m v' = m g e3 - f R e3 + phi_D,   R' = R Omega^x,   J Omega' = J Omega x Omega + tau + tau_D

with world NED / body FRD.  An observer is built from (m, J) and its gains, is reset from a
measurement and updated with the measurement and the *known applied* collective thrust ``f`` [N]
and body torque ``tau`` [N m] (``info["applied"]`` of the env).  Everything is batch-first: the
measurement arrays carry a leading axis N (see :mod:`fawtgym.core.measurement`), ``thrust`` has
shape (N,), ``torque`` (N, 3); a single vehicle is N = 1.  No Python loop over N.

Per-row reset.  Rows of a batched env end at different times, so ``reset(measurement, rows=mask)``
re-initializes only the rows where the bool mask (N,) is True: they get exactly the state a freshly
built observer reset on those rows' measurements would have, the other rows keep theirs bitwise.
Every observer keeps its state in arrays with a leading row axis, so this is a masked write
(:func:`fawtgym.core.rows.write_rows`); :meth:`Observer.reset` validates the request once for every observer, and a
subclass implements :meth:`Observer._reset`, which builds the fresh state of the rows it is given.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.measurement import TRAILING_SHAPES, batch_measurement
from fawtgym.core.rows import check_row_mask


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
    """Base class: holds (m, J, g), validates inputs, defines reset/update.

    A subclass implements :meth:`_reset` (the fresh state of the rows of a measurement, written with
    :func:`write_rows`) and :meth:`update`; :meth:`reset` is the public entry point for both a full and a
    per-row reset and does the checks they share.
    """

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
        #: rows N of the state, set by the last full reset (None before it)
        self._n_rows: int | None = None

    def reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None = None,
              torque: ArrayLike | None = None, *, rows: ArrayLike | None = None, **options: Any) -> None:
        """Initialize the state estimates from a measurement (and optionally initial disturbance guesses).

        ``measurement``: batch-first mapping (:mod:`fawtgym.core.measurement`) with the keys the observer
        needs; ``force`` / ``torque``: initial guesses of phi_D (world NED) / tau_D (body FRD), shape (3,)
        (every row) or (N, 3), default zero (an observer that does not estimate a channel ignores its guess).

        ``rows``: None (default) resets every row; the batch size N of ``measurement`` becomes the
        observer's N (it may differ from the previous one).  A bool array of shape (N,) resets only the
        rows where it is True: ``measurement`` (and an (N, 3) guess) still holds all N rows of the
        observer's batch, the rows where the mask is True get exactly the state a freshly built observer
        reset on those rows' measurements (and guesses) would have -- only their measurement is read, the
        other rows' may be anything, e.g. non-finite -- and the rows where it is False keep their state
        bitwise.  An all-False mask changes nothing; an all-True mask is a full reset.  At N = 1 a mask
        is all or nothing, so it never reaches a float fast path half-way.

        Raises ValueError (one line; the same text at every N apart from the sizes it names) when
        ``rows`` is given before any full reset, is not a bool array of shape (N,), or ``measurement``
        (or a guess) does not hold N rows; the state is then unchanged.  ``options`` are observer-specific
        reset options (e.g. ``thrust`` of the QB observer).
        """
        if rows is None:
            self._n_rows = self._reset(measurement, force, torque, None, **options)
            return
        who = self.name or type(self).__name__
        if self._n_rows is None:
            raise ValueError(f"{who}: reset(measurement, rows=mask) selects rows of the batch set by a full "
                             "reset; call reset(measurement) once first")
        n = self._n_rows
        mask = check_row_mask(rows, n, who)
        meas = batch_measurement(measurement)
        for key, value in meas.items():
            if key in TRAILING_SHAPES and value.shape[0] != n:
                raise ValueError(f"{who}: reset(rows=mask) needs the measurement of all {n} rows of the batch (the "
                                 f"mask selects among them); measurement[{key!r}] has {value.shape[0]} rows")
        force_rows = _guess_rows(force, n, mask, "force", who)
        torque_rows = _guess_rows(torque, n, mask, "torque", who)
        if not mask.any():
            return
        if mask.all():
            self.reset(measurement, force, torque, **options)
            return
        sub = {k: (v[mask] if k in TRAILING_SHAPES else v) for k, v in meas.items()}
        self._reset(sub, force_rows, torque_rows, mask, **options)

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None, **options: Any) -> int:
        """Build the fresh state of the rows of ``measurement`` (and the guesses) and store it.

        ``rows`` None: a full reset, the fresh state replaces the state.  Else ``rows`` is the observer's
        bool mask (N,) with both values present, ``measurement`` holds only the masked rows (already
        checked to be rows of this batch) and ``force`` / ``torque`` are None, (3,) or one row per masked
        row; store ``write_rows(state, fresh, rows)``, after bringing any float cache of the state up to
        date, and build the fresh state completely before writing it (an error leaves the state as it
        was).  Returns the number of rows of ``measurement``.
        """
        raise NotImplementedError(f"{type(self).__name__} must implement _reset (or override reset)")

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


def _guess_rows(guess: ArrayLike | None, n: int, rows: NDArray[np.bool_], label: str,
                who: str) -> NDArray[np.float64] | None:
    """An initial guess of a per-row reset: None, (3,) as is, or (n, 3) -> its masked rows."""
    if guess is None:
        return None
    g = np.asarray(guess, dtype=float)
    if g.shape not in ((3,), (n, 3)) or not np.all(np.isfinite(g)):
        raise ValueError(f"{who}: initial {label} guess must be finite with shape (3,) (every row) or ({n}, 3) (one "
                         f"per row of the batch), got shape {g.shape}")
    return g if g.ndim == 1 else g[rows]


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


def observer_class(name: str) -> type[Observer]:
    """The class registered under ``name``; ValueError listing the valid names otherwise."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown observer {name!r}; valid names: {observer_names()}")
    return _REGISTRY[name]


def observer_names() -> list[str]:
    """Registered observer names (importing :mod:`fawtgym.observers` registers them all)."""
    return sorted(_REGISTRY)


def make_observer(name: str, mass: float, inertia: ArrayLike, **kwargs: Any) -> Observer:
    """Build a registered observer by name; unknown names raise ValueError listing the valid ones."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown observer {name!r}; valid names: {observer_names()}")
    return _REGISTRY[name](mass, inertia, **kwargs)
