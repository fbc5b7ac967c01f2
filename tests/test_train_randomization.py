"""Domain randomization: seeded per-row draws at every episode start, inside the stated ranges, applied to the
simulated vehicle only (mass, inertia, drag, IMU biases, FAWT duty), the unrandomized streams unchanged."""

import numpy as np
import pytest

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.vehicles import GRAVITY
from fawtgym.envs.wind.fawt import FawtWind
from fawtgym.train.envs import make_vector_env
from fawtgym.train.randomization import Randomization

ALL = {"duty": [0.3, 0.7], "mass": 0.1, "inertia": 0.2, "drag": 0.3, "gyro_bias": 0.01, "accel_bias": 0.2}


def _draws(env):
    base = env.unwrapped
    return {"mass": base.mass_scale.copy(), "inertia": base.inertia_scale.copy(), "drag": base.drag_scale.copy(),
            "gyro": base.sensor.gyro_bias.copy(), "accel": base.sensor.accel_bias.copy(),
            "duty": np.array([base.randomizer.last[i]["duty"] for i in range(base.num_envs)])}


def _run(seed, steps=60, n=6):
    """Draws after reset(seed) and after every restart of a run with short episodes (all rows restart together,
    plus row 2 pushed out early)."""
    env = make_vector_env("table4-50", n, "motors", randomize=ALL, episode_seconds=0.05)
    env.reset(seed=seed)
    out = [_draws(env)]
    push = np.zeros((n, 3))
    push[2, 0] = 2000.0
    env.unwrapped.set_external_wrench(push)
    for _ in range(steps):
        *_, term, trunc, info = env.step(np.zeros((n, 4)))
        env.unwrapped.set_external_wrench()
        if (term | trunc).any():
            out.append(_draws(env))
    return out


def test_draws_are_seeded_redrawn_per_episode_and_in_range():
    a, b, c = _run(3), _run(3), _run(4)
    assert len(a) >= 6
    for x, y in zip(a, b, strict=True):
        for key in x:
            np.testing.assert_array_equal(x[key], y[key])  # same seed, same draws
    assert not np.array_equal(a[0]["mass"], c[0]["mass"])  # another seed, other draws
    assert not np.array_equal(a[1]["mass"], a[-1]["mass"])  # redrawn at every episode start
    every = {k: np.concatenate([d[k].ravel() for d in a]) for k in a[0]}
    assert np.all((0.9 <= every["mass"]) & (every["mass"] <= 1.1))
    assert np.all((0.8 <= every["inertia"]) & (every["inertia"] <= 1.2))
    assert np.all((0.7 <= every["drag"]) & (every["drag"] <= 1.3))
    assert np.all(np.abs(every["gyro"]) <= 0.01) and np.all(np.abs(every["accel"]) <= 0.2)
    assert np.all((0.3 <= every["duty"]) & (every["duty"] <= 0.7))
    assert np.ptp(every["mass"]) > 0.1 and np.ptp(every["duty"]) > 0.2  # spread over the ranges


def test_duty_rows_fly_their_own_fawt_wind_with_the_scenario_schedule():
    env = make_vector_env("table4-50", 3, "motors", randomize={"duty": [0.3, 0.7]}, episode_seconds=0.05)
    env.reset(seed=0)
    base = env.unwrapped
    models = {int(rows[0]): m for m, rows, alive in base.wind.cohorts}
    assert sorted(models) == [0, 1, 2]  # one wind model per row
    for row, model in models.items():
        assert isinstance(model, FawtWind) and model.duty == pytest.approx(base.randomizer.last[row]["duty"])
        assert (model.schedule.on_time, model.schedule.off_time) == (5.0, 50.0)  # table4's fan schedule kept


