"""Shared hypothesis strategies and checks of the property-based suite (tests/test_properties_*.py).

The property every public entry point must have (issue 14, "Same errors at every N"): a call either succeeds
with finite outputs, or raises ValueError / TypeError / RuntimeError (FloatingPointError for a diverging
estimate) with a one-line message; and the same bad input gives the same exception type and the same message
at N = 1 and N = 3 (apart from the batch size the message names, see :func:`same_text_apart_from_sizes`).

Settings: the examples are derandomized (the same on every run, so CI is reproducible) and bounded
(``max_examples``, ``deadline=None``) so that the whole property suite stays well under a minute on 2 cores.
``FAWTGYM_HYPOTHESIS_PROFILE=deep`` searches further (random, 20x the examples) for local runs.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

#: exception types a bad input may raise (FloatingPointError only for a diverging estimate, see ALLOWED_UPDATE)
ALLOWED = (ValueError, TypeError, RuntimeError)
ALLOWED_UPDATE = (*ALLOWED, FloatingPointError)
#: a call that takes longer than this is a failure (hc_eso once ran ceil(dt / 0.005) Python substeps: dt = 1e6
#: took about 50 minutes); SIGALRM turns the hang into a test failure naming the call.  Generous, because a first
#: call may compile a numba kernel for a new argument type (an alarm inside numba's compiler breaks that kernel
#: for the rest of the process: warm the common paths up outside the limit, see test_properties_observers.warm)
CALL_SECONDS = 30.0

#: function_scoped_fixture: the observer warm-up fixture is idempotent, harmless across examples
_SUPPRESS = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture]
settings.register_profile("ci", max_examples=25, deadline=None, derandomize=True, database=None, print_blob=True,
                          suppress_health_check=_SUPPRESS)  # no example database: every run tries the same examples
settings.register_profile("deep", max_examples=500, deadline=None, derandomize=False, print_blob=True,
                          suppress_health_check=_SUPPRESS)
settings.load_profile(os.environ.get("FAWTGYM_HYPOTHESIS_PROFILE", "ci"))


class CallTookTooLong(Exception):
    """Raised inside a call that exceeded CALL_SECONDS (not an allowed error type: the property fails)."""


@contextlib.contextmanager
def time_limit(seconds: float = CALL_SECONDS, what: str = "call") -> Iterator[None]:
    """Fail a call that hangs (main thread only; elsewhere no limit is set)."""

    def handler(signum: int, frame: Any) -> None:
        raise CallTookTooLong(f"{what} took more than {seconds:g} s")

    try:
        old = signal.signal(signal.SIGALRM, handler)
    except ValueError:  # not the main thread
        yield
        return
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


class Outcome:
    """What a call did: its value, or the exception it raised."""

    def __init__(self, value: Any = None, error: BaseException | None = None) -> None:
        self.value = value
        self.error = error

    @property
    def ok(self) -> bool:
        return self.error is None

    def describe(self) -> str:
        return "returned" if self.ok else f"{type(self.error).__name__}: {self.error}"


def call(fn: Callable[[], Any], what: str = "call") -> Outcome:
    """Run ``fn`` under the time limit; capture what it returned or raised (never swallow KeyboardInterrupt)."""
    try:
        with time_limit(what=what):
            return Outcome(value=fn())
    except Exception as exc:  # the property classifies it
        return Outcome(error=exc)


def check_error(outcome: Outcome, allowed: tuple[type[BaseException], ...] = ALLOWED, what: str = "") -> None:
    """A raised error is of an allowed type and its message is one non-empty line."""
    exc = outcome.error
    assert exc is not None
    assert isinstance(exc, allowed), (f"{what}: raised {type(exc).__name__} ({exc}); allowed: "
                                      f"{[t.__name__ for t in allowed]}")
    # FloatingPointError is an ArithmeticError, not a ValueError: allowed only where ALLOWED_UPDATE says so
    if isinstance(exc, FloatingPointError) and FloatingPointError not in allowed:
        raise AssertionError(f"{what}: raised FloatingPointError ({exc}) where a bad input must be named")
    text = str(exc)
    assert text.strip(), f"{what}: {type(exc).__name__} with an empty message"
    assert "\n" not in text.strip(), f"{what}: {type(exc).__name__} message is not one line: {text!r}"


def all_finite(value: Any) -> bool:
    """True when every number reachable in ``value`` (arrays, scalars, mappings, sequences) is finite."""
    if isinstance(value, dict):
        return all(all_finite(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(all_finite(v) for v in value)
    if isinstance(value, (str, bytes, type(None), bool)):
        return True
    if hasattr(value, "__dataclass_fields__"):
        return all(all_finite(getattr(value, f)) for f in value.__dataclass_fields__)
    arr = np.asarray(value)
    if arr.dtype.kind in "fc":
        return bool(np.all(np.isfinite(arr)))
    return True


_NUMBER = re.compile(r"(-?\d+(?:\.\d+)?(?:e[-+]?\d+)?)")
_INTEGER = re.compile(r"-?\d+")


def same_text_apart_from_sizes(text_1: str, text_3: str) -> bool:
    """The messages at N = 1 and N = 3 are the same text apart from the sizes they name: they split into the same
    words and numbers, and only whole numbers (a batch size, a shape such as (N + 1, 3)) may differ.  A value
    (1.5, nan, an array's contents) or the number of rows listed must not depend on N."""
    if text_1 == text_3:
        return True
    parts_1, parts_3 = _NUMBER.split(text_1), _NUMBER.split(text_3)
    if len(parts_1) != len(parts_3):
        return False
    return all(a == b or (_INTEGER.fullmatch(a) is not None and _INTEGER.fullmatch(b) is not None)
               for a, b in zip(parts_1, parts_3, strict=True))


def check_same_outcome(by_n: dict[str, Outcome], what: str, compare_text: bool = True) -> None:
    """Every variant (e.g. ``{"N=1": ..., "N=3": ...}``) succeeded, or every one raised the same type (and text)."""
    oks = {name: o.ok for name, o in by_n.items()}
    assert len(set(oks.values())) == 1, (
        f"{what}: succeeds for some batch sizes only: " + "; ".join(f"{k} {o.describe()}" for k, o in by_n.items()))
    if all(oks.values()):
        return
    types = {name: type(o.error).__name__ for name, o in by_n.items()}
    assert len(set(types.values())) == 1, f"{what}: exception type depends on N: {types}"
    if compare_text:
        texts = [str(o.error) for o in by_n.values()]
        for text in texts[1:]:
            assert same_text_apart_from_sizes(texts[0], text), (
                f"{what}: message depends on N: " + " | ".join(f"{k}: {o.error}" for k, o in by_n.items()))


# ---- values ----------------------------------------------------------------------------------------------
NONFINITE = [math.nan, math.inf, -math.inf]
HUGE = [1e300, -1e300, 1e30, -1e30]
#: values that are not numbers at all
NOT_NUMBERS = ["a", "1.0", None, [1.0, 2.0], {"x": 1}, b"1", object()]
#: bad scalars for an option that wants a finite positive number
BAD_POSITIVE = [0, 0.0, -1, -1e-9, *NONFINITE, True, False, 1 + 1j, *NOT_NUMBERS[:5]]

finite_floats = st.floats(-2.0, 2.0, allow_nan=False)
any_floats = st.one_of(finite_floats, st.sampled_from([*NONFINITE, *HUGE, 0.0, 1.0]))


def float_arrays(shape: tuple[int, ...] | st.SearchStrategy[tuple[int, ...]],
                 elements: st.SearchStrategy[float] = any_floats) -> st.SearchStrategy[np.ndarray]:
    return hnp.arrays(np.float64, shape, elements=elements)


# ---- env actions -------------------------------------------------------------------------------------------
BAD_ACTION_SHAPES = [(), (3,), (5,), (2, 2), (1, 4), (4, 1), (8,)]


def _typed_actions() -> st.SearchStrategy[np.ndarray]:
    """(4,) actions of every dtype: float64/float32 with any values, ints, bools, complex."""
    return st.one_of(
        hnp.arrays(np.float32, (4,), elements=st.floats(-2, 2, width=32) | st.sampled_from([math.nan, math.inf])),
        hnp.arrays(np.int64, (4,), elements=st.integers(-2, 2)),
        hnp.arrays(np.bool_, (4,)),
        hnp.arrays(np.complex128, (4,), elements=st.complex_numbers(max_magnitude=1.0, allow_nan=False)),
    )


#: anything that might be passed as one vehicle's action
actions = st.one_of(
    float_arrays((4,)),
    float_arrays((4,), elements=st.floats(0.0, 1.0)),
    _typed_actions(),
    float_arrays(st.sampled_from(BAD_ACTION_SHAPES), elements=st.floats(0.0, 1.0)),
    st.sampled_from(["a", None, "0.5 0.5 0.5 0.5", [0.5, 0.5, 0.5], [0.5, 0.5, 0.5, "a"], [0.5, 0.5, 0.5, None]]),
)


def is_valid_action(action: Any) -> bool:
    """The spec: a real (int or float, not bool or complex) array of shape (4,) with finite entries."""
    if not isinstance(action, np.ndarray):
        return False
    return action.shape == (4,) and action.dtype.kind in "iuf" and bool(np.all(np.isfinite(action)))


# ---- env reset options -------------------------------------------------------------------------------------
setpoints = st.one_of(
    float_arrays((3,), elements=st.floats(-3.0, 1.0)),
    float_arrays((3,)),
    st.sampled_from(["a", None, [1.0, 2.0], [0.0, 1.5, -1.5], (0.0, 0.0, -1.0), [0.0, 0.0, 0.5], [0.0, 0.0, 0.0],
                     np.float32(-1.0), [[0.0, 1.5, -1.5]], [0.0, 1.5, "a"], np.array([0, 1, -1], dtype=np.int64),
                     np.array([0, 1.5, -1.5], dtype=np.complex128)]),
)
init_noises = st.sampled_from([0, 0.5, 1, 2.0, -1, math.nan, math.inf, "a", None, True, np.float32(0.5), np.int64(1),
                               [1.0], 1e300, 1 + 0j])
reset_options = st.one_of(
    st.fixed_dictionaries({}, optional={"setpoint": setpoints, "init_noise": init_noises}),
    st.fixed_dictionaries({"bogus": st.just(1)}, optional={"setpoint": setpoints}),
    st.sampled_from([5, "setpoint", [("init_noise", 0.5)], 1.5]),
)


# ---- observer inputs ---------------------------------------------------------------------------------------
def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix (QR of a Gaussian matrix, sign-fixed, det +1)."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _near_identity() -> np.ndarray:
    c, s = math.cos(0.1), math.sin(0.1)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: attitudes that are not rotation matrices (name, matrix); every observer that reads the attitude must refuse them
NON_ROTATIONS: list[tuple[str, np.ndarray]] = [
    ("2I", 2.0 * np.eye(3)),
    ("reflection diag(1, 1, -1)", np.diag([1.0, 1.0, -1.0])),
    ("zeros", np.zeros((3, 3))),
    ("random matrix", np.random.default_rng(7).standard_normal((3, 3))),
    ("1.001 x a rotation", 1.001 * _near_identity()),
    ("a rotation with one nan", np.where(np.eye(3) > 0, math.nan, _near_identity())),
    ("-I (det -1)", -np.eye(3)),
]

#: dt values of every type and size: (label, value, kind) with kind "ok" (must be accepted), "bad" (must be refused)
#: or "either" (the observer's design rate decides: refused, or accepted with finite estimates)
DTS: list[tuple[str, Any, str]] = [
    ("0.005", 0.005, "ok"),
    ("0.001", 0.001, "ok"),
    ("np.float32(0.005)", np.float32(0.005), "ok"),
    ("np.float64(0.0025)", np.float64(0.0025), "ok"),
    ("0.02", 0.02, "either"),
    ("1e-9", 1e-9, "either"),
    ("0.1", 0.1, "either"),
    ("1.0", 1.0, "either"),
    ("1e6", 1e6, "bad"),
    ("1e300", 1e300, "bad"),
    ("0", 0.0, "bad"),
    ("-0.005", -0.005, "bad"),
    ("nan", math.nan, "bad"),
    ("inf", math.inf, "bad"),
    ("True", True, "bad"),
    ("'0.005'", "0.005", "bad"),
    ("None", None, "bad"),
    ("1j", 1j, "bad"),
    ("[0.005]", [0.005], "bad"),
    ("np.array([0.005, 0.005, 0.005])", np.array([0.005, 0.005, 0.005]), "bad"),
]
