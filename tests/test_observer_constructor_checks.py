"""Observer constructors (audit D5 of issue 14): mass, inertia, gravity and every gain get a one-line ValueError naming
the argument and what is allowed -- real (bool, complex, str, None refused), finite, in range -- and gains that would
overflow the design (the audit's 1e300 cases: a bare OverflowError, a numpy LinAlgError) are refused up front with
the bound in the message."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from fawtgym.core.checks import check_number, check_positive
from fawtgym.observers import make_observer, observer_names

J = np.diag([0.03, 0.03, 0.06])
BAD_REALS = [("a", "'a' (str)"), (None, "None (NoneType)"), (True, "True (bool)"), (np.True_, "np.True_ (bool)"),
             (1 + 0j, "(1+0j) (complex)"), (float("nan"), "nan (float)"), (float("inf"), "inf (float)"),
             (-1.0, "-1.0 (float)"), (0, "0 (int)")]


def _make(name, mass=1.0, inertia=J, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # qb: the shipped gain was designed for another mass
        return make_observer(name, mass, inertia, **kwargs)


def _one_line(exc: BaseException) -> str:
    text = str(exc)
    assert "\n" not in text, text
    return text


@pytest.mark.parametrize("name", observer_names())
@pytest.mark.parametrize("value,shown", BAD_REALS)
def test_mass_must_be_a_real_positive_number(name, value, shown):
    with pytest.raises(ValueError) as info:
        _make(name, mass=value)
    assert _one_line(info.value) == f"{name}: mass must be a finite real number in [0.0001, 10000] kg, got {shown}"


@pytest.mark.parametrize("name", observer_names())
@pytest.mark.parametrize("value,shown", [*BAD_REALS, (-9.80665, "-9.80665 (float)"), (1e300, "1e+300 (float)")])
def test_gravity_must_be_a_real_positive_bounded_number(name, value, shown):
    """A NaN or negative gravity used to be accepted and make every update fail (the divergence bound m g 1e3 was
    NaN or negative); 1e300 made that bound meaningless."""
    with pytest.raises(ValueError) as info:
        _make(name, gravity=value)
    assert _one_line(info.value) == f"{name}: gravity must be a finite real number in [0.1, 250] m/s^2, got {shown}"


@pytest.mark.parametrize("name", observer_names())
@pytest.mark.parametrize("inertia,tail", [
    ("abc", "'abc' (dtype <U3)"), ((True, True, True), "(True, True, True) (dtype bool)"),
    ((0.03 + 1j, 0.03, 0.06), "((0.03+1j), 0.03, 0.06) (dtype complex128)"), ((0.03, 0.03), "(0.03, 0.03)"),
    ((0.03, float("nan"), 0.06), "(0.03, nan, 0.06)"), ((0.03, -0.03, 0.06), "(0.03, -0.03, 0.06) (not positive "
                                                                              "definite)")])
def test_inertia_must_be_real_positive_definite(name, inertia, tail):
    with pytest.raises(ValueError) as info:
        _make(name, inertia=inertia)
    assert _one_line(info.value) == (f"{name}: inertia must be a 3x3 matrix or 3 diagonal entries of finite real "
                                     f"numbers [kg m^2], positive definite, got {tail}")


def test_numpy_and_int_numbers_are_accepted():
    obs = _make("leso", mass=np.float32(1.5), inertia=[1, 1, 2], gravity=np.int64(10), omega_t=np.float64(8.0),
                omega_a=12)
    assert (obs.mass, obs.gravity, obs.max_dt) == (1.5, 10.0, 1.0 / 36.0)
    assert obs.inertia.dtype == np.float64 and obs.beta_t == (24.0, 192.0, 512.0)


# gain, bad value, the exact message: the audit's cases (D5) and one of each kind per observer
GAIN_CASES = [
    ("fxtsdo", {"a2": 1e300}, "fxtsdo: exponent a2 must be a finite real number in (1, 3.5], got 1e+300 (float)"),
    ("fxtsdo", {"a1": 1.0}, "fxtsdo: exponent a1 must be a finite real number in (0, 1), got 1.0 (float)"),
    ("fxtsdo", {"k1": "a"}, "fxtsdo: gain k1 must be a finite real number in (0, 1e+06], got 'a' (str)"),
    ("leso", {"omega_t": 1e300}, "leso: gain omega_t must be a finite real number in (0, 1e+06], got 1e+300 (float)"),
    ("leso", {"omega_a": True}, "leso: gain omega_a must be a finite real number in (0, 1e+06], got True (bool)"),
    ("geso", {"bandwidth": 1e300}, "GESO bandwidth must be a finite real number in (0, 1e+06] rad/s, got 1e+300 "
                                   "(float)"),
    ("geso", {"bandwidth": "20"}, "GESO bandwidth must be a finite real number in (0, 1e+06] rad/s, got '20' (str)"),
    ("ffts_eso", {"kt1": float("nan")}, "ffts_eso: gain kt1 must be a finite real number in (0, 1e+06] (A_t = "
                                        "[[-kt1, 1], [-kt2, 0]] of eq. 48 is Hurwitz iff kt1, kt2 > 0), got nan "
                                        "(float)"),
    ("ffts_eso", {"kt1": True}, "ffts_eso: gain kt1 must be a finite real number in (0, 1e+06] (A_t = [[-kt1, 1], "
                                "[-kt2, 0]] of eq. 48 is Hurwitz iff kt1, kt2 > 0), got True (bool)"),
    ("ffts_eso", {"ka2": 1e300}, "ffts_eso: gain ka2 must be a finite real number in (0, 1e+06] (A_a = [[-ka1, 1], "
                                 "[-ka2, 0]] of eq. 67 is Hurwitz iff ka1, ka2 > 0), got 1e+300 (float)"),
    ("ffts_eso", {"kappa_t": "a"}, "ffts_eso: gain kappa_t must be a finite real number in (0.5, 1e+06] (kappa > "
                                   "1/2, Wang et al. (2024) eq. 50), got 'a' (str)"),
    ("ffts_eso", {"p": None}, "p must be a finite real number in (1, 2) (the open interval of Wang et al. (2024) "
                              "Theorem 1), got None (NoneType)"),
    ("ffts_eso", {"eps": 1j}, "ffts_eso: eps must be a finite real number in (0, 1] (the floor of e^T e, eq. 50), "
                              "got 1j (complex)"),
    ("ffts_eso", {"morse_k": ("a", 1, 1)}, "ffts_eso: Morse gains morse_k = (K1, K2, K3) must be 3 finite real "
                                           "numbers with 1e+06 >= K1 > K2 > K3 >= 1 (Lemma 5, eq. 41), got ('a', 1, "
                                           "1)"),
    ("sto", {"bound_t": 1e300}, "sto: gain bound_t must be a finite real number in (0, 1e+06], got 1e+300 (float)"),
    ("hc_eso", {"kappa": 1e300}, "hc_eso: gain kappa must be a finite real number in (0, 1e+06], got 1e+300 (float)"),
    ("hc_eso", {"max_step": "a"}, "hc_eso: max_step must be a finite real number >= 0.001 s (>= max_dt / 100), "
                                  "got 'a' (str)"),
    ("pdt_sta", {"noise_bound": float("nan")}, "pdt_sta: noise_bound must be a finite real number >= 0 (ell of "
                                               "eq. 42), got nan (float)"),
    ("pdt_sta", {"noise_bound": -1.0}, "pdt_sta: noise_bound must be a finite real number >= 0 (ell of eq. 42), got "
                                       "-1.0 (float)"),
    ("pdt_sta", {"kappa1": None}, "pdt_sta: gain kappa1 must be a finite real number > 0 (kappa1 > 0, eqs. 16-22), "
                                  "got None (NoneType)"),
    ("pdt_sta", {"t_c": True}, "t_c must be a finite real number, got True (bool)"),
    ("pdt_sta", {"weights": (True, True)}, "pdt_sta: weights must be two finite real numbers > 0 (accelerometer, "
                                           "magnetometer), got (True, True)"),
    ("pdt_sta", {"magnetic_field": "abc"}, "pdt_sta: magnetic_field must be 3 finite real numbers (NED) not "
                                           "parallel to gravity, got 'abc'"),
    ("hc_eso", {"field_ned": (1j, 0, 0)}, "hc_eso: field_ned must be 3 finite real numbers (the Earth field, NED), "
                                          "got (1j, 0, 0)"),
    ("hc_eso", {"morse_gains": "abc"}, "K = diag(k1, k2, k3) needs real numbers k1 > k2 > k3 >= 1 (Lemma 1), got "
                                       "'abc'"),
    ("qb", {"gain_file": 5}, "gain_file must be None (the shipped gain for the vehicle), a path or a shipped gain's "
                             "name, got 5 (int)"),
    ("pdt_sta", {"reanchor": "a"}, "pdt_sta: reanchor must be a finite real number in (0, 10] (a Gibbs-vector "
                                   "norm), got 'a' (str)"),
]


@pytest.mark.parametrize("name,kwargs,message", GAIN_CASES, ids=[f"{c[0]}-{next(iter(c[1]))}" for c in GAIN_CASES])
def test_gain_errors_name_the_gain_and_the_allowed_range(name, kwargs, message):
    with pytest.raises(ValueError) as info:
        _make(name, **kwargs)
    assert _one_line(info.value) == message


@pytest.mark.parametrize("name,kwargs", [("fxtsdo", {"a2": 3.5, "k2": 1e6}), ("leso", {"omega_t": 1e6}),
                                         ("geso", {"bandwidth": 1e6}), ("ffts_eso", {"kt1": 1e6, "kt3": 1e6}),
                                         ("sto", {"bound_a": 1e6})])
def test_the_largest_accepted_gains_give_a_finite_positive_max_dt(name, kwargs):
    """At the stated bounds nothing overflows: max_dt stays a finite positive step."""
    with np.errstate(all="raise"):
        obs = _make(name, **kwargs)
    assert 0.0 < obs.max_dt <= 0.05 and np.isfinite(obs.max_dt)


def test_the_shared_helper():
    assert check_positive(np.float32(2.5), "x") == 2.5 and check_number(-3, "x") == -3.0
    assert check_number(0, "x", minimum=0.0, inclusive_minimum=True) == 0.0
    with pytest.raises(ValueError, match=re.escape("x must be a finite real number < 2, got 2 (int)")):
        check_number(2, "x", maximum=2.0, inclusive_maximum=False)
    with pytest.raises(ValueError, match=re.escape("x must be a finite real number > 0, got an int of about 401 digits "
                                                   "(int)")):
        check_positive(10**400, "x")
    # an int beyond Python's 4300-digit str limit, a long str: shown by their length, not a second error
    with pytest.raises(ValueError, match=re.escape("x must be a finite real number > 0, got an int of about 5001 "
                                                   "digits (int)")):
        check_positive(10**5000, "x")
    with pytest.raises(ValueError, match=re.escape(f"x must be a finite real number > 0, got '{'a' * 199}... (502 "
                                                   "characters) (str)")):
        check_positive("a" * 500, "x")
