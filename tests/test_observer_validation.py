"""The observer validation layer (observers/base.py): every bad input gets the same exception type and text at
N = 1 and N = 3, for every registered observer; a diverging estimate is a FloatingPointError naming the observer
and the channel, and leaves the state as it was."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from fawtgym.core.so3 import exp_so3
from fawtgym.eval.bench.observers import hover_measurement
from fawtgym.observers import make_observer, observer_names
from fawtgym.observers.base import Observer

MASS = 1.5
J = np.diag([0.03, 0.03, 0.05])


def _make(name: str) -> Observer:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # qb: the shipped gain was designed for another mass
        return make_observer(name, MASS, J)


def _layered(name: str) -> bool:
    """True if the observer's update is the base class's (the validation layer in front of its law)."""
    return type(_make(name)).update is Observer.update


NAMES = observer_names()
#: hc_eso integrates each update with the previous sample held (its new sample is read by the next update), so an
#: absurd sample diverges one update later; tests/test_hc_eso_tumbling_and_errors.py checks that case
#: pdt_sta is gyroless: it reads only the accelerometer and the magnetometer, as directions (normalized)
NO_RATE_DIVERGENCE = {"hc_eso": "hc_eso holds the previous sample over the step: tested in "
                                "test_hc_eso_tumbling_and_errors.py",
                      "pdt_sta": "pdt_sta reads no rate and normalizes its vectors: an absurd sample cannot diverge it"}
LAYERED = [n for n in NAMES if _layered(n)]
#: the observers an absurd rate/position sample diverges in one update, and those that read the attitude
RATE_DIVERGING = [n for n in LAYERED if n not in NO_RATE_DIVERGENCE]
ATTITUDE_READERS = [n for n in LAYERED if "attitude" in _make(n).required_keys]


def test_every_observer_has_the_layer() -> None:
    """Every registered observer's update is the base class's: no observer bypasses the validation layer."""
    assert LAYERED == NAMES
    assert set(NO_RATE_DIVERGENCE) <= set(NAMES)


def _norm(msg: str) -> str:
    """Error text with the batch size it names (``N = <n>``) replaced: everything else must match."""
    return re.sub(r"N = \d+", "N = n", msg)


def _setup(name: str, n: int) -> tuple[Observer, dict[str, np.ndarray], np.ndarray, np.ndarray]:
    obs = _make(name)
    meas = {k: v[:n].copy() for k, v in hover_measurement(3, np.random.default_rng(1)).items()}  # same row 0
    obs.reset(meas)
    return obs, meas, np.full(n, MASS * 9.81), np.zeros((n, 3))


def _error(name: str, n: int, case: str) -> BaseException:
    """The exception ``case`` raises on a fresh observer of batch size n (the bad entry in row 0)."""
    obs, meas, f, tau = _setup(name, n)
    dt = 1e-3
    key = obs.required_keys[0]
    bad_rows = dict(meas)
    args: tuple = (meas, f, tau, dt)
    if case == "before_reset":
        obs = _make(name)
    elif case.startswith("dt="):
        args = (meas, f, tau, {"True": True, "str": "0.01", "None": None, "complex": 1e-3 + 0j, "nan": np.nan,
                               "neg": -1e-3, "zero": 0.0, "inf": np.inf, "huge": 1e6}[case[3:]])
    elif case == "meas_not_mapping":
        args = (5, f, tau, dt)
    elif case == "missing_key":
        args = ({k: v for k, v in meas.items() if k != key}, f, tau, dt)
    elif case == "wrong_trailing":
        bad_rows[key] = np.zeros(4)
        args = (bad_rows, f, tau, dt)
    elif case == "wrong_rows":
        bad_rows[key] = np.zeros((5,) + np.shape(meas[key])[1:])
        args = (bad_rows, f, tau, dt)
    elif case == "nonfinite":
        bad_rows[key] = meas[key].copy()
        bad_rows[key][0].flat[0] = np.nan
        args = (bad_rows, f, tau, dt)
    elif case == "complex":
        bad_rows[key] = meas[key] + 1j
        args = (bad_rows, f, tau, dt)
    elif case == "string":
        bad_rows[key] = "a"
        args = (bad_rows, f, tau, dt)
    elif case.startswith("attitude="):
        r = meas["attitude"].copy()
        rot = exp_so3(np.array([0.1, -0.2, 0.3]))
        r[0] = {"2I": 2 * np.eye(3), "reflection": np.diag([1.0, 1.0, -1.0]), "zeros": np.zeros((3, 3)),
                "random": np.arange(9.0).reshape(3, 3) / 7.0, "scaled": 1.001 * rot}[case[9:]]
        args = (dict(meas, attitude=r), f, tau, dt)
    elif case == "thrust_shape":
        args = (meas, np.ones(5), tau, dt)
    elif case == "thrust_nan":
        f = f.copy()
        f[0] = np.nan
        args = (meas, f, tau, dt)
    elif case == "thrust_complex":
        args = (meas, f + 0j, tau, dt)
    elif case == "thrust_set":
        args = (meas, {1.0}, tau, dt)
    elif case == "torque_shape":
        args = (meas, f, np.zeros((5, 3)), dt)
    elif case == "torque_nan":
        tau = tau.copy()
        tau[0, 1] = np.inf
        args = (meas, f, tau, dt)
    elif case == "torque_complex":
        args = (meas, f, tau + 1j, dt)
    else:
        raise AssertionError(case)
    with pytest.raises(Exception) as info:
        obs.update(*args)
    return info.value


CASES = {
    "before_reset": RuntimeError,
    **{f"dt={k}": TypeError for k in ("True", "str", "None", "complex")},
    **{f"dt={k}": ValueError for k in ("nan", "neg", "zero", "inf", "huge")},
    "meas_not_mapping": TypeError, "missing_key": ValueError, "wrong_trailing": ValueError, "wrong_rows": ValueError,
    "nonfinite": ValueError, "complex": TypeError, "string": TypeError,
    **{f"attitude={k}": ValueError for k in ("2I", "reflection", "zeros", "random", "scaled")},
    "thrust_shape": ValueError, "thrust_nan": ValueError, "thrust_complex": TypeError, "thrust_set": TypeError,
    "torque_shape": ValueError, "torque_nan": ValueError, "torque_complex": TypeError,
}


@pytest.mark.parametrize(("name", "case"), [(n, c) for n in LAYERED for c in sorted(CASES)
                                             if not c.startswith("attitude=") or n in ATTITUDE_READERS])
def test_same_error_at_every_batch_size(name: str, case: str) -> None:
    e1, e3 = _error(name, 1, case), _error(name, 3, case)
    assert type(e1) is CASES[case], (case, repr(e1))
    assert type(e3) is type(e1)
    assert _norm(str(e1)) == _norm(str(e3))
    text = str(e1)
    assert "\n" not in text and text.startswith(f"{name}: "), text
    if case.startswith("attitude="):
        assert "rotation" in text
    if case.startswith("dt=") and case not in ("dt=True", "dt=str", "dt=None", "dt=complex"):
        assert "max_dt" in text


@pytest.mark.parametrize("name", LAYERED)
def test_max_dt_is_accepted_and_bounds_the_step(name: str) -> None:
    obs, meas, f, tau = _setup(name, 1)
    assert 0.0 < obs.max_dt <= 0.1
    obs.update(meas, f, tau, obs.max_dt)
    with pytest.raises(ValueError, match="max_dt"):
        obs.update(meas, f, tau, np.nextafter(obs.max_dt, 1.0))


@pytest.mark.parametrize("name", RATE_DIVERGING)
@pytest.mark.parametrize("n", [1, 3])
def test_diverging_estimate_raises_and_keeps_the_state(name: str, n: int) -> None:
    """A finite but absurd measurement (rates of 1e200) makes every law's estimate leave the bound in one step."""
    obs, meas, f, tau = _setup(name, n)
    twin, _, _, _ = _setup(name, n)
    bad = dict(meas)
    for key in ("position", "velocity", "angular_velocity", "gyro"):
        bad[key] = meas[key].copy()
        bad[key][0] = 1e200
    with np.errstate(all="ignore"), pytest.raises(FloatingPointError) as info:
        obs.update(bad, f, tau, 1e-3)
    text = str(info.value)
    assert text.startswith(f"{name}: the ") and "estimate diverged" in text and "\n" not in text
    channel = text.split("the ", 1)[1].split(" estimate")[0]
    # the failed update changed nothing: the next good updates match an observer that never saw it
    for _ in range(3):
        a, b = obs.update(meas, f, tau, 1e-3), twin.update(meas, f, tau, 1e-3)
    assert channel in {"force", "torque"} | set(a.states)
    np.testing.assert_array_equal(a.force, b.force)
    np.testing.assert_array_equal(a.torque, b.torque)


