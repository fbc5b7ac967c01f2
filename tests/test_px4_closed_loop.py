"""PX4Agent / PX4ObserverAgent in the hover env: calm hover, 1 m step, feedforward, short FAWT study."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import fawtgym  # noqa: F401  (registers the env)
from fawtgym.agents.px4_agent import PX4Agent, PX4ObserverAgent
from fawtgym.observers.base import Observer, ObserverEstimate

RATE = 200.0


def _env(**kw):
    kw.setdefault("vehicle", "s500")
    kw.setdefault("control_rate", RATE)
    return gym.make("fawtgym/Hover-v0", **kw)


def _fly(env, agent, seconds: float, seed: int = 0, on_reset=None):
    obs, info = env.reset(seed=seed)
    agent.reset(info)
    if on_reset is not None:
        on_reset(env, agent)
    sp = env.unwrapped.setpoint
    errors = []
    for _ in range(int(round(seconds * RATE))):
        obs, _, term, trunc, info = env.step(agent.act(obs, info))
        errors.append(info["truth"]["position"] - sp)
        assert not term, info["failure"]
    return np.array(errors)


def test_calm_hover_holds_within_1cm() -> None:
    env = _env(episode_seconds=10.0, init_noise=1.0)
    agent = PX4Agent.for_env(env)
    err = _fly(env, agent, 9.0, seed=3)
    assert np.linalg.norm(err[0]) > 0.01  # it really started perturbed
    assert np.abs(np.linalg.norm(err[int(6 * RATE):], axis=1)).max() < 0.01


def test_one_metre_step_overshoot_below_20_percent() -> None:
    env = _env(episode_seconds=12.0, init_noise=0.0)
    agent = PX4Agent.for_env(env)

    def step_setpoint(env, agent):
        agent.set_setpoint(env.unwrapped.setpoint + np.array([1.0, 0.0, 0.0]))

    err = _fly(env, agent, 11.0, on_reset=step_setpoint)
    x = err[:, 0]  # position relative to the old set point; target +1 m
    overshoot = x.max() - 1.0
    assert 0.0 <= overshoot < 0.20
    assert abs(x[-1] - 1.0) < 0.03  # settled
    t_rise = np.argmax(x > 0.9) / RATE
    assert 1.0 < t_rise < 4.0  # PX4-like: MPC_XY_P 0.95 gives ~1 m/s, a 1-3 s rise
    assert np.abs(err[:, 1:]).max() < 0.02  # no cross-coupling to y/z


class KnownWrench(Observer):
    """A 'perfect' observer of a constant disturbance that is known in advance (test helper)."""

    name = "known"

    def __init__(self, mass, inertia, force, torque):
        super().__init__(mass, inertia)
        self.force = np.asarray(force, dtype=float)
        self.torque_ = np.asarray(torque, dtype=float)

    def reset(self, measurement, force=None, torque=None):
        pass

    def update(self, measurement, thrust, torque, dt):
        n = np.atleast_1d(np.asarray(thrust)).shape[0]
        return ObserverEstimate(np.tile(self.force, (n, 1)), np.tile(self.torque_, (n, 1)))


def test_feedforward_of_a_perfect_estimate_beats_integral_action() -> None:
    force, torque = np.array([1.5, -1.0, 0.5]), np.array([0.03, -0.02, 0.01])

    def disturb(env, agent):
        env.unwrapped.set_external_wrench(force, torque)

    env = _env(episode_seconds=8.0, init_noise=0.0)
    base = _fly(env, PX4Agent.for_env(env), 6.0, on_reset=disturb)
    p = env.unwrapped.preset
    ff_agent = PX4ObserverAgent.for_env(env, observer=KnownWrench(p.mass, p.inertia_matrix, force, torque))
    ff = _fly(env, ff_agent, 6.0, on_reset=disturb)
    nb, nf = np.linalg.norm(base, axis=1), np.linalg.norm(ff, axis=1)
    # integral action alone: a large excursion that decays slowly (0.78 m peak, 0.33 m left after 6 s)
    assert nb.max() > 0.3 and nb[-1] > 0.2
    # perfect feedforward: only the attitude-response transient remains (the tilt takes ~0.3 s), and
    # the error has vanished where integral action alone still has most of it
    assert nf.max() < 0.2 * nb.max()
    assert nf.mean() < 0.1 * nb.mean()
    assert nf[-1] < 0.02 and nf[-1] < 0.1 * nb[-1]


def test_agent_batch_first_and_errors() -> None:
    env = _env(episode_seconds=2.0, init_noise=0.5)
    _, info = env.reset(seed=1)
    single, batched = PX4Agent.for_env(env), PX4Agent.for_env(env)
    single.reset(info)
    binfo = {part: {k: np.stack([np.asarray(v)] * 3) for k, v in info[part].items()}
             for part in ("measurement", "applied")}
    batched.reset(binfo)
    a1, a3 = single.act(None, info), batched.act(None, binfo)
    assert a1.shape == (4,) and a3.shape == (3, 4)
    # N = 1 and a batch of 3 equal rows: one row kernel on the same inputs, bit for bit (tests/_tolerance.py)
    np.testing.assert_array_equal(a3, np.tile(a1, (3, 1)))
    assert np.all((a1 >= 0) & (a1 <= 1))
    with pytest.raises(ValueError, match="reset"):
        single.act(None, binfo)
    with pytest.raises(ValueError, match="measurement"):
        single.act(None, {"truth": info["truth"]})
    with pytest.raises(ValueError, match="position_rate"):
        PX4Agent(control_rate=200.0, position_rate=400.0)
    with pytest.raises(ValueError, match="setpoint"):
        PX4Agent(setpoint=[0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="unknown observer"):
        PX4ObserverAgent(observer="no_such_eso")
    with pytest.raises(ValueError, match="did you mean MPC_XY_P"):
        PX4Agent(params={"MPC_XYP": 1.0})


def test_short_fawt_study_ordering() -> None:
    """One duty, one seed of the Table 4 study: the FFTS-ESO feedforward lowers the error."""
    from fawtgym.eval.reproduce.table4 import cell_value, run_cell

    cells = {c: run_cell(c, 50, [0], hover_seconds=10.0, fan_on=1.0, fan_off=10.0)
             for c in ("px4", "px4+ffts_eso")}
    base = cell_value(cells["px4"], "mean_position_error")
    eso = cell_value(cells["px4+ffts_eso"], "mean_position_error")
    assert base is not None and eso is not None  # both held hover
    assert eso < 0.6 * base
    phi = cell_value(cells["px4+ffts_eso"], "mean_attitude_error")
    assert phi is not None and 0.0 < phi < 0.1
