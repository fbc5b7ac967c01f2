"""FAWT presets against seed-000 Table 3, geometry, schedule, registry and bad input (envs/wind/fawt.py)."""

import math

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.frames import FAWT_HOVER_POINT_NED, fawt_to_ned
from fawtgym.envs.wind import FawtWind, make_wind, wind_names
from fawtgym.envs.wind.fawt import FAN_PITCH, TABLE3, fawt_statistics, length_scale_from_table3

#: seed-000 Table 3 (ffts_eso_tse3_fawt_wang2024.txt), typed independently of the module
PAPER = {30: (5.472, 0.061, 0.0451), 40: (6.876, 0.082, 0.0417), 50: (8.213, 0.116, 0.0415),
         60: (9.590, 0.168, 0.0427), 70: (10.920, 0.237, 0.0446)}
HOTWIRE = fawt_to_ned(np.array([1.2, 0.0, 0.0]))


def _run(wind, n, steps, dt, point, velocity=None, t0=0.0):
    pts = np.broadcast_to(np.asarray(point, dtype=float), (n, 1, 3)).copy()
    vel = np.zeros((n, 3)) if velocity is None else velocity
    return np.stack([wind.step(t0 + (k + 1) * dt, dt, pts, vel)[:, 0, :].copy() for k in range(steps)])


@pytest.mark.parametrize("duty", sorted(PAPER))
def test_preset_reproduces_table3(duty):
    """Hot-wire point, fixed seed, 64 fields x 2000 steps of 10 ms: mean within 2 %, variance within 5 %."""
    u, var, ti = PAPER[duty]
    wind = make_wind(f"fawt-{duty}")
    wind.reset(64, seed=duty)
    w = _run(wind, 64, 2000, 0.01, HOTWIRE)[..., 0]  # stream-wise = NED north
    assert w.mean() == pytest.approx(u, rel=0.02)
    assert w.var() == pytest.approx(var, rel=0.05)
    assert math.sqrt(w.var()) / w.mean() == pytest.approx(ti, rel=0.05)


def test_table3_ti_column_is_consistent():
    """TI = sqrt(var) / U recomputed from the table's own columns (rounding of the paper: 1 %)."""
    for u, var, ti in PAPER.values():
        assert math.sqrt(var) / u == pytest.approx(ti, rel=0.01)
    for duty, (u, var, _) in PAPER.items():
        s = fawt_statistics(duty / 100)
        assert (s["mean"], s["variance"]) == (pytest.approx(u), pytest.approx(var))


def test_hover_point_sees_nearly_the_hotwire_statistics():
    wind = FawtWind(0.5)
    wind.reset(1, seed=0)
    m_h = wind.mean_wind_at(FAWT_HOVER_POINT_NED)[0]
    assert m_h == pytest.approx(PAPER[50][0], rel=0.01)
    assert m_h < wind.mean_wind_at(HOTWIRE)[0]  # slow decay downstream


def test_length_scale_default_is_inside_the_geometric_bracket():
    """Re_lambda estimate L = C_eps Re^2 nu / (15 u') lies in 0.1-0.5 fan pitches (grid turbulence at x/M = 15)."""
    for duty, (_, var, re_l, _) in TABLE3.items():
        length = length_scale_from_table3(duty)
        lam = re_l * 1.5e-5 / math.sqrt(var)  # Taylor microscale
        # two implementations of one formula (tests/_tolerance.py)
        assert_same_law(length, 0.5 * re_l * lam / 15.0, what=f"duty {duty}")
        assert 0.1 * FAN_PITCH <= length <= 0.5 * FAN_PITCH


def test_interpolation_and_policy_outside_the_table():
    s45 = fawt_statistics(0.45)
    assert s45["mean"] == pytest.approx(0.5 * (PAPER[40][0] + PAPER[50][0]))
    assert s45["variance"] == pytest.approx(0.5 * (PAPER[40][1] + PAPER[50][1]))
    assert fawt_statistics(0.0)["mean"] == 0.0
    assert fawt_statistics(0.15)["mean"] == pytest.approx(PAPER[30][0] / 2)
    assert fawt_statistics(1.0)["mean"] == pytest.approx(12.0)
    assert fawt_statistics(0.85)["ti"] == pytest.approx(math.sqrt(PAPER[70][1]) / PAPER[70][0])
    means = [fawt_statistics(d)["mean"] for d in np.linspace(0, 1, 41)]
    assert np.all(np.diff(means) > 0)


@pytest.mark.parametrize("duty", [-0.1, 1.2, float("nan"), 50])
def test_bad_duty_raises_naming_the_value(duty):
    with pytest.raises(ValueError, match=f"duty.*{duty!r}"):
        FawtWind(duty)


