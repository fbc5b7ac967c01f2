"""The FFTS-ESO's checked kernel (observers/ffts_eso.py ``ffts_eso_update``): the update's input checks, the law and
the estimate check in one compiled call, taken when the inputs are C-contiguous float64 arrays; any other input goes
through the Python checks.  Both ways must give the same estimates, the same errors and leave the state alike."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.eval.bench.observers import hover_measurement
from fawtgym.observers import make_observer
from fawtgym.observers.base import Observer

MASS = 1.5
J = np.diag([0.03, 0.03, 0.05])
KEYS = ("position", "velocity", "attitude", "angular_velocity")
DT = 0.005


def _pair(n: int) -> tuple[Observer, Observer, dict[str, np.ndarray]]:
    """Two FFTS-ESOs reset on the same measurement of n rows, and that measurement (C-contiguous float64)."""
    meas = {k: np.ascontiguousarray(v) for k, v in hover_measurement(n, np.random.default_rng(3)).items()
            if k in KEYS}
    a, b = make_observer("ffts_eso", MASS, J), make_observer("ffts_eso", MASS, J)
    a.reset(meas)
    b.reset(meas)
    return a, b, meas


def _inputs(n: int, k: int) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    rng = np.random.default_rng(10 + k)
    meas = {key: np.ascontiguousarray(v) for key, v in hover_measurement(n, rng).items() if key in KEYS}
    return meas, MASS * 9.80665 + 0.1 * rng.standard_normal(n), 0.01 * rng.standard_normal((n, 3))


def _strided(a: np.ndarray) -> np.ndarray:
    """The same values as a non-contiguous view."""
    wide = np.zeros(a.shape[:-1] + (2 * a.shape[-1],))
    wide[..., ::2] = a
    view = wide[..., ::2]
    assert not view.flags.c_contiguous
    return view


def _readonly(a: np.ndarray) -> np.ndarray:
    b = a.copy()
    b.flags.writeable = False
    return b


VARIANTS = {
    "strided": lambda m, f, t: ({k: _strided(v) for k, v in m.items()}, f, _strided(t)),
    "readonly": lambda m, f, t: ({k: _readonly(v) for k, v in m.items()}, _readonly(f), _readonly(t)),
    "lists": lambda m, f, t: ({k: v.tolist() for k, v in m.items()}, f.tolist(), t.tolist()),
    "float32-exact": lambda m, f, t: ({k: v.astype(np.float32) for k, v in m.items()}, f.astype(np.float32),
                                      t.astype(np.float32)),
}


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_other_input_types_give_the_same_estimates(n: int, variant: str) -> None:
    """Inputs the typed kernel refuses (views, read-only, lists, float32) take the Python checks and the same law:
    bitwise the estimates of C-contiguous float64 inputs of the same values, over several updates."""
    a, b, _ = _pair(n)
    for k in range(4):
        meas, f, tau = _inputs(n, k)
        if variant == "float32-exact":   # values a float32 holds exactly, so both observers see the same numbers
            meas = {key: v.astype(np.float32).astype(float) for key, v in meas.items()}
            f, tau = f.astype(np.float32).astype(float), tau.astype(np.float32).astype(float)
        ea = a.update(meas, f, tau, DT)
        eb = b.update(*VARIANTS[variant](meas, f, tau), DT)
        np.testing.assert_array_equal(ea.force, eb.force)
        np.testing.assert_array_equal(ea.torque, eb.torque)
        for key in ea.states:
            np.testing.assert_array_equal(ea.states[key], eb.states[key])


def test_unbatched_and_scalar_inputs_at_n1() -> None:
    """At N = 1 the single env's unbatched (3,) / (3, 3) arrays and a float thrust give the batched estimates."""
    a, b, _ = _pair(1)
    meas, f, tau = _inputs(1, 0)
    ea = a.update(meas, f, tau, DT)
    eb = b.update({k: v[0] for k, v in meas.items()}, float(f[0]), tau[0], DT)
    np.testing.assert_array_equal(ea.force, eb.force)
    np.testing.assert_array_equal(ea.torque, eb.torque)