@pytest.mark.parametrize("name", RATE_DIVERGING)
def test_state_unchanged_after_failed_update(name: str) -> None:
    obs, meas, f, tau = _setup(name, 3)
    twin, _, _, _ = _setup(name, 3)
    bad = dict(meas)
    bad["velocity"] = meas["velocity"] * 1e200
    bad["angular_velocity"] = meas["angular_velocity"] * 1e200
    bad["position"] = meas["position"] * 1e200
    with np.errstate(all="ignore"), pytest.raises(FloatingPointError):
        obs.update(bad, f, tau, 1e-3)
    for _ in range(3):
        a, b = obs.update(meas, f, tau, 1e-3), twin.update(meas, f, tau, 1e-3)
    np.testing.assert_array_equal(a.force, b.force)
    np.testing.assert_array_equal(a.torque, b.torque)
    for k in b.states:
        np.testing.assert_array_equal(a.states[k], b.states[k])


@pytest.mark.parametrize(("name", "case"), [(n, c) for n in LAYERED for c in ("missing_key", "nonfinite", "complex",
                                                                               "attitude")
                                             if c != "attitude" or n in ATTITUDE_READERS])
def test_reset_checks_the_measurement_alike_at_every_batch_size(name: str, case: str) -> None:
    """reset() runs the same measurement checks as update() (the keys the law reads) before building any state."""
    obs = _make(name)
    errors = []
    for n in (1, 3):
        meas = {k: v[:n].copy() for k, v in hover_measurement(3, np.random.default_rng(1)).items()}
        key = obs.required_keys[0]
        if case == "missing_key":
            del meas[key]
        elif case == "nonfinite":
            meas[key][0].flat[0] = np.inf
        elif case == "complex":
            meas[key] = meas[key] * (1 + 0j)
        else:
            meas["attitude"][0] = np.diag([1.0, 1.0, -1.0])
        fresh = _make(name)
        with pytest.raises((ValueError, TypeError)) as info:
            fresh.reset(meas)
        errors.append(info.value)
        with pytest.raises(RuntimeError):          # nothing was built: the observer is still not reset
            fresh.update(meas, np.zeros(n), np.zeros((n, 3)), 1e-3)
    assert type(errors[0]) is type(errors[1]) and _norm(str(errors[0])) == _norm(str(errors[1]))