def test_bad_length_scale_and_position():
    with pytest.raises(ValueError, match="length_scale.*-0.01"):
        make_wind({"name": "fawt-50", "length_scale": -0.01})
    wind = make_wind("fawt-50")
    wind.reset(1, seed=0)
    pts = np.zeros((1, 5, 3))
    pts[0, 2, 1] = np.nan
    with pytest.raises(ValueError, match="nan"):
        wind.step(0.01, 0.01, pts, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="inf"):
        wind.step(0.01, 0.01, np.zeros((1, 5, 3)), np.array([[0.0, np.inf, 0.0]]))
    with pytest.raises(ValueError, match=r"\(1, K, 3\)"):
        wind.step(0.01, 0.01, np.zeros((2, 5, 3)), np.zeros((2, 3)))


def test_geometry_core_shear_layer_and_outside():
    wind = FawtWind(0.6)
    wind.reset(256, seed=1)
    core = fawt_to_ned(np.array([1.5, 0.0, 0.0]))
    edge = fawt_to_ned(np.array([1.5, 0.72, 0.0]))  # side edge of the jet (y = half span)
    outside = fawt_to_ned(np.array([1.5, 1.2, 0.0]))
    below = fawt_to_ned(np.array([1.5, 0.0, -0.7]))
    m = wind.mean_wind_at(np.stack([core, edge, outside, below]))[:, 0]
    assert m[1] == pytest.approx(0.5 * m[0], rel=0.02)  # mixing-layer centre: half the core speed
    assert m[2] < 0.05 * m[0] and m[3] < 0.05 * m[0]
    pts = np.broadcast_to(np.stack([core, edge, outside]), (256, 3, 3)).copy()
    w = np.stack([wind.step(2 + (k + 1) * 0.01, 0.01, pts, np.zeros((256, 3)))[..., 0].copy() for k in range(200)])
    std = w.std(axis=(0, 1))
    assert std[1] > 3.0 * std[0]  # turbulence rises in the shear layer
    assert std[2] < 0.2 * std[0]
    # the shear layer grows with x: mean at y = 0.6 m falls further downstream
    near, far = wind.mean_wind_at(fawt_to_ned(np.array([[0.5, 0.6, 0.0], [3.0, 0.6, 0.0]])))[:, 0]
    assert far < near


def test_no_wind_behind_the_array():
    wind = FawtWind(0.5)
    wind.reset(1, seed=0)
    assert wind.mean_wind_at(fawt_to_ned(np.array([-0.3, 0.0, 0.0])))[0] == 0.0


def test_steady_at_t0_and_schedule_spin_up_95_percent():
    steady = FawtWind(0.5)
    steady.reset(1, seed=0)
    first = _run(steady, 1, 1, 0.01, FAWT_HOVER_POINT_NED)
    assert first[0, 0, 0] > 7.0
    tau = 0.8
    wind = FawtWind(0.5, on_time=1.0, off_time=20.0, spin_tau=tau, turbulence=False)
    wind.reset(1, seed=0)
    dt = 0.002
    w = _run(wind, 1, 2000, dt, FAWT_HOVER_POINT_NED)[:, 0, 0]
    t = dt * (np.arange(2000) + 1)
    full = wind.mean_speed * wind.mean_wind_at(FAWT_HOVER_POINT_NED)[0] / wind.mean_speed / wind.level
    assert np.all(w[t < 1.0] == 0.0)
    t95 = t[np.argmax(w >= 0.95 * full)]
    assert t95 - 1.0 == pytest.approx(wind.schedule.time_to_fraction(0.95), abs=2 * dt)
    assert wind.schedule.time_to_fraction(0.95) == pytest.approx(-tau * math.log(0.05))
    # fan-off transient: spins down after off_time
    w2 = _run(wind, 1, 300, 0.01, FAWT_HOVER_POINT_NED, t0=19.0)[:, 0, 0]
    assert w2[90] > 0.99 * full and w2[-1] < 0.1 * full


def test_schedule_is_step_independent():
    a = FawtWind(0.5, on_time=0.5, spin_tau=0.7, turbulence=False)
    b = FawtWind(0.5, on_time=0.5, spin_tau=0.7, turbulence=False)
    a.reset(1)
    b.reset(1)
    wa = _run(a, 1, 200, 0.01, FAWT_HOVER_POINT_NED)[-1, 0, 0]
    wb = _run(b, 1, 8, 0.25, FAWT_HOVER_POINT_NED)[-1, 0, 0]
    # the closed-form schedule reached through 200 and through 8 steps: only the time sums round differently
    # (tests/_tolerance.py)
    assert_same_law(wa, wb, steps=200, what="wind at t = 2 s")


