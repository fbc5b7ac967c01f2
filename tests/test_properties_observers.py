"""Property-based tests (hypothesis) of every registered observer's inputs (issue 14, "Same errors at every N").

Parametrized over ``observer_names()``, so a newly registered observer is covered without editing this file.
Each input is given to a fresh observer at N = 1 and at N = 3 (the same row in every row of the batch).
Properties:

* ``reset`` / ``update`` succeed with finite estimates, or raise ValueError / TypeError / RuntimeError
  (FloatingPointError from ``update`` for a diverging estimate) with a one-line message;
* ``update`` before ``reset`` is a RuntimeError for every observer;
* an attitude that is not a rotation (2I, a reflection, zeros, a random matrix, a 1.001-scaled rotation, NaN)
  is refused by every observer that reads the attitude, at reset and at update;
* dt: a float period of a flight controller (np.float32 too) is accepted; a non-positive, non-finite,
  boolean, non-numeric or absurdly large dt (1e6 s) is refused; anything in between is the observer's call
  (refused, or accepted with finite estimates);
* thrust / torque of another shape, complex, boolean or non-finite are refused (never broadcast or cast);
* a missing measurement key is a ValueError naming it (not a KeyError);
* N = 1 and N = 3 agree: both succeed, or both raise the same type with the same message (apart from the
  batch size it names).

Strategies and the shared checks: tests/_strategies.py (bounded, derandomized examples).
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from _strategies import (
    ALLOWED,
    ALLOWED_UPDATE,
    DTS,
    NON_ROTATIONS,
    Outcome,
    all_finite,
    call,
    check_error,
    check_same_outcome,
)
from hypothesis import given
from hypothesis import strategies as st

import fawtgym.observers  # noqa: F401  (registers every observer)
from fawtgym.core.measurement import EARTH_FIELD_NED
from fawtgym.observers import make_observer, observer_names

NAMES = observer_names()
G = 9.80665
DT = 0.005
SIZES = (1, 3)


def _build(name: str) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the QB observer warns that its gain was designed for another mass
        return make_observer(name, mass=1.0, inertia=[0.03, 0.03, 0.06])


def _row() -> dict[str, Any]:
    """One vehicle's measurement: hovering, yawed 0.3 rad, moving slowly (every key any observer reads)."""
    c, s = math.cos(0.3), math.sin(0.3)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return {"position": np.array([0.1, -0.2, -1.5]), "velocity": np.array([0.05, 0.0, -0.02]), "attitude": rot,
            "angular_velocity": np.array([0.01, -0.02, 0.03]), "specific_force": rot.T @ np.array([0.0, 0.0, -G]),
            "gyro": np.array([0.01, -0.02, 0.03]), "magnetometer": rot.T @ EARTH_FIELD_NED, "time": np.float64(0.0)}


def _batch(row: Mapping[str, Any], n: int) -> dict[str, Any]:
    """The row repeated n times along a leading axis (a non-array value is passed as it is)."""
    return {k: (np.stack([np.asarray(v)] * n) if isinstance(v, np.ndarray | np.generic) else v) for k, v in row.items()}


def _thrust(n: int) -> np.ndarray:
    return np.full(n, 1.0 * G)


def _torque(n: int) -> np.ndarray:
    return np.zeros((n, 3))


def _estimate_is_finite(est: Any) -> bool:
    return all_finite(est.force) and all_finite(est.torque) and all(all_finite(v) for v in est.states.values())


def _run(name: str, n: int, reset_meas: Mapping[str, Any], update_meas: Mapping[str, Any] | None = None,
         thrust: Any = None, torque: Any = None, dt: Any = DT) -> tuple[Outcome, Outcome | None]:
    """reset on ``reset_meas`` then (if it succeeded) one update; returns both outcomes."""
    obs = _build(name)
    reset = call(lambda: obs.reset(reset_meas), f"{name}.reset (N={n})")
    if not reset.ok:
        return reset, None
    update = call(lambda: obs.update(update_meas if update_meas is not None else reset_meas,
                                     _thrust(n) if thrust is None else thrust,
                                     _torque(n) if torque is None else torque, dt), f"{name}.update (N={n})")
    return reset, update