def test_vehicle_draws_act_on_the_simulated_vehicle_only():
    """Mass: at the nominal hover command a heavier row sinks with g (1 - 1/s); drag: the aero wrench scales by the
    draw; the initial states are the unrandomized env's (the draws use their own stream); the hover action stays
    nominal."""
    kw = dict(wind={"name": "fawt-50"}, sensors="mocap_imu", control_rate=200.0, init_noise=1.0)
    sampler = Randomization(mass=0.3, drag=0.5).sampler()
    rnd = HoverBatchEnv(4, **kw, randomizer=sampler)
    ref = HoverBatchEnv(4, **kw)
    _, ir = rnd.reset(seed=11)
    _, i0 = ref.reset(seed=11)
    np.testing.assert_array_equal(ir["truth"]["position"], i0["truth"]["position"])
    np.testing.assert_array_equal(ir["truth"]["wind"], i0["truth"]["wind"])
    np.testing.assert_allclose(ir["truth"]["force"], i0["truth"]["force"] * rnd.drag_scale[:, None], rtol=1e-12)
    np.testing.assert_array_equal(rnd.hover_action(), ref.hover_action())
    # mass: no wind, no initial motion, hover command -> vertical acceleration g (1 - 1/s) (NED down positive)
    still = HoverBatchEnv(4, init_noise=0.0, randomizer=Randomization(mass=0.3).sampler())
    still.reset(seed=2)
    _, _, _, _, info = still.step(still.hover_action())
    a_down = info["truth"]["velocity"][:, 2] / still.dt
    s = still.mass_scale
    np.testing.assert_allclose(a_down, GRAVITY * (1.0 - 1.0 / s), rtol=0.05, atol=1e-3)
    assert np.ptp(s) > 0.05
    # inertia: a constant external torque from rest spins each row up at tau / (s J) (no other torque acts at a
    # level hover start: balanced rotors, no wind, no rate); a nominal env alongside keeps J (its model untouched)
    tau = np.array([0.002, -0.003, 0.01])
    rates = {}
    for label, randomizer in (("randomized", Randomization(inertia=0.4).sampler()), ("nominal", None)):
        spin = HoverBatchEnv(3, init_noise=0.0, randomizer=randomizer)
        spin.reset(seed=0)
        spin.set_external_wrench(np.zeros(3), tau)
        rates[label] = spin.step(spin.hover_action())[4]["truth"]["angular_velocity"] / (tau * spin.dt)
        scale = spin.inertia_scale if randomizer is not None else np.ones(3)
        j = np.diag(spin.preset.inertia_matrix)
        # 1e-4: the rotors' small speed-dependent reaction torques over the first step (measured 1.2e-5)
        np.testing.assert_allclose(rates[label], 1.0 / (scale[:, None] * j[None, :]), rtol=1e-4, err_msg=label)
    assert np.ptp(1.0 / (rates["randomized"][:, 2] * j[2])) > 0.05  # the rows got different inertias


def test_bad_randomization_options():
    cases = [({"wind_speed": 1}, "unknown randomize key(s) ['wind_speed']; valid: duty, mass, inertia, drag"),
             ({"duty": [30, 70]}, "fractions, e.g. [0.3, 0.7]"), ({"duty": 0.5}, "must be [lo, hi]"),
             ({"mass": 1.5}, "randomize 'mass' is a fraction f in [0, 0.9]"),
             ({"accel_bias": -0.1}, "half-range b >= 0"), ({"drag": "lots"}, "must be a finite real number")]
    for options, text in cases:
        with pytest.raises(ValueError) as err:
            Randomization.from_options(options)
        assert text in str(err.value) and "\n" not in str(err.value)
    assert Randomization.from_options({}) is None and Randomization.from_options({"mass": 0.0}) is None
    with pytest.raises(ValueError, match="needs a FAWT wind .* the scenario's wind is 'dryden-light'"):
        make_vector_env("dryden-light", 2, randomize={"duty": [0.3, 0.7]})
    env = HoverBatchEnv(2, sensors="none", randomizer=Randomization(gyro_bias=0.01).sampler())
    with pytest.raises(ValueError, match="sensors are exact"):
        env.reset(seed=0)
    env = HoverBatchEnv(2, randomizer=lambda rows, rngs: {"mass_scale": -np.ones(len(rows))})
    with pytest.raises(ValueError, match=r"randomizer draw 'mass_scale' must be > 0 with shape \(2,\)"):
        env.reset(seed=0)
    env = HoverBatchEnv(2, randomizer=lambda rows, rngs: {"gravity": 1.0})
    with pytest.raises(ValueError, match=r"randomizer draws \['gravity'\] are unknown; valid: \['mass_scale'"):
        env.reset(seed=0)