def test_frozen_turbulence_speed_follows_relative_air_velocity():
    """Moving with the mean flow lowers V = |U - v| to the floor: the gusts decorrelate much more slowly."""
    wind = FawtWind(0.5, length_scale=0.5)
    wind.reset(16, seed=4)
    vel = np.zeros((16, 3))
    vel[8:, 0] = 8.2
    w = _run(wind, 16, 1500, 0.01, FAWT_HOVER_POINT_NED, velocity=vel)[..., 0]
    w = w - w.mean(axis=0)
    rho = [float((w[:-1, s] * w[1:, s]).sum() / (w[:, s] ** 2).sum()) for s in (slice(0, 8), slice(8, 16))]
    assert rho[0] == pytest.approx(math.exp(-8.16 * 0.01 / 0.5), abs=0.02)
    assert rho[1] > 0.95


def test_registry_names_and_options():
    names = set(wind_names())
    assert {"calm", "fawt", "fawt-30", "fawt-40", "fawt-50", "fawt-60", "fawt-70", "dryden-light",
            "dryden-moderate", "dryden-severe", "gust-1cos"} <= names
    w = make_wind({"name": "fawt", "duty": 0.45, "form": "1797", "spin_tau": 2.0})
    assert isinstance(w, FawtWind) and w.duty == 0.45 and w.form == "1797"
    with pytest.raises(ValueError, match="duty is fixed"):
        make_wind({"name": "fawt-50", "duty": 0.3})
    with pytest.raises(ValueError, match="bogus.*valid options"):
        make_wind({"name": "dryden-light", "bogus": 1})
    with pytest.raises(ValueError, match="form"):
        make_wind({"name": "fawt-50", "form": "x"})


def test_rates_give_differential_gusts_across_the_vehicle():
    wind = FawtWind(0.5, rates=True, length_scale=2.0)
    wind.reset(1, seed=3)
    pts = (FAWT_HOVER_POINT_NED + np.array([[0, 0, 0], [0.17, 0.17, 0], [-0.17, -0.17, 0],
                                            [0.17, -0.17, 0], [-0.17, 0.17, 0]]))[None]
    w = np.stack([wind.step((k + 1) * 0.01, 0.01, pts, np.zeros((1, 3)))[0].copy() for k in range(200)])
    assert np.std(w[:, 1, 2] - w[:, 2, 2]) > 1e-3  # vertical gust differs between diagonal rotors
    np.testing.assert_allclose(w[:, 1, 0] - w[:, 0, 0], w[:, 1, 0] - w[:, 0, 0])


@pytest.mark.parametrize("options", [{}, {"on_time": 0.05, "spin_tau": 0.1}, {"turbulence": False},
                                     {"rates": True, "length_scale": 0.3}])
def test_a_row_equals_that_vehicle_alone(options):
    """Row i of an N = 3 run is bit for bit the wind of that vehicle run alone with the same field seed (one kernel
    over rows; each row's gust step uses its own state, noise and step-matrix bin)."""
    seeds = np.random.SeedSequence(8).spawn(3)
    batch = FawtWind(0.6, **options)
    batch.reset(3, seed=seeds)
    alone = [FawtWind(0.6, **options) for _ in range(3)]
    for i, w in enumerate(alone):
        w.reset(1, seed=[seeds[i]])
    rng = np.random.default_rng(0)
    for k in range(300):
        pts = fawt_to_ned(rng.uniform([-0.2, -1.0, -0.6], [3.0, 1.0, 0.6], (3, 5, 3)))
        vel = rng.normal(0, 1, (3, 3))
        wb = batch.step((k + 1) * 0.01, 0.01, pts, vel)
        for i, w in enumerate(alone):
            np.testing.assert_array_equal(w.step((k + 1) * 0.01, 0.01, pts[i:i + 1], vel[i:i + 1])[0], wb[i],
                                          err_msg=f"step {k} row {i}")


def _step_errors(name, n):
    """(type, message) of each bad step input for wind ``name`` with ``n`` rows (N-dependent shapes masked)."""
    wind = make_wind(name)
    pts, vel = np.tile(FAWT_HOVER_POINT_NED, (n, 5, 1)), np.zeros((n, 3))
    bad_pts, bad_vel = pts.copy(), vel.copy()
    bad_pts[-1, 2, 1] = np.nan
    bad_vel[-1, 0] = -np.inf
    cases = [(0.01, 0.0, pts, vel), (0.01, -1.0, pts, vel), (0.01, 2.0, pts, vel), (0.01, "0.01", pts, vel),
             (0.01, None, pts, vel), (0.01, True, pts, vel), (float("nan"), 0.01, pts, vel),
             (0.01, 0.01, bad_pts, vel), (0.01, 0.01, pts, bad_vel), (0.01, 0.01, pts[:, :, :2], vel),
             (0.01, 0.01, pts, vel[:, :2]), (0.01, 0.01, pts + 0j, vel), (0.01, 0.01, pts.astype(str), vel)]
    out = []
    with pytest.raises(RuntimeError, match="reset") as err:
        wind.step(0.01, 0.01, pts, vel)
    out.append((err.type, str(err.value)))
    wind.reset(n, seed=1)
    for t, dt, p, v in cases:
        with pytest.raises(ValueError) as err:
            wind.step(t, dt, p, v)
        assert "\n" not in str(err.value)
        out.append((err.type, str(err.value).replace(f"({n}, ", "(N, ")))
    return out