def _bad_row_outcomes(name: str, bad_row: Mapping[str, Any], when: str) -> dict[str, Outcome]:
    """At every N of SIZES: the outcome of ``reset`` on ``bad_row`` in every row (``when="reset"``), or of the
    ``update`` on it after a reset on valid rows (``when="update"``)."""
    outcomes: dict[str, Outcome] = {}
    for n in SIZES:
        if when == "reset":
            outcomes[f"N={n}"] = _run(name, n, _batch(bad_row, n))[0]
        else:
            update = _run(name, n, _batch(_row(), n), _batch(bad_row, n))[1]
            assert update is not None
            outcomes[f"N={n}"] = update
    return outcomes


@functools.cache
def warm(name: str) -> None:
    """One valid reset + update at every N, outside the time limit, before an observer is fuzzed: a first call
    compiles its numba kernels (seconds), and an alarm inside the compiler would break them.  Errors are left to the
    tests that check valid inputs."""
    for n in SIZES:
        obs = _build(name)
        try:
            obs.reset(_batch(_row(), n))
            obs.update(_batch(_row(), n), _thrust(n), _torque(n), DT)
        except Exception:  # reported by test_valid_inputs_give_finite_estimates_at_every_n
            return


@pytest.fixture(autouse=True)
def _warm_up(request: pytest.FixtureRequest) -> None:
    """Warm the observer a test is parametrized with (idempotent, so harmless across hypothesis examples)."""
    callspec = getattr(request.node, "callspec", None)
    if callspec is not None and "name" in callspec.params:
        warm(callspec.params["name"])


@functools.cache
def _reads(name: str, key: str) -> bool:
    """Whether the observer needs ``key`` (its reset/update fails without it)."""
    row = _row()
    del row[key]
    reset, update = _run(name, 1, _batch(row, 1))
    return not (reset.ok and update is not None and update.ok)


def _check_call(name: str, what: str, outcomes: dict[str, Outcome], expect: str,
                allowed: tuple[type[BaseException], ...]) -> None:
    """expect "ok": every N succeeds with finite estimates; "bad": every N refuses; "either": the property only."""
    for label, outcome in outcomes.items():
        if outcome.ok:
            assert expect != "bad", f"{name}: {what} at {label}: accepted (the spec refuses it)"
            if outcome.value is not None:
                assert _estimate_is_finite(outcome.value), f"{name}: {what} at {label}: non-finite estimate"
        else:
            assert expect != "ok", f"{name}: {what} at {label}: refused a valid input: {outcome.describe()}"
            check_error(outcome, allowed, f"{name}: {what} at {label}")
    check_same_outcome(outcomes, f"{name}: {what}")


def _check_update(name: str, what: str, expect: str, **inputs_by_n: Any) -> None:
    """Run reset (valid) + update with the per-N inputs ``inputs_by_n[key](n)`` and check the update outcome."""
    outcomes: dict[str, Outcome] = {}
    for n in SIZES:
        meas = _batch(_row(), n)
        kwargs = {k: f(n) for k, f in inputs_by_n.items()}
        update_meas = kwargs.pop("update_meas", None)
        reset, update = _run(name, n, meas, update_meas, **kwargs)
        assert reset.ok, f"{name}: reset on a valid measurement failed at N={n}: {reset.describe()}"
        assert update is not None
        outcomes[f"N={n}"] = update
    _check_call(name, what, outcomes, expect, ALLOWED_UPDATE)


