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

import dataclasses
import inspect
import math
from collections.abc import Callable, Iterator, Mapping
from operator import itemgetter
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.arrays import REAL_KINDS, as_array
from fawtgym.core.checks import check_known, check_number, keyword_names, listed, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.kernel_types import TYPED_DISPATCH, compile_only
from fawtgym.core.measurement import ATTITUDE, TRAILING_SHAPES, batch_measurement
from fawtgym.core.rows import check_row_mask
from fawtgym.core.so3_kernels import first_non_rotation
from fawtgym.observers._checks import (
    INPUT_CHECKS,
    ROTATION_TOL,
    first_bad_estimate,
    first_bad_wrench,
    first_nonfinite_input,
    first_nonfinite_row,
)

#: the smallest positive float (a subnormal): as an inclusive lower bound of dt it means dt > 0
SMALLEST_DT = math.ulp(0.0)

#: the shortest update step [s] of a law that divides by dt (a finite difference, a first-order hold): below it the
#: quotient overflows or swamps the estimate (a subnormal dt gives inf); no env or flight log steps faster than 1 ns
DIVIDING_MIN_DT = 1e-9


@dataclasses.dataclass
class ObserverEstimate:
    """What an observer reports after an update (all arrays batch-first).

    ``force``: disturbance force estimate phi_hat, world NED [N], shape (N, 3).
    ``torque``: disturbance torque estimate tau_hat, body FRD [N m], shape (N, 3).
    ``states``: the observer's own state estimates by name (e.g. ``"velocity"`` (N, 3),
    ``"attitude"`` (N, 3, 3), ``"angular_velocity"`` (N, 3)).  An observer that estimates only one
    channel reports zeros for the other; :attr:`Observer.channels` says which it estimates.

    The arrays are the caller's: no observer keeps a reference to them.  (A plain dataclass, not a frozen one:
    building a frozen dataclass costs 0.5 us more, a twentieth of an update's budget at N = 1.)
    """

    force: NDArray[np.float64]
    torque: NDArray[np.float64]
    states: Mapping[str, NDArray[np.float64]] = dataclasses.field(default_factory=dict)


#: :meth:`Observer.snapshot` of an observer that keeps no ``_state`` (nothing to take back)
_NO_SNAPSHOT = object()


class BufferStates(Mapping[str, NDArray[np.float64]]):
    """The ``states`` of an estimate whose arrays are all column blocks of one kernel buffer (N, k).

    ``layout`` maps each state's name to (first column, last column + 1 or None for the rest, trailing shape); the views
    ``buffer[:, a:b].reshape(N, *shape)`` are made on first access (building six views costs about a
    microsecond, a tenth of an update's budget at N = 1, and the agent reads only force and torque).
    :meth:`Observer._check_estimate` checks the whole buffer in one pass without making them.
    """

    __slots__ = ("buffer", "_layout", "_views")

    def __init__(self, buffer: NDArray[np.float64],
                 layout: Mapping[str, tuple[int, int | None, tuple[int, ...]]],
                 views: dict[str, NDArray[np.float64]] | None = None) -> None:
        self.buffer = buffer
        self._layout = layout
        #: every state's view, once made (``views``: already made by the caller, in the layout's order)
        self._views = views

    def _all(self) -> dict[str, NDArray[np.float64]]:
        views = self._views
        if views is None:
            buf = self.buffer
            n = buf.shape[0]
            views = self._views = {name: buf[:, a:b].reshape((n, *shape)) for name, (a, b, shape)
                                   in self._layout.items()}
        return views

    def __getitem__(self, key: str) -> NDArray[np.float64]:
        return self._all()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._layout)

    def __len__(self) -> int:
        return len(self._layout)

    def __repr__(self) -> str:
        return repr(self._all())