@pytest.mark.parametrize("name", wind_names())
def test_bad_step_input_gives_the_same_error_at_every_n(name):
    one, three = _step_errors(name, 1), _step_errors(name, 3)
    assert one == three
    text = " ".join(m for _, m in one)
    for word in ("dt must be a finite real number in (0, 1] s (a wind step), got 2.0 (float)", "'0.01'", "None",
                 "t must be a finite real number (the time in s)",
                 "points_ned must be finite", "vehicle_velocity_ned must be finite", "points_ned must have shape",
                 "vehicle_velocity_ned must have shape", "real numbers"):
        assert word in text, word


def test_a_failed_step_changes_nothing():
    """A step refused for a non-finite point leaves the fan level and the gust stream as they were."""
    a, b = FawtWind(0.5, on_time=0.0, spin_tau=0.2), FawtWind(0.5, on_time=0.0, spin_tau=0.2)
    a.reset(2, seed=3)
    b.reset(2, seed=3)
    pts, vel = np.tile(FAWT_HOVER_POINT_NED, (2, 5, 1)), np.zeros((2, 3))
    bad = pts.copy()
    bad[1, 0, 0] = np.nan
    for k in range(5):
        with pytest.raises(ValueError, match="finite"):
            a.step((k + 1) * 0.01, 0.01, bad, vel)
        np.testing.assert_array_equal(a.step((k + 1) * 0.01, 0.01, pts, vel), b.step((k + 1) * 0.01, 0.01, pts, vel))


def test_fawt_variance_independent_of_time_step():
    """fawt-50 at the hot wire (L / U ~ 1.8 ms): dt = 1 ms and 10 ms give the same variance within 5 %."""
    out = []
    for dt in (0.001, 0.01):
        wind = make_wind("fawt-50")
        wind.reset(64, seed=21)
        out.append(_run(wind, 64, 2000, dt, HOTWIRE)[..., 0].var())
    assert out[0] / out[1] == pytest.approx(1.0, abs=0.05)
    assert out[0] == pytest.approx(PAPER[50][1], rel=0.05)


_NUMERIC_OPTIONS = {"fawt": ["duty", "on_time", "off_time", "spin_tau", "spin_down_tau", "length_scale", "span"],
                    "dryden-light": ["altitude", "direction_deg", "length_scale", "span", "mean_wind"],
                    "gust-1cos": ["amplitude", "length", "speed", "start_time", "direction_deg"]}


_BAD_NUMBERS = ["a", True, float("nan"), float("inf"), [1.0, 2.0], {}]
# an amplitude may be a vector (a 2-vector is refused in test_numpy_scalars_are_numbers); mean_wind=True is the
# log-profile wind
_VALID_HERE = {("amplitude", 4), ("mean_wind", 1)}


@pytest.mark.parametrize("name, option, bad", [(n, o, b) for n, opts in _NUMERIC_OPTIONS.items() for o in opts
                                               for k, b in enumerate(_BAD_NUMBERS) if (o, k) not in _VALID_HERE])
def test_numeric_wind_options_refuse_non_numbers_in_one_line(name, option, bad):
    """A numeric option given a string, a boolean, NaN/inf, a list or a dict: one ValueError naming the option (a
    boolean is not a number here: True would silently be 1)."""
    with pytest.raises(ValueError, match=option) as err:
        make_wind({"name": name, option: bad})
    assert "\n" not in str(err.value)


def test_numpy_scalars_are_numbers():
    w = make_wind({"name": "fawt", "duty": np.float32(0.5), "length_scale": np.float64(0.02), "spin_tau": np.int64(2)})
    assert w.duty == pytest.approx(0.5) and w.length_scale == 0.02
    with pytest.raises(ValueError, match="amplitude"):
        make_wind({"name": "gust-1cos", "amplitude": [1.0, 2.0]})
    with pytest.raises(ValueError, match="spin_tau"):
        make_wind({"name": "fawt", "spin_tau": None})