# ---- order of calls ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", NAMES)
def test_update_before_reset_is_a_runtime_error_at_every_n(name: str) -> None:
    outcomes = {f"N={n}": call(lambda n=n: _build(name).update(_batch(_row(), n), _thrust(n), _torque(n), DT))
                for n in SIZES}
    for label, outcome in outcomes.items():
        assert not outcome.ok, f"{name}: update() before reset() succeeded at {label}"
        check_error(outcome, (RuntimeError,), f"{name}: update() before reset() at {label}")
    check_same_outcome(outcomes, f"{name}: update() before reset()")


@pytest.mark.parametrize("name", NAMES)
def test_valid_inputs_give_finite_estimates_at_every_n(name: str) -> None:
    _check_update(name, "a valid update", "ok")


# ---- attitude ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("label", [label for label, _ in NON_ROTATIONS])
@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("when", ["reset", "update"])
def test_attitude_that_is_not_a_rotation_is_refused(name: str, label: str, when: str) -> None:
    if not _reads(name, "attitude"):
        pytest.skip(f"{name} does not read measurement['attitude']")
    matrix = dict(NON_ROTATIONS)[label]
    bad_row = {**_row(), "attitude": matrix}
    outcomes = _bad_row_outcomes(name, bad_row, when)
    _check_call(name, f"{when} with attitude = {label}", outcomes, "bad", ALLOWED)


# ---- dt ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("label", "dt", "expect"), DTS, ids=[label for label, _, _ in DTS])
@pytest.mark.parametrize("name", NAMES)
def test_dt_of_every_type_and_size(name: str, label: str, dt: Any, expect: str) -> None:
    _check_update(name, f"update(dt={label})", expect, dt=lambda n: dt)


# ---- thrust and torque -------------------------------------------------------------------------------------
#: shapes relative to the batch size n: (label, n -> shape, expectation); no torque (N,): at N = 3 it is (3,)
THRUST_SHAPES: list[tuple[str, Any, str]] = [
    ("(N,)", lambda n: (n,), "ok"), ("()", lambda n: (), "either"), ("(N, 1)", lambda n: (n, 1), "bad"),
    ("(N + 1,)", lambda n: (n + 1,), "bad"), ("(2N,)", lambda n: (2 * n,), "bad"), ("(N, 3)", lambda n: (n, 3), "bad"),
]
TORQUE_SHAPES: list[tuple[str, Any, str]] = [
    ("(N, 3)", lambda n: (n, 3), "ok"), ("(3,)", lambda n: (3,), "either"), ("(N, 1)", lambda n: (n, 1), "bad"),
    ("(N + 1, 3)", lambda n: (n + 1, 3), "bad"), ("(N, 4)", lambda n: (n, 4), "bad"),
    ("(N, 3, 1)", lambda n: (n, 3, 1), "bad"), ("(N, 2)", lambda n: (n, 2), "bad"),
]
#: element kinds: (label, dtype, fill value, expectation)
ELEMENTS: list[tuple[str, Any, Any, str]] = [
    ("float", np.float64, None, "ok"), ("float32", np.float32, None, "ok"), ("int", np.int64, 1, "ok"),
    ("nan", np.float64, math.nan, "bad"), ("inf", np.float64, math.inf, "bad"), ("-inf", np.float64, -math.inf, "bad"),
    ("huge", np.float64, 1e300, "either"), ("complex", np.complex128, 1 + 1j, "bad"), ("bool", np.bool_, True, "bad"),
    ("str", np.str_, "1.0", "bad"),
]


def _array(shape: tuple[int, ...], dtype: Any, fill: Any, nominal: float) -> np.ndarray:
    return np.full(shape, nominal if fill is None else fill, dtype=dtype)


def _worst(*expectations: str) -> str:
    return "bad" if "bad" in expectations else ("either" if "either" in expectations else "ok")


@given(shape=st.sampled_from(THRUST_SHAPES), element=st.sampled_from(ELEMENTS))
@pytest.mark.parametrize("name", NAMES)
def test_thrust_of_any_shape_and_dtype(name: str, shape: tuple[str, Any, str], element: tuple[str, Any, Any, str]
                                       ) -> None:
    shape_label, shape_of, shape_expect = shape
    el_label, dtype, fill, el_expect = element
    _check_update(name, f"update(thrust shape {shape_label}, {el_label})", _worst(shape_expect, el_expect),
                  thrust=lambda n: _array(shape_of(n), dtype, fill, G))


