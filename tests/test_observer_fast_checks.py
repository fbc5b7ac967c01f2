"""Observer.update's compiled input checks (observers/base.py ``_passed_measurement``, observers/_checks.py
``INPUT_CHECKS``): every observer without a fused checked kernel checks C-contiguous float64 inputs in one compiled
call, then runs its law exactly as after the Python checks.  Both ways must give bitwise the same estimates, the same
errors (type and text) at N = 1 and N = 3, and leave the state alike after a refused update."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from types import MappingProxyType
from typing import Any

import numpy as np
import pytest

from fawtgym.eval.bench.observers import hover_measurement
from fawtgym.observers import base, make_observer, observer_names
from fawtgym.observers.base import Observer, _input_checks

MASS = 1.5
J = np.diag([0.03, 0.03, 0.05])
DT = 2e-3
#: every shipped key set: the registered observers with their defaults, and the options that change the keys
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    **{name: (name, {}) for name in observer_names() if name != "ffts_eso"},
    "geso force": ("geso", {"channels": "force"}), "geso torque": ("geso", {"channels": "torque"}),
    "geso gyro": ("geso", {"rate_key": "gyro"}), "hc_eso attitude": ("hc_eso", {"vectors": "attitude"}),
}


def _make(variant: str) -> Observer:
    name, options = VARIANTS[variant]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # qb: the shipped gain was designed for another mass
        return make_observer(name, MASS, J, **options)


def _inputs(n: int, k: int) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """A hover-like measurement (every key, C-contiguous float64), thrust and torque of n rows; row 0 the same at
    every n (the same error text)."""
    rng = np.random.default_rng(20 + k)
    meas = {key: np.ascontiguousarray(v[:n]) for key, v in hover_measurement(3, rng).items()}
    return meas, MASS * 9.80665 + 0.1 * rng.standard_normal(3)[:n], 0.001 * rng.standard_normal((3, 3))[:n]


def _pair(variant: str, n: int) -> tuple[Observer, Observer]:
    a, b = _make(variant), _make(variant)
    meas = _inputs(n, 0)[0]
    a.reset(meas)
    b.reset(meas)
    return a, b


def _python_path(meas: dict[str, np.ndarray]) -> MappingProxyType[str, np.ndarray]:
    """The same arrays behind a mapping that is not a dict: the compiled checks refuse it, the Python checks pass the
    arrays on unchanged (today's path, by construction the reference)."""
    return MappingProxyType(meas)


@pytest.fixture()
def python_checks(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts the calls of the Python measurement checks (zero when the compiled checks passed)."""
    calls = {"check_measurement": 0}
    original = base.check_measurement

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls["check_measurement"] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(base, "check_measurement", counted)
    return calls


def _assert_same_estimate(a: Any, b: Any) -> None:
    np.testing.assert_array_equal(a.force, b.force)
    np.testing.assert_array_equal(a.torque, b.torque)
    assert list(a.states) == list(b.states)
    for key in b.states:
        np.testing.assert_array_equal(a.states[key], b.states[key])


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_shipped_key_set_has_compiled_checks(variant: str) -> None:
    """The kernel family covers the key set of every shipped observer (and its key-changing options)."""
    obs = _make(variant)
    assert not obs._checked_path
    assert _input_checks(obs.required_keys)[0] is not None, obs.required_keys


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_same_estimates_as_the_python_checks(variant: str, n: int, python_checks: dict[str, int]) -> None:
    """The same update sequence through the compiled checks and through the Python checks: bitwise the same
    estimates (force, torque, every state) at every step, so the same state."""
    fast, slow = _pair(variant, n)
    for k in range(1, 6):
        meas, f, tau = _inputs(n, k)
        before = python_checks["check_measurement"]
        est_fast = fast.update(meas, f, tau, DT)
        assert python_checks["check_measurement"] == before, "the compiled checks were not taken"
        est_slow = slow.update(_python_path(meas), f, tau, DT)
        assert python_checks["check_measurement"] == before + 1
        _assert_same_estimate(est_fast, est_slow)


def _with(key: str, make: Callable[[np.ndarray], np.ndarray]) -> Callable[..., tuple[Any, Any, Any]]:
    return lambda m, f, t: ({**m, key: make(m[key])}, f, t)


def _nan_row0(a: np.ndarray) -> np.ndarray:
    b = a.copy()
    b[0] = np.nan
    return b


def _strided(a: np.ndarray) -> np.ndarray:
    wide = np.zeros(a.shape[:-1] + (2 * a.shape[-1],))
    wide[..., ::2] = a
    return wide[..., ::2]


def _readonly(a: np.ndarray) -> np.ndarray:
    b = a.copy()
    b.flags.writeable = False
    return b


def _attitude_row0(r0: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    def make(r: np.ndarray) -> np.ndarray:
        b = r.copy()
        b[0] = r0
        return b
    return make


#: bad values that reach the compiled checks (C-contiguous float64 arrays of the right shapes): an error
BAD_VALUES: dict[str, Callable[..., tuple[Any, Any, Any]]] = {
    "thrust nan": lambda m, f, t: (m, _nan_row0(f), t),
    "thrust inf": lambda m, f, t: (m, np.full_like(f, np.inf), t),
    "torque nan": lambda m, f, t: (m, f, _nan_row0(t)),
    "attitude scaled": _with("attitude", lambda r: 1.001 * r),
    "attitude reflection": _with("attitude", _attitude_row0(np.diag([1.0, 1.0, -1.0]))),
    "attitude 2I": _with("attitude", _attitude_row0(2 * np.eye(3))),
    **{f"{key} nan": _with(key, _nan_row0) for key in ("position", "velocity", "attitude", "angular_velocity",
                                                        "gyro", "specific_force", "magnetometer")},
    "velocity inf": _with("velocity", lambda a: np.full_like(a, np.inf)),
}
#: inputs of another type, shape or layout: refused by the compiled checks (TypeError at the call, or a shape
#: check in the kernel); the Python checks convert them or word the error
OTHER_INPUTS: dict[str, Callable[..., tuple[Any, Any, Any]]] = {
    **{f"{key} {kind}": _with(key, make) for key in ("velocity", "attitude", "specific_force")
       for kind, make in (("float32", lambda a: a.astype(np.float32)), ("strided", _strided),
                          ("readonly", _readonly), ("list", lambda a: a.tolist()),
                          ("extra row", lambda a: np.concatenate([a, a[:1]])),
                          ("unbatched", lambda a: a[0].copy()), ("masked", lambda a: np.ma.masked_array(a)))},
    "thrust float32": lambda m, f, t: (m, f.astype(np.float32), t),
    "thrust scalar": lambda m, f, t: (m, float(f[0]), t),
    "thrust rows": lambda m, f, t: (m, np.concatenate([f, f[:1]]), t),
    "torque strided": lambda m, f, t: (m, f, _strided(t)),
    "torque unbatched": lambda m, f, t: (m, f, t[0].copy()),
    "torque masked": lambda m, f, t: (m, f, np.ma.masked_array(t)),
    "torque 2-d thrust": lambda m, f, t: (m, f[:, None].copy(), t),
    "missing key": lambda m, f, t: ({k: v for k, v in m.items() if k not in ("velocity", "specific_force")}, f, t),
    "not a dict": lambda m, f, t: (MappingProxyType(m), f, t),
}


def _outcome(obs: Observer, meas: Any, f: Any, tau: Any) -> tuple[str, Any]:
    """("ok", estimate) or (exception type name, its text)."""
    try:
        with np.errstate(all="ignore"):
            return "ok", obs.update(meas, f, tau, DT)
    except (ValueError, TypeError, FloatingPointError) as e:
        return type(e).__name__, str(e)


def _reads(obs: Observer, case: str) -> bool:
    """Whether ``case`` spoils an input the observer reads (else it must not raise)."""
    key = case.split(" ")[0]
    return key in ("thrust", "torque") or key in obs.required_keys or case in ("missing key", "not a dict")


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("case", sorted(BAD_VALUES) + sorted(OTHER_INPUTS))
@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_refused_inputs_take_the_python_checks(variant: str, case: str, n: int) -> None:
    """Each bad value or other input type: the same outcome as through the Python checks alone (the same exception
    type and text, or bitwise the same estimate), and after a refused update the state is as before (the next good
    update matches an observer that never saw it)."""
    fast, slow = _pair(variant, n)
    twin = _pair(variant, n)[0]
    meas, f, tau = _inputs(n, 1)
    bad_meas, bad_f, bad_tau = {**BAD_VALUES, **OTHER_INPUTS}[case](meas, f, tau)
    got = _outcome(fast, bad_meas, bad_f, bad_tau)
    want = _outcome(slow, _python_path(dict(bad_meas)), bad_f, bad_tau)
    assert got[0] == want[0], (got, want)
    if got[0] == "ok":
        _assert_same_estimate(got[1], want[1])
        assert case in OTHER_INPUTS or not _reads(fast, case), case
        return
    assert got[1] == want[1]
    assert "\n" not in got[1] and got[1].startswith(f"{fast.name}: ")
    if case in BAD_VALUES:
        assert got[0] == "ValueError" and _reads(fast, case)
    good, gf, gt = _inputs(n, 2)
    _assert_same_estimate(fast.update(good, gf, gt, DT), twin.update(good, gf, gt, DT))


@pytest.mark.parametrize("case", sorted(BAD_VALUES))
@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_the_same_error_text_at_n1_and_n3(variant: str, case: str) -> None:
    """A bad value in row 0 gives the same exception and text at N = 1 and N = 3 through the compiled checks."""
    out = []
    for n in (1, 3):
        obs = _pair(variant, n)[0]
        meas, f, tau = _inputs(n, 1)
        out.append(_outcome(obs, *BAD_VALUES[case](meas, f, tau)))
    assert out[0][0] == out[1][0]
    if out[0][0] != "ok":
        assert out[0][1] == out[1][1]


def test_masked_arrays_reach_the_law_as_plain_arrays(monkeypatch: pytest.MonkeyPatch) -> None:
    """An ndarray subclass passes numba's typed dispatch: it must still go through the Python checks, which hand the
    law plain ndarrays (as before the compiled checks)."""
    obs = _pair("leso", 2)[0]
    seen: list[type] = []
    law = type(obs)._update

    def spy(self: Observer, meas: dict[str, np.ndarray], f: np.ndarray, tau: np.ndarray, dt: float) -> Any:
        seen.extend(type(v) for v in (*meas.values(), f, tau))
        return law(self, meas, f, tau, dt)

    monkeypatch.setattr(type(obs), "_update", spy)
    meas, f, tau = _inputs(2, 1)
    obs.update({k: np.ma.masked_array(v) for k, v in meas.items()}, np.ma.masked_array(f), tau, DT)
    assert seen and all(t is np.ndarray for t in seen)


def test_a_key_set_outside_the_family_takes_the_python_checks(python_checks: dict[str, int]) -> None:
    """A key the kernel family has no kind for (``time``, shape (N,)): no compiled checks, the same estimates."""
    from fawtgym.observers.leso import LESO

    class Timed(LESO):
        required_keys = (*LESO.required_keys, "time")

    a, b = Timed(MASS, J), LESO(MASS, J)
    meas = _inputs(2, 0)[0]
    a.reset(meas)
    b.reset(meas)
    assert _input_checks(Timed.required_keys)[0] is None
    meas, f, tau = _inputs(2, 1)
    before = python_checks["check_measurement"]
    _assert_same_estimate(a.update(meas, f, tau, DT), b.update(meas, f, tau, DT))
    assert python_checks["check_measurement"] == before + 1   # Timed's update; LESO's took the compiled checks
    with pytest.raises(ValueError, match=r"measurement\['time'\] has a non-finite entry in row 0"):
        a.update({**meas, "time": np.full(2, np.nan)}, f, tau, DT)


@pytest.mark.parametrize("owner", ["sto", "ffts_eso"])
def test_an_overridden_law_runs_after_the_compiled_checks(owner: str, python_checks: dict[str, int]) -> None:
    """A subclass's _update, _check_estimate and _commit run on the compiled path as on the Python path (also for a
    subclass of the FFTS-ESO that overrides its law, which then leaves the FFTS-ESO's fused kernel)."""
    from fawtgym.observers.base import observer_class

    cls = observer_class(owner)
    calls = {"_update": 0, "_check_estimate": 0, "_commit": 0}

    class Hooked(cls):  # type: ignore[valid-type, misc]
        def _update(self, *args: Any) -> Any:
            calls["_update"] += 1
            return super()._update(*args)

        def _check_estimate(self, *args: Any) -> None:
            calls["_check_estimate"] += 1
            super()._check_estimate(*args)

        def _commit(self, state: Any) -> None:
            calls["_commit"] += 1
            super()._commit(state)

    a, b = Hooked(MASS, J), cls(MASS, J)
    meas = _inputs(3, 0)[0]
    a.reset(meas)
    b.reset(meas)
    before = python_checks["check_measurement"]
    for k in range(1, 4):
        meas, f, tau = _inputs(3, k)
        _assert_same_estimate(a.update(meas, f, tau, DT), b.update(meas, f, tau, DT))
    assert calls == {"_update": 3, "_check_estimate": 3, "_commit": 3}
    assert python_checks["check_measurement"] == before