BAD = {
    "nan position": lambda m, f, t: ({**m, "position": np.full_like(m["position"], np.nan)}, f, t),
    "scaled attitude": lambda m, f, t: ({**m, "attitude": 1.001 * m["attitude"]}, f, t),
    "inf rate": lambda m, f, t: ({**m, "angular_velocity": np.full_like(m["angular_velocity"], np.inf)}, f, t),
    "nan thrust": lambda m, f, t: (m, np.full_like(f, np.nan), t),
    "nan torque": lambda m, f, t: (m, f, np.full_like(t, np.nan)),
    "missing key": lambda m, f, t: ({k: v for k, v in m.items() if k != "velocity"}, f, t),
    "extra row": lambda m, f, t: ({**m, "position": np.concatenate([m["position"], m["position"][:1]])}, f, t),
    "thrust rows": lambda m, f, t: (m, np.concatenate([f, f[:1]]), t),
    "diverging rate": lambda m, f, t: ({**m, "angular_velocity": np.full_like(m["angular_velocity"], 1e200)}, f, t),
}


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("bad", sorted(BAD))
def test_bad_inputs_raise_as_the_python_checks_and_keep_the_state(n: int, bad: str) -> None:
    """A bad C-contiguous float64 input raises the Python layer's error (the same as for a list of the same values,
    which never reaches the compiled checks), and the state is as before: the next good update matches an observer
    that never saw the bad input."""
    a, b, _ = _pair(n)
    meas, f, tau = _inputs(n, 0)
    bad_meas, bad_f, bad_tau = BAD[bad](meas, f, tau)
    with pytest.raises((ValueError, FloatingPointError)) as fast:
        a.update(bad_meas, bad_f, bad_tau, DT)
    as_lists = {k: v.tolist() for k, v in bad_meas.items()}
    with pytest.raises(fast.type) as slow:
        _fresh_update(n, as_lists, bad_f.tolist(), bad_tau.tolist())
    assert str(fast.value) == str(slow.value)
    meas2, f2, tau2 = _inputs(n, 1)
    np.testing.assert_array_equal(a.update(meas2, f2, tau2, DT).force, b.update(meas2, f2, tau2, DT).force)


def _fresh_update(n: int, meas: object, f: object, tau: object) -> None:
    obs = make_observer("ffts_eso", MASS, J)
    obs.reset(_pair(n)[2])
    obs.update(meas, f, tau, DT)  # type: ignore[arg-type]


def test_a_subclass_overriding_the_hooks_takes_the_general_path() -> None:
    """The checked kernel stands for _update, _check_estimate and _commit of the FFTS-ESO: a subclass that
    overrides any of them gets them called (and the same estimate as the base)."""
    from fawtgym.observers.ffts_eso import FFTSESO

    calls: dict[str, int] = {"_update": 0, "_check_estimate": 0, "_commit": 0}

    class Hooked(FFTSESO):
        def _update(self, meas, thrust, torque, dt):  # type: ignore[no-untyped-def]
            calls["_update"] += 1
            return super()._update(meas, thrust, torque, dt)

        def _check_estimate(self, est, who):  # type: ignore[no-untyped-def]
            calls["_check_estimate"] += 1
            super()._check_estimate(est, who)

        def _commit(self, state):  # type: ignore[no-untyped-def]
            calls["_commit"] += 1
            super()._commit(state)

    assert FFTSESO._checked_path and not Hooked._checked_path
    a, _, meas = _pair(2)
    hooked = Hooked(MASS, J)
    hooked.reset(meas)
    for k in range(3):
        m, f, tau = _inputs(2, k)
        np.testing.assert_array_equal(hooked.update(m, f, tau, DT).force, a.update(m, f, tau, DT).force)
    assert calls == {"_update": 3, "_check_estimate": 3, "_commit": 3}
