"""Observer input defects of the second audit of issue 14 (/work/review2/findings.md A4-A7), for every registered
observer at N = 1 and N = 3: the one-line error (exact text, exception type) and a refused call changes nothing
(the next valid calls give bitwise the estimates of an observer that never saw the refused call)."""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.checks import shown
from fawtgym.eval.bench.observers import hover_measurement
from fawtgym.observers import make_observer, observer_names
from fawtgym.observers.base import Observer

MASS = 1.5
J = np.diag([0.03, 0.03, 0.05])
NAMES = observer_names()
DT = 2e-3


def _make(name: str, mass: float = MASS, inertia: object = J, **kwargs: object) -> Observer:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # qb: the shipped gain was designed for another mass
        return make_observer(name, mass, inertia, **kwargs)


def _measurement(n: int, seed: int = 1) -> dict[str, np.ndarray]:
    """n rows of a hovering vehicle's measurement (row 0 the same for every n)."""
    return {k: v[:n].copy() for k, v in hover_measurement(3, np.random.default_rng(seed)).items()}


def _inputs(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.full(n, MASS * 9.81), np.zeros((n, 3))


def _run(obs: Observer, n: int, steps: int = 3) -> list[np.ndarray]:
    """The estimates (force and torque side by side) of ``steps`` valid updates on fresh measurements."""
    f, tau = _inputs(n)
    out = []
    for k in range(steps):
        est = obs.update(_measurement(n, seed=10 + k), f, tau, DT)
        out.append(np.concatenate([est.force, est.torque], axis=1))
    return out


def _refused(name: str, n: int, call: Callable[[Observer], object], kind: type[BaseException]) -> str:
    """The one-line text of the error ``call`` raises on a reset observer of batch size n; checks that the observer's
    next valid updates equal, bitwise, those of a twin that never saw the call."""
    obs, twin = _make(name), _make(name)
    meas = _measurement(n)
    obs.reset(meas)
    twin.reset(meas)
    with pytest.raises(kind) as info:
        call(obs)
    text = str(info.value)
    assert "\n" not in text
    for a, b in zip(_run(obs, n), _run(twin, n), strict=True):
        np.testing.assert_array_equal(a, b)
    return text


def _norm(text: str) -> str:
    return re.sub(r"N = \d+", "N = n", text)


# ---- A4: dt beyond float range ------------------------------------------------------------------------------------
#: the observers whose law divides by dt, and why (the floor of A5)
FLOORED = {"fxtsdo": "the finite difference of the velocities divides by dt",
           "qb": "the first-order hold divides by dt"}


def _dt_message(obs: Observer, got: str) -> str:
    if obs.name in FLOORED:
        return (f"{obs.name}: dt must be a finite number of seconds in [1e-09, {obs.max_dt:g}] (min_dt: "
                f"{FLOORED[obs.name]}; max_dt, the bound of its discretisation), got {got}")
    return (f"{obs.name}: dt must be a finite number of seconds in (0, {obs.max_dt:g}] (max_dt, the bound of its "
            f"discretisation), got {got}")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("dt", [10**400, -(10**400)], ids=["10**400", "-10**400"])
def test_a_dt_beyond_float_range_is_the_dt_error(name: str, n: int, dt: int) -> None:
    """A4: float(10**400) raises OverflowError; it is the dt message (naming the int as given), not a bare one."""
    text = _refused(name, n, lambda o: o.update(_measurement(n), *_inputs(n), dt), ValueError)
    assert text == _dt_message(_make(name), shown(dt))


@pytest.mark.parametrize("gamma", [10**400, -(10**400), 2.5, 0, True, "2"], ids=str)
def test_hc_eso_gamma_beyond_float_range_is_the_gamma_error(gamma: object) -> None:
    """A4: hc_eso's gamma went through float() unguarded (OverflowError for 10**400)."""
    with pytest.raises(ValueError) as info:
        _make("hc_eso", gamma=gamma)
    assert str(info.value) == (f"hc_eso: gamma must be a positive integer (Prop. 3), finite as a float, got "
                               f"{shown(gamma)}")
    assert _make("hc_eso", gamma=3).gains.gamma == 3


# ---- A5: a dt floor for the laws that divide by dt ----------------------------------------------------------------
def _stepped(name: str, n: int, dt: float) -> np.ndarray:
    """The estimate (force, torque) of one update by ``dt`` after a reset, the velocities 1 cm/s and 0.01 rad/s off the
    reset's (the audit's scripts/repro_fxtsdo_dt.py, for every observer and key)."""
    obs = _make(name)
    meas = _measurement(n)
    obs.reset(meas)
    moved = {k: v + (0.01 if v.ndim == 2 else 0.0) for k, v in meas.items()}
    est = obs.update(moved, *_inputs(n), dt)
    return np.concatenate([est.force, est.torque], axis=1)


@pytest.mark.parametrize("name", sorted(FLOORED))
@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("dt", [float(np.nextafter(1e-9, 0.0)), 1e-12, 1e-300, 5e-324])
def test_a_dt_below_the_floor_of_a_dividing_law_is_the_dt_error(name: str, n: int, dt: float) -> None:
    """A5: fxtsdo's finite difference divides by dt; a tiny dt was accepted and its estimate (growing like dt^-1/2)
    reported as divergence, inf at a subnormal dt.  Now refused with the dt message naming min_dt (as qb's)."""
    text = _refused(name, n, lambda o: o.update(_measurement(n), *_inputs(n), dt), ValueError)
    assert text == _dt_message(_make(name), repr(dt))
    assert _make(name).min_dt == 1e-9
    assert np.isfinite(_stepped(name, n, 1e-9)).all()      # the floor itself is accepted


@pytest.mark.parametrize("name", [n for n in NAMES if n not in FLOORED])
def test_the_laws_that_do_not_divide_by_dt_take_any_positive_dt(name: str) -> None:
    """The other observers integrate with dt as a factor (Euler steps, expm of F dt, substeps of dt): a subnormal dt
    changes their state by (almost) nothing, so they keep the range (0, max_dt]."""
    assert _make(name).min_dt == 5e-324
    for dt in (1e-9, 1e-300, 5e-324):
        est = _stepped(name, 3, dt)
        np.testing.assert_allclose(est, _stepped(name, 3, 1e-15), rtol=0, atol=1e-6)


def test_fxtsdo_gains_whose_max_dt_is_below_the_floor_keep_max_dt() -> None:
    """k2 = 1e6, a2 = 3.5 (the largest accepted) gives max_dt = 6e-12 s < 1 ns: min_dt = max_dt, that step runs."""
    obs = _make("fxtsdo", k2=1e6, a2=3.5)
    assert obs.min_dt == obs.max_dt < 1e-9
    obs.reset(_measurement(1))
    obs.update(_measurement(1), *_inputs(1), obs.max_dt)
    with pytest.raises(ValueError, match=re.escape(f"in [{obs.max_dt:g}, {obs.max_dt:g}] (min_dt: ")):
        obs.update(_measurement(1), *_inputs(1), obs.max_dt / 2)


# ---- A6: reset guesses beyond the divergence bound ----------------------------------------------------------------
def _guess_message(obs: Observer, label: str, got: str) -> str:
    force_bound, torque_bound = obs.estimate_bounds()
    if label == "force":
        bound, unit, meaning = force_bound, "N", "1000 vehicle weights m g"
    else:
        bound, unit, meaning = torque_bound, "N m", "100000 rad/s^2 times the largest principal inertia"
    return (f"{obs.name}: reset {label} guess must be within the divergence bound of the estimate, "
            f"|component| <= {bound:.10g} {unit} ({meaning}; an update refuses a larger estimate), got {got}")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("label", ["force", "torque"])
@pytest.mark.parametrize("per_row", [False, True], ids=["every-row", "per-row"])
@pytest.mark.parametrize("masked", [False, True], ids=["full", "rows-mask"])
def test_a_guess_beyond_the_divergence_bound_is_refused_at_reset(name: str, n: int, label: str, per_row: bool,
                                                                 masked: bool) -> None:
    """A6: reset(force=[1e300, 0, 0]) was accepted and every later update raised 'the force estimate diverged'.  Now
    the reset is refused naming the bound (the same for a per-row reset) and the state is the one before it."""
    obs = _make(name)
    bound = obs.estimate_bounds()[label == "torque"]
    big = float(np.nextafter(bound, np.inf))
    guess = np.zeros((n, 3)) if per_row else np.zeros(3)
    (guess[n - 1] if per_row else guess)[1] = -big
    kwargs = {label: guess, "rows": np.ones(n, bool) if masked else None}
    text = _refused(name, n, lambda o: o.reset(_measurement(n), **kwargs), ValueError)
    got = f"row {n - 1}: {[0.0, -big, 0.0]}" if per_row else f"{[0.0, -big, 0.0]}"
    assert text == _guess_message(obs, label, got)
    if per_row:
        assert text.endswith(f"got row {n - 1}: [0.0, {-big!r}, 0.0]")
    ok = _make(name)            # just below the bound a guess is accepted (qb rotates the torque: a rounding above)
    ok.reset(_measurement(n), **{label: [0.0, bound * (1 - 1e-12), 0.0]})
    ok.reset(_measurement(n), **{label: np.full((n, 3), -bound / 2)})


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("label", ["force", "torque"])
def test_the_guess_bound_error_is_the_same_text_at_every_n(name: str, label: str) -> None:
    texts = set()
    for n in (1, 3):
        with pytest.raises(ValueError) as info:
            obs = _make(name)
            obs.reset(_measurement(n), **{label: [1e300, 0.0, 0.0]})
        texts.add(_norm(str(info.value)))
    assert len(texts) == 1
    assert texts.pop() == _guess_message(_make(name), label, "[1e+300, 0.0, 0.0]")


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("masked", [False, True], ids=["full", "rows-mask"])
def test_qb_refuses_a_thrust_whose_initial_force_is_beyond_the_bound(n: int, masked: bool) -> None:
    """qb without a force guess starts its force from the accelerometer and the reset's ``thrust``: thrust = 1e9 N was
    accepted, then every update raised 'the force estimate diverged'.  Refused at reset (naming the batch's row)."""
    thrust = np.full(n, MASS * 9.81)
    thrust[n - 1] = 1e9
    kwargs = {"thrust": thrust, "rows": np.ones(n, bool) if masked else None}
    if masked and n == 3:
        kwargs["rows"] = np.array([False, True, True])
    text = _refused("qb", n, lambda o: o.reset(_measurement(n), **kwargs), ValueError)
    bound = _make("qb").estimate_bounds()[0]
    assert text.startswith(f"qb: reset: the initial force estimate is beyond the divergence bound of the estimate "
                           f"(row {n - 1}: [")
    assert text.endswith(f"allowed: |component| <= {bound:.10g}; an update refuses a larger estimate): check the "
                         "measurement and thrust")


# ---- audit item 9 (observers): tiny or huge finite mass, gravity, inertia -----------------------------------------
@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("mass", [5e-324, 1e-300, 9.99e-5, 1.0001e4, 1e300])
def test_a_mass_outside_the_physical_range_is_refused(name: str, mass: float) -> None:
    """qb accepted mass 1e-300 / 1e300 and then every update 'diverged'; every observer accepted a subnormal mass."""
    with pytest.raises(ValueError) as info:
        _make(name, mass=mass, inertia=np.full(3, 1e-6))
    assert str(info.value) == f"{name}: mass must be a finite real number in [0.0001, 10000] kg, got {mass!r} (float)"


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("gravity", [5e-324, 1e-300, 0.0999])
def test_a_gravity_below_the_physical_range_is_refused(name: str, gravity: float) -> None:
    """gravity 1e-300 was accepted: the divergence bound 1e3 m g became 1e-297 N and every update of ffts_eso, fxtsdo,
    geso, leso, qb and sto 'diverged'; pdt_sta's reset raised numpy's LinAlgError."""
    with pytest.raises(ValueError) as info:
        _make(name, gravity=gravity)
    assert str(info.value) == (f"{name}: gravity must be a finite real number in [0.1, 250] m/s^2, got {gravity!r} "
                               "(float)")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("inertia,moment", [((5e-324,) * 3, 5e-324), ((1e-300, 0.03, 0.05), 1e-300),
                                            ((0.03, 0.03, 1e300), 1e300), ((1.4e-6, 0.03, 0.05), 1.4e-6)])
def test_an_inertia_no_body_of_the_mass_can_have_is_refused(name: str, inertia: tuple, moment: float) -> None:
    """A subnormal inertia was accepted (its inverse is inf: every update 'diverged' in 7 of 8 observers), qb's every
    update diverged at 1e300.  Each principal moment must have a radius of gyration in [1 mm, 100 m]."""
    radius = (moment / MASS) ** 0.5
    assert not 1e-3 <= radius <= 1e2
    with pytest.raises(ValueError) as info:
        _make(name, inertia=inertia)
    assert str(info.value) == (f"{name}: inertia must be a 3x3 matrix or 3 diagonal entries of finite real numbers "
                               f"[kg m^2], positive definite, with every radius of gyration sqrt(principal moment / "
                               f"mass) in [0.001, 100] m, got {inertia!r} (principal moment {moment:.4g} kg m^2, mass "
                               f"1.5 kg: radius {radius:.4g} m)")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("mass,radius,gravity", [(1e-4, 1e-3, 9.80665), (1e-4, 1e2, 9.80665), (1e4, 1e-3, 9.80665),
                                                 (1e4, 1e2, 9.80665), (1.5, 0.15, 0.1)])
def test_the_range_limits_are_accepted_and_fly(name: str, mass: float, radius: float, gravity: float) -> None:
    """At the limits of the ranges every observer runs 20 updates of a hovering vehicle (Earth-gravity measurement)
    without a divergence (the radius a little inside its range: eigvalsh rounds)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        obs = make_observer(name, mass, np.full(3, mass * radius**2 * (1 + 1e-9 if radius < 1 else 1 - 1e-9)),
                            gravity=gravity)
    obs.reset(_measurement(3))
    for k in range(20):
        est = obs.update(_measurement(3, seed=20 + k), np.full(3, mass * 9.81), np.zeros((3, 3)), DT)
    assert np.isfinite(est.force).all() and np.isfinite(est.torque).all()


# ---- audit item 11 (observers): smaller items ---------------------------------------------------------------------
@pytest.mark.parametrize("name", [n for n in NAMES if hasattr(_make(n), "estimate")])
def test_estimate_before_reset_has_one_text_for_every_observer(name: str) -> None:
    """qb said 'estimate() before reset(); ...', the others only 'call reset(measurement) first'."""
    with pytest.raises(RuntimeError) as info:
        _make(name).estimate()
    assert str(info.value) == f"{name}: estimate() before reset(); call reset(measurement) first"


@pytest.mark.parametrize("noise_bound", [1e300, 0.3])
def test_pdt_sta_noise_bound_beyond_t_c_over_eta_names_noise_bound(noise_bound: float) -> None:
    """noise_bound = 1e300 gave 't_e = t_c - eta*ell = -5e+300 is not after t0 = 0.0', naming no argument."""
    with pytest.raises(ValueError) as info:
        _make("pdt_sta", noise_bound=noise_bound)
    assert str(info.value) == ("pdt_sta: noise_bound must be a finite real number in [0, 0.3) (ell of eq. 42; below "
                               "t_c / eta, so that the early switch t_e = t_c - eta ell of eq. 43 is after t = 0), got "
                               f"{noise_bound!r} ({type(noise_bound).__name__})")
    assert _make("pdt_sta", noise_bound=0.29).core.t_s == pytest.approx(1.5 - 5 * 0.29)


@pytest.mark.parametrize("channels", [5, None, 2.5])
def test_geso_channels_not_iterable_is_the_channels_error(channels: object) -> None:
    """channels=5 gave a bare "TypeError: 'int' object is not iterable"."""
    with pytest.raises(ValueError) as info:
        _make("geso", channels=channels)
    assert str(info.value) == f"GESO channels must be a non-empty subset of ('force', 'torque'), got {channels!r}"


@pytest.mark.parametrize("name,kwargs", [("geso", {}), ("geso", {"channels": "torque", "order": 2}),
                                         ("geso", {"hold": "zoh"}), ("hc_eso", {})])
@pytest.mark.parametrize("n", [1, 3])
def test_estimate_is_the_last_updates_estimate(name: str, kwargs: dict, n: int) -> None:
    """geso and hc_eso had no estimate() (AttributeError): it now returns, bitwise, what the last update returned
    (the same row helper the update's kernel uses), and after a reset the guesses."""
    obs = _make(name, **kwargs)
    obs.reset(_measurement(n), force=[0.25, 0.0, 0.0], torque=[0.0, 0.01, 0.0])
    first = obs.estimate()
    if "force" in obs.channels:
        np.testing.assert_array_equal(first.force, np.tile([0.25, 0.0, 0.0], (n, 1)))
    # the torque guess comes back as J (J^-1 tau): a round trip through the inverse inertia (cond: J's condition
    # number), compared to the policy's tolerance for the guess's magnitude (tests/_tolerance.py)
    assert_same_law(first.torque, np.tile([0.0, 0.01, 0.0], (n, 1)), scale=0.01, cond=float(np.linalg.cond(J)),
                    what="torque guess")
    for k in range(3):
        est = obs.update(_measurement(n, seed=30 + k), *_inputs(n), DT)
    again = obs.estimate()
    for a, b in [(est.force, again.force), (est.torque, again.torque),
                 *((est.states[key], again.states[key]) for key in est.states)]:
        np.testing.assert_array_equal(a, b)
    assert list(again.states) == list(est.states)