@given(shape=st.sampled_from(TORQUE_SHAPES), element=st.sampled_from(ELEMENTS))
@pytest.mark.parametrize("name", NAMES)
def test_torque_of_any_shape_and_dtype(name: str, shape: tuple[str, Any, str], element: tuple[str, Any, Any, str]
                                       ) -> None:
    shape_label, shape_of, shape_expect = shape
    el_label, dtype, fill, el_expect = element
    if fill is None and dtype is not np.str_:
        fill = 0.0
    _check_update(name, f"update(torque shape {shape_label}, {el_label})", _worst(shape_expect, el_expect),
                  torque=lambda n: _array(shape_of(n), dtype, fill, 0.0))


# ---- measurement values ------------------------------------------------------------------------------------
KEYS = list(_row())
#: (label, row value -> bad row value, expectation for a key the observer reads)
MUTATIONS: list[tuple[str, Any, str]] = [
    ("nan", lambda v: np.full(np.shape(v), math.nan), "bad"),
    ("inf", lambda v: np.full(np.shape(v), math.inf), "bad"),
    ("huge", lambda v: np.full(np.shape(v), 1e300), "either"),
    ("string", lambda v: np.full(np.shape(v), "a"), "bad"),
    ("complex", lambda v: np.asarray(v) + 1j, "bad"),
    ("a trailing axis too many", lambda v: np.asarray(v)[..., None], "bad"),
    ("one entry short", lambda v: np.asarray(v).reshape(-1)[:-1] if np.ndim(v) else np.zeros(2), "bad"),
]


@given(key=st.sampled_from(KEYS), mutation=st.sampled_from(MUTATIONS), when=st.sampled_from(["reset", "update"]))
@pytest.mark.parametrize("name", NAMES)
def test_bad_measurement_value_is_refused_alike_at_every_n(name: str, key: str, mutation: tuple[str, Any, str],
                                                           when: str) -> None:
    label, mutate, expect = mutation
    if not _reads(name, key):
        expect = "either"  # a key the observer does not read may hold anything
    bad_row = {**_row(), key: mutate(_row()[key])}
    outcomes = _bad_row_outcomes(name, bad_row, when)
    _check_call(name, f"{when} with measurement[{key!r}] {label}", outcomes, expect, ALLOWED_UPDATE)


@pytest.mark.parametrize("key", KEYS)
@pytest.mark.parametrize("name", NAMES)
def test_missing_measurement_key_is_a_value_error_naming_it(name: str, key: str) -> None:
    if not _reads(name, key):
        pytest.skip(f"{name} does not read measurement[{key!r}]")
    row = _row()
    del row[key]
    outcomes: dict[str, Outcome] = {}
    for n in SIZES:
        reset, update = _run(name, n, _batch(row, n))
        assert reset.ok or update is None
        outcomes[f"N={n}"] = update if update is not None else reset
    for label, outcome in outcomes.items():
        assert not outcome.ok
        check_error(outcome, (ValueError,), f"{name}: measurement without {key!r} at {label}")
        assert key in str(outcome.error), f"{name}: the error for a missing {key!r} does not name it: {outcome.error}"
    check_same_outcome(outcomes, f"{name}: measurement without {key!r}")


@pytest.mark.parametrize("name", NAMES)
def test_measurement_that_is_not_a_mapping_is_refused(name: str) -> None:
    for bad in (None, 5, "position", [1.0, 2.0]):
        obs = _build(name)
        outcome = call(lambda bad=bad, obs=obs: obs.reset(bad))
        assert not outcome.ok, f"{name}: reset({bad!r}) accepted"
        check_error(outcome, ALLOWED, f"{name}: reset({bad!r})")