class Observer:
    """Base class: holds (m, J, g), validates inputs, defines reset/update.

    A subclass implements :meth:`_reset` (the fresh state of the rows of a measurement, written with
    :func:`write_rows`) and :meth:`_update` (the law: the estimate and the new state, from checked inputs);
    :meth:`reset` and :meth:`update` are the public entry points and do every check, once, for every observer
    (the same message and exception type at every N).  A subclass states :attr:`required_keys` and
    :attr:`max_dt`.
    """

    #: registry name, set by :func:`register_observer`
    name: ClassVar[str] = ""
    #: which disturbance channels it estimates: subset of {"force", "torque"}
    channels: frozenset[str] = frozenset({"force", "torque"})
    #: measurement keys the law reads: :meth:`update` (and :meth:`reset`) check them (present, N rows of the
    #: shape of :mod:`fawtgym.core.measurement`, real, finite; ``"attitude"`` a rotation).  A subclass states
    #: them (an instance whose keys depend on its options sets ``self.required_keys`` in ``__init__``).
    required_keys: tuple[str, ...] = ()
    #: the largest update step dt [s] the observer's discretisation is documented for; each observer states its
    #: own, derived from its design rate / the stability of its discretisation (an instance may set a bound
    #: that depends on its gains).  The base value, 0.1 s, is a fallback for an observer that states none.
    max_dt: float = 0.1
    #: the shortest update step dt [s] (inclusive).  The default, the smallest positive float, accepts every dt > 0;
    #: an observer whose law divides by dt states :data:`DIVIDING_MIN_DT` and the reason (:attr:`min_dt_reason`,
    #: named in the dt error)
    min_dt: float = SMALLEST_DT
    #: why :attr:`min_dt` (a few words, e.g. "the finite difference divides by dt"); empty for the default
    min_dt_reason: str = ""
    #: an estimated force component above this many vehicle weights (m g) counts as divergence
    MAX_FORCE_WEIGHTS: ClassVar[float] = 1e3
    #: an estimated torque component above this angular acceleration [rad/s^2] times the largest principal
    #: inertia counts as divergence
    MAX_ANGULAR_ACCELERATION: ClassVar[float] = 1e5
    #: reset options besides the guesses ``force`` / ``torque`` and ``rows``: name -> trailing shape of one row's
    #: value (a number or one per row, checked by :meth:`reset` as the guesses are; the QB observer's ``thrust``)
    reset_options: ClassVar[Mapping[str, tuple[int, ...]]] = {}
    #: whether :meth:`update` may take :meth:`_update_checked` (set per class by :meth:`__init_subclass__`)
    _checked_path: ClassVar[bool] = False
    #: (:attr:`required_keys`, their check kernel, the kernel's argument order): :func:`_input_checks` of the keys,
    #: with the instance's own keys object (``update`` compares it by identity)
    _input_checks: tuple[tuple[str, ...] | None, Any, Any] = (None, None, None)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """A class's :meth:`_update_checked` (the law and the checks in one compiled call) stands for :meth:`_update`,
        :meth:`_check_estimate` and :meth:`_commit` of the class that wrote it: a subclass that overrides any of the
        three (after it) goes the general path, so its overrides run."""
        super().__init_subclass__(**kwargs)
        owner = next(c for c in cls.__mro__ if "_update_checked" in c.__dict__)
        cls._checked_path = owner is not Observer and all(
            getattr(cls, hook) is getattr(owner, hook) for hook in ("_update", "_check_estimate", "_commit"))

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = GRAVITY) -> None:
        """``mass`` [kg]: a real number in :data:`MASS_RANGE`; ``gravity`` [m/s^2]: a real number in
        [:data:`MIN_GRAVITY`, :data:`MAX_GRAVITY`]; ``inertia`` [kg m^2]: a symmetric-part positive-definite 3x3 matrix
        of real numbers, or its 3 diagonal entries, each principal moment a body of this mass can have (radius of
        gyration in :data:`RADIUS_OF_GYRATION`).  Else one-line ValueError naming the argument and what is allowed.

        The bounds are physical, far outside any multicopter, and keep the laws in float range: the divergence bounds
        (:meth:`estimate_bounds`) scale with m g and the inertia, so a subnormal gravity or inertia (accepted as > 0
        before) made every update of a hovering vehicle "diverge"."""
        who = self.name or type(self).__name__
        self.mass = check_number(mass, f"{who}: mass", minimum=MASS_RANGE[0], maximum=MASS_RANGE[1],
                                 inclusive_minimum=True, note="kg")
        self.gravity = check_number(gravity, f"{who}: gravity", minimum=MIN_GRAVITY, maximum=MAX_GRAVITY,
                                    inclusive_minimum=True, note="m/s^2")
        j = _inertia_matrix(inertia, who, self.mass)
        self.inertia = j
        self.inertia_inv = np.linalg.inv(j)
        self._j_max = float(np.linalg.eigvalsh((j + j.T) / 2).max())
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
        bitwise.  An all-False mask changes nothing; an all-True mask is a full reset.

        Raises ValueError (one line; the same text at every N apart from the sizes it names, and for every
        observer) when ``rows`` is given before any full reset, is not a bool array of shape (N,), or
        ``measurement`` does not hold N rows, or a guess is not real numbers (bool, complex, str refused) of
        shape (3,) or (N, 3), all finite and within its channel's divergence bound (:meth:`estimate_bounds`: a
        larger guess would make every later update raise) (:func:`check_guess`); the state is then unchanged.
        ``options`` are the observer-specific reset options of :attr:`reset_options` (e.g. ``thrust`` of the QB
        observer: a number or one per row, checked the same way); any other keyword -> TypeError naming it and the
        allowed ones, the same text for every observer.
        """
        who = self.name or type(self).__name__
        allowed = self.reset_options
        if options and not allowed.keys() >= options.keys():
            raise TypeError(f"{who}: unknown reset options {listed(set(options) - set(allowed))}; allowed: "
                            f"{', '.join(('force', 'torque', 'rows', *allowed))}")
        if rows is None:
            meas = measurement
            n = self._rows_of(measurement)
            if self.required_keys:
                meas = check_measurement(measurement, self.required_keys, n, who)
            force, torque = self._check_guesses(force, torque, n, who)
            options = {k: check_guess(v, n, k, allowed[k], who) for k, v in options.items()}
            self._n_rows = self._reset(meas, force, torque, None, **options)
            return
        if self._n_rows is None:
            raise ValueError(f"{who}: reset(measurement, rows=mask) selects rows of the batch set by a full "
                             "reset; call reset(measurement) once first")
        n = self._n_rows
        mask = check_row_mask(rows, n, who)
        meas = batch_measurement(measurement)
        for key, value in meas.items():
            if key in TRAILING_SHAPES and value.shape[0] != n:
                raise ValueError(f"{who}: reset(rows=mask) needs the measurement of all {n} rows of the batch (the "
                                 f"mask selects among them); measurement[{shown(key)}] has {value.shape[0]} rows")
        force_checked, torque_checked = self._check_guesses(force, torque, n, who)
        force_rows = _masked(force_checked, mask, 1)
        torque_rows = _masked(torque_checked, mask, 1)
        option_rows = {k: _masked(check_guess(v, n, k, allowed[k], who), mask, len(allowed[k]))
                       for k, v in options.items()}
        if not mask.any():
            return
        if mask.all():
            self.reset(measurement, force, torque, **options)
            return
        sub = {k: (v[mask] if k in TRAILING_SHAPES else v) for k, v in meas.items()}
        if self.required_keys:
            sub = check_measurement(sub, self.required_keys, int(mask.sum()), who)
        self._reset(sub, force_rows, torque_rows, mask, **option_rows)

    def _check_guesses(self, force: ArrayLike | None, torque: ArrayLike | None, n: int,
                       who: str) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        """The reset's force and torque guesses checked by :func:`check_guess`, each within its channel's divergence
        bound (:meth:`estimate_bounds`): a larger guess would make every later update raise (the estimate is refused
        and the state kept), so it is refused here, naming the bound."""
        force_bound, torque_bound = self.estimate_bounds()
        weights = f"{self.MAX_FORCE_WEIGHTS:g} vehicle weights m g"
        inertia = f"{self.MAX_ANGULAR_ACCELERATION:g} rad/s^2 times the largest principal inertia"
        return (check_guess(force, n, "force guess", (3,), who, bound=(force_bound, "N", weights)),
                check_guess(torque, n, "torque guess", (3,), who, bound=(torque_bound, "N m", inertia)))

    def _rows_of(self, measurement: Mapping[str, ArrayLike]) -> int:
        """The batch size of a full reset's measurement: the rows of its first required key (of its first known key
        if the observer states none; 1 if unbatched or absent: :func:`check_measurement` then names the problem)."""
        if not isinstance(measurement, Mapping):
            return 1
        keys = self.required_keys or tuple(k for k in measurement if k in TRAILING_SHAPES)
        if not keys or keys[0] not in measurement:
            return 1
        key = keys[0]
        shape = np.shape(measurement[key])
        return int(shape[0]) if len(shape) > len(TRAILING_SHAPES[key]) else 1

    def _reset(self, measurement: Mapping[str, Any], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None) -> int:
        """Build the fresh state of the rows of ``measurement`` (and the guesses) and store it.

        ``rows`` None: a full reset, the fresh state replaces the state.  Else ``rows`` is the observer's
        bool mask (N,) with both values present, ``measurement`` holds only the masked rows (already
        checked to be rows of this batch) and ``force`` / ``torque`` are None, (3,) or one row per masked
        row; store ``write_rows(state, fresh, rows)``, after bringing any cache of the state up to
        date, and build the fresh state completely before writing it (an error leaves the state as it
        was).  Returns the number of rows of ``measurement``.  An observer that states :attr:`required_keys`
        receives those keys only, checked as :meth:`update` checks them (float64, finite, a rotation).
        """
        raise NotImplementedError(f"{type(self).__name__} must implement _reset (or override reset)")

    # ---- update: one validation layer in front of every law ----------------------------------
    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        """Advance the observer by ``dt`` seconds with the measurement and the known thrust/torque; the estimate.

        ``measurement``: mapping with the keys :attr:`required_keys` (shapes of :mod:`fawtgym.core.measurement`,
        N rows, N the batch of the last full reset; unbatched at N = 1); ``thrust``: a number or (N,) [N];
        ``torque``: (3,) or (N, 3) [N m]; ``dt``: a real number of seconds in [:attr:`min_dt`, :attr:`max_dt`]
        (any dt > 0 up to max_dt unless the law divides by dt).

        The checks, in this order, each a one-line error naming the value, the same type and text at every N
        (sizes are named as ``N = <n>``): update before reset -> RuntimeError; ``dt`` not a real number (bool,
        str, None, complex) -> TypeError, not finite (an int beyond float range too), below ``min_dt`` (<= 0 by
        default) or above ``max_dt`` -> ValueError; measurement not a mapping or a value not real -> TypeError; a
        key missing, a wrong shape or row count, a non-finite
        entry, an attitude that is not a rotation (orthonormal within :data:`ROTATION_TOL`, det +1) ->
        ValueError; thrust/torque the same.  Then the law (:meth:`_update`); an estimate that is not finite
        or absurdly large (a force component above :attr:`MAX_FORCE_WEIGHTS` vehicle weights, a torque
        component above :attr:`MAX_ANGULAR_ACCELERATION` times the largest principal inertia) ->
        FloatingPointError naming the observer and the channel, and the state is left as it was before the
        update (the law's new state is stored, by :meth:`_commit`, only after the estimate passed).

        Two compiled fast paths run the same checks when the inputs are already what the Python checks pass on
        unchanged (a ``dict`` measurement whose required keys are C-contiguous float64 ndarrays (N, *trailing),
        thrust (N,), torque (N, 3), ``dt`` a float): a law with a checked kernel (:meth:`_update_checked`) does the
        checks, the law and the store in one compiled call (a subclass that overrides ``_update``,
        ``_check_estimate`` or ``_commit`` never takes it); every other observer checks the inputs' shapes and values
        in one compiled call (:data:`~fawtgym.observers._checks.INPUT_CHECKS`, the kernel for the kinds of its keys,
        with the same row checks), then runs :meth:`_update`, :meth:`_check_estimate` and :meth:`_commit` as here.
        On anything else (another type, layout or shape, a key set outside the kernel family) and on any failed check
        the Python checks run: they convert the inputs or word the error, so the error is the same either way, and
        the law receives the same arrays (bitwise the same estimates).
        """
        n = self._n_rows
        meas = None
        if n is not None and type(dt) is float and self.min_dt <= dt <= self.max_dt:
            if self._checked_path:
                est = self._update_checked(measurement, thrust, torque, dt, n)
                if est is not None:  # the law's kernel checked its inputs and its estimate (one compiled call)
                    return est
            elif type(measurement) is dict and type(thrust) is _ND and type(torque) is _ND:
                # the compiled input checks (Observer._input_checks): the measurement the law reads, or None
                keys, kernel, order = self._input_checks
                if keys is not self.required_keys:      # the first update, or an instance that changed its keys
                    keys = self.required_keys
                    kernel, order = _input_checks(keys)
                    self._input_checks = (keys, kernel, order)
                if kernel is not None:
                    try:    # a key missing (KeyError), an array of another dtype, ndim or layout (TypeError)
                        meas = {key: value for key in keys if type(value := measurement[key]) is _ND}
                        if (len(meas) != len(keys) or not TYPED_DISPATCH and not _fast_types(meas, thrust, torque, n)
                                or not kernel(n, thrust, torque, *(meas.values() if order is None else order(meas)))):
                            meas = None
                    except (KeyError, TypeError):
                        meas = None
        who = self.name or type(self).__name__
        if meas is None:        # the Python checks: they convert the inputs or word the error
            if n is None:
                raise RuntimeError(f"{who}: update() before reset(); call reset(measurement) first")
            dt = check_dt(dt, self.max_dt, who, self.min_dt, self.min_dt_reason)
            meas = check_measurement(measurement, self.required_keys, n, who)
            thrust, torque = check_inputs(thrust, torque, n, who)
        est, state = self._update(meas, thrust, torque, dt)  # type: ignore[arg-type]
        self._check_estimate(est, who)
        self._commit(state)
        return est

    def _update(self, meas: dict[str, NDArray[np.float64]], thrust: NDArray[np.float64],
                torque: NDArray[np.float64], dt: float) -> tuple[ObserverEstimate, Any]:
        """The law: the estimate after one step and the new state, which it must not store (nor write into
        the current state's arrays): :meth:`update` stores it with :meth:`_commit` once the estimate passed.

        ``meas``: the keys of :attr:`required_keys` (only those), checked, as float64 arrays with N rows;
        ``thrust`` (N,), ``torque`` (N, 3) float64, finite; ``dt`` a float in [:attr:`min_dt`, :attr:`max_dt`].
        The estimate's arrays must not be views of state the next update writes into.
        """
        raise NotImplementedError(f"{type(self).__name__} must implement _update (or override update)")

    def _update_checked(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike, dt: float,
                        n: int) -> ObserverEstimate | None:
        """Optional fast path of :meth:`update` (after the update-before-reset and ``dt`` checks): a law whose kernel
        also runs the checks of :func:`check_measurement`, :func:`check_inputs` and :meth:`_check_estimate` (the same
        compiled row checks, :mod:`fawtgym.observers._checks`) before it returns, in one compiled call.

        Returns the estimate, after storing the new state, when the inputs are already C-contiguous float64 arrays
        of the checked shapes (the kernel's explicit signature, :mod:`fawtgym.core.kernel_types`, refuses anything
        else with a TypeError; :func:`fast_inputs` checks the same under ``NUMBA_DISABLE_JIT=1``) and the kernel
        reports every check passed; None otherwise, with the state unchanged: :meth:`update` then runs its Python
        checks, which raise the one-line error (the same text and type as without this path) or convert the inputs.
        The default (None) always takes that path."""
        return None

    def _commit(self, state: Any) -> None:
        """Store the new state :meth:`_update` returned (default: as ``self._state``)."""
        self._state = state

    def snapshot(self) -> Any:
        """The state an :meth:`update` replaces, as :meth:`_commit` takes it (references, not copies: an update
        never writes into the arrays it holds, it stores new ones), for a caller that must take an update back
        (:meth:`restore`): e.g. an agent whose controller refuses the step the observer has just taken.  An
        observer whose :meth:`_commit` stores more than ``self._state`` returns what it stores; one that keeps its
        state elsewhere (a user class overriding :meth:`update`) overrides both, or cannot be taken back."""
        return getattr(self, "_state", _NO_SNAPSHOT)

    def restore(self, snapshot: Any) -> None:
        """Take back the updates since :meth:`snapshot` returned ``snapshot`` (no reset in between)."""
        if snapshot is not _NO_SNAPSHOT:
            self._commit(snapshot)

    def estimate_bounds(self) -> tuple[float, float]:
        """(force bound [N], torque bound [N m]): an estimate component above one counts as divergence
        (:attr:`MAX_FORCE_WEIGHTS` vehicle weights, :attr:`MAX_ANGULAR_ACCELERATION` times the largest principal
        inertia)."""
        return self.MAX_FORCE_WEIGHTS * self.mass * self.gravity, self.MAX_ANGULAR_ACCELERATION * self._j_max

    def _check_estimate(self, est: ObserverEstimate, who: str) -> None:
        """FloatingPointError naming the observer and the channel if an estimate is not finite or absurdly large.

        One compiled pass over force and torque; the states in one pass over their common buffer when they are
        views of one (what the kernels return), else one pass each."""
        force_bound, torque_bound = self.estimate_bounds()
        states = est.states
        if type(states) is BufferStates:      # every state a view of one buffer: one pass, no views made
            code = first_bad_estimate(est.force, est.torque, force_bound, torque_bound, states.buffer)
            if code == -1:
                return
        else:
            code = first_bad_wrench(est.force, est.torque, force_bound, torque_bound)
        if code >= 0:
            row, channel = code // 2, ("force", "torque")[code % 2]
            value = (est.force, est.torque)[code % 2][row]
            raise FloatingPointError(
                f"{who}: the {channel} estimate diverged (row {row}: {np.asarray(value).tolist()}; "
                f"allowed: finite, |component| <= {(force_bound, torque_bound)[code % 2]:.4g}); the state is left "
                "as before this update (check dt, the gains and the measurement)")
        if not states:
            return
        buf = est.force.base
        shared = buf is not None
        for value in states.values():
            if value.base is not buf:
                shared = False
                break
        if shared and buf is not None:
            if first_nonfinite_row(buf if buf.ndim == 2 else buf.reshape(buf.shape[0], -1)) < 0:
                return
        for channel, value in states.items():
            row = first_nonfinite_row(value if value.ndim == 2 else value.reshape(value.shape[0], -1))
            if row >= 0:
                raise FloatingPointError(
                    f"{who}: the {channel} estimate diverged (row {row} has a non-finite entry); the state is left "
                    "as before this update (check dt, the gains and the measurement)")


def fast_inputs(measurement: object, shapes: tuple[tuple[str, tuple[int, ...], int], ...], thrust: object,
                torque: object, n: int) -> list[NDArray[np.float64]] | None:
    """The arrays ``measurement[key]`` for the keys of ``shapes`` (:func:`input_shapes`), then ``thrust`` and
    ``torque``, if every one is already a float64 ndarray of the shape :func:`check_measurement` /
    :func:`check_inputs` pass on as is ((n, *trailing), (n,), (n, 3)); None otherwise (the caller then goes through
    those checks).  Values are not checked here."""
    if type(measurement) is not dict:
        return None
    out = []
    get = measurement.get
    for key, shape, _ in shapes:
        a = get(key)
        if type(a) is not np.ndarray or a.dtype is not _F64 or a.shape != shape:
            return None
        out.append(a)
    if (type(thrust) is not np.ndarray or thrust.dtype is not _F64 or thrust.shape != (n,)
            or type(torque) is not np.ndarray or torque.dtype is not _F64 or torque.shape != (n, 3)):
        return None
    out.append(thrust)
    out.append(torque)
    return out



#: the largest gravitational acceleration an observer accepts [m/s^2] (ten times Jupiter's 24.8): a larger one is a
#: typo, and the divergence bound MAX_FORCE_WEIGHTS m g would grow with it
MAX_GRAVITY = 250.0
#: the smallest [m/s^2] (a third of Ceres' 0.28; Titan's is 1.35): the divergence bound MAX_FORCE_WEIGHTS m g shrinks
#: with it, and at 1e-300 every update of a vehicle in Earth gravity "diverged"
MIN_GRAVITY = 0.1
#: the vehicle masses an observer accepts [kg], 0.1 g to 10 t (a subnormal or 1e300 mass made qb's every update diverge)
MASS_RANGE = (1e-4, 1e4)
#: the radius of gyration sqrt(principal moment / mass) [m] of each principal axis, 1 mm to 100 m (a multicopter's is
#: a few cm to a few m): a subnormal inertia gave an infinite inverse, and qb's momentum estimate mixes the force into
#: the torque at a far smaller radius (every update "diverged" at 0.1 mm)
RADIUS_OF_GYRATION = (1e-3, 1e2)


def _inertia_matrix(inertia: object, who: str, mass: float) -> NDArray[np.float64]:
    """``inertia`` as a float64 (3, 3) (3 entries: the diagonal); ValueError naming it unless it holds real
    numbers (bool, complex, str refused), has one of those shapes, is finite, its symmetric part is positive
    definite and each principal moment's radius of gyration sqrt(moment / ``mass``) is in :data:`RADIUS_OF_GYRATION`."""
    allowed = "a 3x3 matrix or 3 diagonal entries of finite real numbers [kg m^2], positive definite"
    j = as_array(inertia)
    if j.dtype.kind not in REAL_KINDS:
        raise ValueError(f"{who}: inertia must be {allowed}, got {shown(inertia)} (dtype {j.dtype})")
    j = j.astype(np.float64)
    j = np.diag(j) if j.shape == (3,) else j
    if j.shape != (3, 3) or not np.all(np.isfinite(j)):
        raise ValueError(f"{who}: inertia must be {allowed}, got {shown(inertia)}")
    moments = np.linalg.eigvalsh((j + j.T) / 2)
    if moments.min() <= 0:
        raise ValueError(f"{who}: inertia must be {allowed}, got {shown(inertia)} (not positive definite)")
    low, high = RADIUS_OF_GYRATION
    radii = np.sqrt(moments / mass)
    outside = (radii < low) | (radii > high)
    if outside.any():
        k = int(np.argmax(outside))
        raise ValueError(f"{who}: inertia must be {allowed}, with every radius of gyration sqrt(principal moment / "
                         f"mass) in [{low:g}, {high:g}] m, got {shown(inertia)} (principal moment {moments[k]:.4g} "
                         f"kg m^2, mass {mass:g} kg: radius {radii[k]:.4g} m)")
    return j


def check_dt(dt: object, max_dt: float, who: str, min_dt: float = SMALLEST_DT, why_min: str = "") -> float:
    """``dt`` as a float in [``min_dt``, ``max_dt``]: TypeError unless a real number (bool, str, None, complex refused),
    ValueError naming it if not finite (an int beyond float range too), below ``min_dt`` or above ``max_dt``.

    ``min_dt``: the shortest step the law takes (:attr:`Observer.min_dt`); the default, the smallest positive float,
    makes the range (0, ``max_dt``].  ``why_min``: why a larger ``min_dt`` (:attr:`Observer.min_dt_reason`), named in
    the message."""
    given = None  # an int beyond float range, as given
    if type(dt) is not float:
        real = isinstance(dt, (int, float, np.integer, np.floating)) and not isinstance(dt, (bool, np.bool_))
        if not real and isinstance(dt, np.ndarray) and dt.ndim == 0 and dt.dtype.kind in REAL_KINDS:
            real = True
        if not real:
            raise TypeError(f"{who}: dt must be a real number of seconds, got {shown(dt)} ({type(dt).__name__})")
        try:
            dt = float(dt)  # type: ignore[arg-type]
        except OverflowError:   # an int beyond float range: named as given
            given, dt = dt, math.inf
    if not (min_dt <= dt <= max_dt):         # NaN fails too
        got = shown(dt if given is None else given)
        if min_dt <= SMALLEST_DT:
            raise ValueError(f"{who}: dt must be a finite number of seconds in (0, {max_dt:g}] (max_dt, the bound of "
                             f"its discretisation), got {got}")
        raise ValueError(f"{who}: dt must be a finite number of seconds in [{min_dt:g}, {max_dt:g}] (min_dt: "
                         f"{why_min}; max_dt, the bound of its discretisation), got {got}")
    return dt


def _real_array(value: object, label: str, who: str) -> NDArray[np.float64]:
    """``value`` as a float64 array; TypeError naming ``label`` unless it holds real numbers (not bool, complex)."""
    a = as_array(value)
    if a.dtype.kind not in REAL_KINDS:
        raise TypeError(f"{who}: {label} must hold real numbers, got {type(value).__name__} of dtype {a.dtype}")
    return a if a.dtype == np.float64 else a.astype(np.float64)


def check_measurement(measurement: Mapping[str, ArrayLike], keys: tuple[str, ...], n: int,
                      who: str) -> dict[str, NDArray[np.float64]]:
    """The ``keys`` of ``measurement``, checked, as float64 arrays with ``n`` rows (:meth:`Observer.update`).

    Fast path (a few hundred ns per key at N = 1): a float64 ndarray of the expected shape goes straight to the
    compiled finiteness / rotation pass; anything else is converted (or refused) by :func:`_measured_array`.
    """
    if type(measurement) is not dict and not isinstance(measurement, Mapping):
        raise TypeError(f"{who}: measurement must be a mapping of arrays (info['measurement']), "
                        f"got {type(measurement).__name__}")
    out = {}
    for key, shape, kind in input_shapes(keys, n):
        try:
            a = measurement[key]
        except KeyError:
            missing = [k for k in keys if k not in measurement]
            raise ValueError(f"{who}: measurement needs the keys {list(keys)}; missing {missing}") from None
        if type(a) is not np.ndarray or a.dtype is not _F64 or a.shape != shape:
            a = _measured_array(a, key, TRAILING_SHAPES[key], n, who)
        if kind == _ROWS:
            row = first_nonfinite_row(a)
            if row >= 0:
                raise ValueError(f"{who}: measurement[{shown(key)}] has a non-finite entry in row {row}: "
                                 f"{a[row].tolist()}")
        elif kind == _ROTATION:
            row = first_non_rotation(a, ROTATION_TOL)
            if row >= 0:
                bad = a[row]
                if not np.isfinite(bad).all():
                    raise ValueError(f"{who}: measurement['attitude'] has a non-finite entry in row {row}: "
                                     f"{bad.tolist()}")
                defect = float(np.abs(bad.T @ bad - np.eye(3)).max())
                raise ValueError(f"{who}: measurement['attitude'] row {row} is not a rotation matrix (allowed: "
                                 f"max |R^T R - I| <= {ROTATION_TOL:g} and det R = +1; got max |R^T R - I| = "
                                 f"{defect:.3g}, det R = {float(np.linalg.det(bad)):.6g})")
        else:
            row = first_nonfinite_row(a.reshape(n, -1))
            if row >= 0:
                raise ValueError(f"{who}: measurement[{shown(key)}] has a non-finite entry in row {row}: "
                                 f"{a[row].tolist()}")
        out[key] = a
    return out


_F64 = np.dtype(np.float64)
#: how :func:`check_measurement` checks a key: rows of a 2-d array finite, a rotation, or the rows of another shape
_ROWS, _ROTATION, _OTHER = 0, 1, 2
_SHAPES: dict[tuple[tuple[str, ...], int], tuple[tuple[str, tuple[int, ...], int], ...]] = {}


def input_shapes(keys: tuple[str, ...], n: int) -> tuple[tuple[str, tuple[int, ...], int], ...]:
    """(key, expected shape (n, *trailing), check kind) of each key (memoized: built once per key set and batch
    size)."""
    spec = _SHAPES.get((keys, n))
    if spec is None:
        spec = _SHAPES[(keys, n)] = tuple(
            (k, (n, *TRAILING_SHAPES[k]), _ROTATION if k == ATTITUDE else _ROWS if len(TRAILING_SHAPES[k]) == 1
             else _OTHER) for k in keys)
    return spec


def _measured_array(value: object, key: str, trailing: tuple[int, ...], n: int, who: str) -> NDArray[np.float64]:
    """``measurement[key]`` as a float64 array (n, *trailing) (unbatched ``trailing`` accepted at n = 1);
    TypeError unless it holds real numbers, ValueError naming the shape otherwise."""
    label = f"measurement[{key!r}]"
    a = np.ascontiguousarray(_real_array(value, label, who))
    if a.shape != (n, *trailing):
        if n == 1 and a.shape == trailing:
            return a[None]
        shape = ", ".join(("N", *map(str, trailing)))
        raise ValueError(f"{who}: {label} must have shape ({shape}) with N = {n} (the batch size set by "
                         f"reset; unbatched {trailing} if N = 1), got {a.shape}")
    return a


def check_inputs(thrust: ArrayLike, torque: ArrayLike, n: int,
                 who: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The known inputs as float64 (n,) and (n, 3): collective thrust [N], a number (every row) or (n,); body
    torque [N m], (3,) (every row) or (n, 3); real (TypeError otherwise) and finite (ValueError)."""
    f = thrust
    if type(f) is not np.ndarray or f.dtype is not _F64 or f.shape != (n,):
        f = _real_array(thrust, "thrust", who)
        if f.shape != (n,):
            if f.ndim != 0:
                raise ValueError(f"{who}: thrust must be a number or have shape (N,) with N = {n} (the batch size "
                                 f"set by reset), got shape {f.shape}")
            f = np.full(n, float(f))
    tau = torque
    if type(tau) is not np.ndarray or tau.dtype is not _F64 or tau.shape != (n, 3):
        tau = _real_array(torque, "torque", who)
        if tau.shape != (n, 3):
            if tau.shape != (3,):
                raise ValueError(f"{who}: torque must have shape (3,) or (N, 3) with N = {n} (the batch size set by "
                                 f"reset), got shape {tau.shape}")
            tau = np.ascontiguousarray(np.broadcast_to(tau, (n, 3)))
    code = first_nonfinite_input(f, tau)
    if code >= 0:
        row = code // 2
        label, value = ("thrust", f[row]) if code % 2 == 0 else ("torque", tau[row].tolist())
        raise ValueError(f"{who}: {label} has a non-finite entry in row {row}: {shown(value)}")
    return f, tau


def check_guess(guess: ArrayLike | None, n: int, label: str, trailing: tuple[int, ...], who: str,
                bound: tuple[float, str, str] | None = None) -> NDArray[np.float64] | None:
    """A reset's initial guess (``force``, ``torque``: trailing (3,); an option such as qb's ``thrust``: ()) as a
    float64 array of shape ``trailing`` (every row) or (n, *trailing) (one per row); None stays None.

    One-line ValueError, the same text for every observer and N (sizes named as ``N = <n>``), naming the argument
    and the allowed shapes unless it holds real numbers (bool, complex, str refused) of one of those shapes, all
    finite; with ``bound`` = (b, its unit, what it is), also naming the bound unless every component is at most b in
    magnitude (the first offending value: the guess (every row), or its row of a per-row guess)."""
    if guess is None:
        return None
    rows = f"({', '.join(('N', *map(str, trailing)))}{',' if not trailing else ''}) with N = {n} (one per row)"
    allowed = (f"a finite real number (every row) or shape {rows}" if not trailing
               else f"finite real numbers of shape {trailing} (every row) or {rows}")
    g = as_array(guess)
    if g.dtype.kind not in REAL_KINDS:
        raise ValueError(f"{who}: reset {label} must be {allowed}, got {type(guess).__name__} of dtype "
                         f"{g.dtype}")
    if g.shape != trailing and g.shape != (n, *trailing):
        raise ValueError(f"{who}: reset {label} must be {allowed}, got shape {g.shape}")
    g = g.astype(np.float64)
    if not np.all(np.isfinite(g)):
        raise ValueError(f"{who}: reset {label} must be {allowed}, got a non-finite entry: "
                         f"{float(g.reshape(-1)[~np.isfinite(g.reshape(-1))][0])!r}")
    if bound is not None:
        limit, unit, meaning = bound
        large = np.abs(g) > limit
        if large.any():
            if g.shape == trailing:
                got = f"{g.tolist()}"
            else:
                row = int(np.argmax(large.reshape(n, -1).any(axis=1)))
                got = f"row {row}: {g[row].tolist()}"
            raise ValueError(f"{who}: reset {label} must be within the divergence bound of the estimate, "
                             f"|component| <= {limit:.10g} {unit} ({meaning}; an update refuses a larger estimate), "
                             f"got {got}")
    return g


def _masked(guess: NDArray[np.float64] | None, rows: NDArray[np.bool_], ndim: int) -> NDArray[np.float64] | None:
    """A checked guess of a per-row reset: None or one for every row (``ndim`` dimensions) as is, else its masked
    rows."""
    return guess if guess is None or guess.ndim == ndim else guess[rows]


_INPUT_CHECKS: dict[tuple[str, ...], tuple[Any, Any]] = {}
_ND = np.ndarray


def _input_checks(keys: tuple[str, ...]) -> tuple[Any, Any]:
    """(check kernel, order) for the compiled input checks of :meth:`Observer.update`: the kernel of
    :data:`~fawtgym.observers._checks.INPUT_CHECKS` for the kinds of ``keys`` (compiled for its one signature on first
    use), None for a key set outside the family (no fast path), and ``order``: None if the kernel takes the keys'
    arrays in the order of ``keys``, else an itemgetter putting the attitude first.  Memoized per key set."""
    plan = _INPUT_CHECKS.get(keys)
    if plan is not None:
        return plan
    rotations = tuple(k for k in keys if TRAILING_SHAPES.get(k) == (3, 3))
    vectors = tuple(k for k in keys if TRAILING_SHAPES.get(k) == (3,))
    entry = INPUT_CHECKS.get((bool(rotations), len(vectors)))
    kernel = order = None
    if (entry is not None and len(rotations) <= 1 and len(rotations) + len(vectors) == len(keys)
            and len(set(keys)) == len(keys)):
        kernel, signature = entry
        if TYPED_DISPATCH and kernel not in _COMPILED:
            compile_only(kernel, signature)
            _COMPILED.add(kernel)
        ordered = rotations + vectors
        order = None if ordered == keys else itemgetter(*ordered)
    plan = _INPUT_CHECKS[keys] = (kernel, order)
    return plan


def _fast_types(meas: dict[str, NDArray[np.float64]], thrust: NDArray[np.float64], torque: NDArray[np.float64],
                n: int) -> bool:
    """Under ``NUMBA_DISABLE_JIT=1`` (plain Python kernels accept anything): whether the arrays are float64 of the
    shapes the check kernels' signatures and shape checks take (:func:`fast_inputs`), as numba's typed dispatch finds
    when compiled."""
    return fast_inputs(meas, input_shapes(tuple(meas), n), thrust, torque, n) is not None


#: the check kernels already compiled for their one signature (:func:`~fawtgym.core.kernel_types.compile_only`)
_COMPILED: set[Any] = set()

_REGISTRY: dict[str, type[Observer]] = {}


def register_observer(name: str) -> Callable[[type[Observer]], type[Observer]]:
    """Class decorator adding an observer to the registry under ``name``."""

    def deco(cls: type[Observer]) -> type[Observer]:
        if name in _REGISTRY and _REGISTRY[name] is not cls:
            raise ValueError(f"observer name {shown(name)} is already registered to {_REGISTRY[name].__name__}")
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return deco


def observer_class(name: str) -> type[Observer]:
    """The class registered under ``name``; ValueError listing the valid names otherwise."""
    if not isinstance(name, str) or name not in _REGISTRY:
        raise ValueError(f"unknown observer {shown(name)}; valid names: {observer_names()}")
    return _REGISTRY[name]


def observer_names() -> list[str]:
    """Registered observer names (importing :mod:`fawtgym.observers` registers them all)."""
    return sorted(_REGISTRY)


def make_observer(name: str, mass: float, inertia: ArrayLike, **kwargs: Any) -> Observer:
    """Build a registered observer by name; an unknown name or option raises ValueError listing the valid ones."""
    cls = observer_class(name)
    options = observer_options(name)
    if options is not None:
        check_known(kwargs, options, f"observer {shown(name)}")
    return cls(mass, inertia, **kwargs)


def observer_options(name: str) -> tuple[str, ...] | None:
    """The keyword options of registered observer ``name`` (its constructor's parameters after mass and inertia), or
    None if it takes arbitrary keywords."""
    cls = observer_class(name)
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in inspect.signature(cls).parameters.values()):
        return None
    return tuple(keyword_names(cls)[2:])
