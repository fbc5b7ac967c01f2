"""Observer.reset's guesses and options (audit D6 of issue 14): one check in the base class for every observer.

Unknown options -> the same one-line TypeError for every observer (naming them and the allowed ones); force / torque
guesses (and qb's ``thrust``) of the wrong type, shape or non-finite -> one one-line ValueError naming the argument and
the allowed shapes, the same text for every observer and at every N (the size named as ``N = <n>``); a refused reset,
full or per row, leaves the state bitwise as it was."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fawtgym.eval.bench.observers import hover_measurement
from fawtgym.observers import make_observer, observer_names

MASS = 1.5
J = np.diag([0.03, 0.03, 0.05])
NAMES = observer_names()


def _make(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # qb: the shipped gain was designed for another mass
        return make_observer(name, MASS, J)


def _guess_text(name, label, n, got):
    return (f"{name}: reset {label} guess must be finite real numbers of shape (3,) (every row) or (N, 3) with "
            f"N = {n} (one per row), got {got}")


def _thrust_text(n, got):
    return (f"qb: reset thrust must be a finite real number (every row) or shape (N,) with N = {n} (one per row), "
            f"got {got}")


# (label of the argument, the bad value for a batch of n, what the message says it got)
BAD_GUESSES = [
    ("force", lambda n: np.zeros(2), lambda n: "shape (2,)"),
    ("torque", lambda n: np.zeros((n + 1, 3)), lambda n: f"shape ({n + 1}, 3)"),
    ("force", lambda n: "abc", lambda n: "str of dtype <U3"),
    ("force", lambda n: True, lambda n: "bool of dtype bool"),
    ("torque", lambda n: [1j, 0, 0], lambda n: "list of dtype complex128"),
    ("force", lambda n: [[0, 0], [0]], lambda n: "list of dtype object"),
    ("torque", lambda n: [0.0, np.inf, 0.0], lambda n: "a non-finite entry: inf"),
    ("force", lambda n: np.full((n, 3), np.nan), lambda n: "a non-finite entry: nan"),
]


def _state(obs):
    """Everything the observer holds (arrays copied), to check a refused reset changed nothing."""
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in vars(obs).items()}


def _assert_same_state(before, obs):
    after = vars(obs)
    assert before.keys() == after.keys()
    for k, v in before.items():
        if isinstance(v, np.ndarray):
            assert after[k].shape == v.shape and after[k].tobytes() == v.tobytes(), k
        else:
            assert after[k] is v or after[k] == v, k


def _estimate(obs, meas):
    est = obs.update(meas, MASS * 9.80665, np.zeros(3), 0.005)
    return est.force.copy(), est.torque.copy()


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("case", range(len(BAD_GUESSES)))
def test_bad_guesses_same_text_for_every_observer_and_n(name, case):
    label, value, got = BAD_GUESSES[case]
    for n in (1, 3):
        obs = _make(name)
        meas = hover_measurement(n, np.random.default_rng(n))
        obs.reset(meas)
        before = _state(obs)
        with pytest.raises(ValueError) as info:
            obs.reset(meas, **{label: value(n)})
        assert str(info.value) == _guess_text(name, label, n, got(n))
        _assert_same_state(before, obs)
        # the per-row reset checks the guesses the same way (its guesses are of the whole batch)
        with pytest.raises(ValueError) as info:
            obs.reset(meas, rows=np.arange(n) == n - 1, **{label: value(n)})
        assert str(info.value) == _guess_text(name, label, n, got(n))
        _assert_same_state(before, obs)


@pytest.mark.parametrize("name", NAMES)
def test_unknown_options_one_text_for_every_observer(name):
    allowed = "force, torque, rows" + (", thrust" if name == "qb" else "")
    for n in (1, 3):
        obs = _make(name)
        meas = hover_measurement(n, np.random.default_rng(0))
        obs.reset(meas)
        before = _state(obs)
        for kwargs in ({"foo": 1}, {"rows": np.ones(n, bool), "foo": 1, "bar": None}):
            with pytest.raises(TypeError) as info:
                obs.reset(meas, **kwargs)
            unknown = sorted(k for k in kwargs if k != "rows")
            assert str(info.value) == f"{name}: unknown reset options {unknown}; allowed: {allowed}"
            _assert_same_state(before, obs)


@pytest.mark.parametrize("value,got", [(np.ones(2), "shape (2,)"), ("a", "str of dtype <U1"),
                                       (True, "bool of dtype bool"), (9.8 + 0j, "complex of dtype complex128"),
                                       (np.nan, "a non-finite entry: nan"), (np.ones((1, 1)), "shape (1, 1)")])
def test_qb_thrust_checked_as_the_guesses_are(value, got):
    for n in (1, 3):
        obs = _make("qb")
        meas = hover_measurement(n, np.random.default_rng(0))
        obs.reset(meas, thrust=14.0)
        before = _state(obs)
        for rows in (None, np.arange(n) == 0):
            with pytest.raises(ValueError) as info:
                obs.reset(meas, thrust=value, rows=rows)
            assert str(info.value) == _thrust_text(n, got)
            _assert_same_state(before, obs)


@pytest.mark.parametrize("name", NAMES)
def test_good_guesses_still_set_the_estimate(name):
    """(3,) and (N, 3) guesses, ints and float32 included, reach the state as before (the guesses are checked, not
    changed): a (3,) guess equals the same guess given per row; a per-row reset takes the masked rows of an (N, 3)."""
    n = 3
    meas = hover_measurement(n, np.random.default_rng(4))
    f, tau = np.array([0.5, -0.25, 1.0]), np.array([0.01, 0.0, -0.02])
    a, b = _make(name), _make(name)
    a.reset(meas, force=f, torque=tau)
    b.reset(meas, force=np.tile(f, (n, 1)).astype(np.float32).astype(np.float64), torque=np.tile(tau, (n, 1)))
    ea, eb = _estimate(a, meas), _estimate(b, meas)
    assert all(x.tobytes() == y.tobytes() for x, y in zip(ea, eb, strict=True))
    c = _make(name)
    c.reset(meas, force=[0, 0, 0])
    c.reset(meas, force=np.tile(f, (n, 1)), torque=np.tile(tau, (n, 1)), rows=np.ones(n, bool))
    assert all(x.tobytes() == y.tobytes() for x, y in zip(ea, _estimate(c, meas), strict=True))
