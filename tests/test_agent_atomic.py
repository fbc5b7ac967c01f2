"""A refused PX4Agent / PX4ObserverAgent call changes nothing: act and reset check every input before any state
changes (the observer's update, the pose delay line, the setpoint), with one-line errors that read the same at every
N; rows of different lengths are refused, never read out of bounds."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fawtgym.agents.px4_agent import PX4Agent, PX4ObserverAgent
from fawtgym.envs.hover_batch_env import HoverBatchEnv

AGENTS = {
    "px4+ffts_eso": lambda env: PX4ObserverAgent.for_env(env, observer="ffts_eso"),
    "px4+sto commanded": lambda env: PX4ObserverAgent.for_env(env, observer="sto", observer_inputs="commanded"),
    "px4 pose_latency": lambda env: PX4Agent.for_env(env, pose_latency=0.02),
    "px4+leso pose_latency": lambda env: PX4ObserverAgent.for_env(env, observer="leso", pose_latency=0.02),
    **{f"px4+{name}": (lambda env, name=name: PX4ObserverAgent.for_env(env, observer=name))
       for name in ("fxtsdo", "geso", "hc_eso", "leso", "qb", "sto")},
}


def _infos(n: int, steps: int = 6) -> tuple[HoverBatchEnv, list[dict]]:
    env = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu")
    obs, info = env.reset(seed=5)
    infos = [copy.deepcopy(info)]
    driver = PX4Agent.for_env(env)
    driver.reset(info)
    for _ in range(steps):
        obs, *_, info = env.step(driver.act(obs, info))
        infos.append(copy.deepcopy(info))
    return env, infos


def _corrupt(info: dict, where: str, row: int) -> dict:
    bad = copy.deepcopy(info)
    if where == "setpoint":
        sp = np.array(bad["setpoint"], dtype=float)
        sp[..., 1] = np.nan
        bad["setpoint"] = sp
    elif where == "attitude":
        bad["measurement"]["attitude"][row] = np.diag([1.0, 1.0, -1.0])  # a reflection
    else:
        bad["measurement"][where][row, 1] = np.nan
    return bad


@pytest.mark.parametrize("name", sorted(AGENTS))
@pytest.mark.parametrize("where", ["specific_force", "angular_velocity", "velocity", "attitude", "setpoint"])
@pytest.mark.parametrize("n", [1, 3])
def test_a_refused_act_changes_nothing(name, where, n):
    env, infos = _infos(n)
    make = AGENTS[name]
    a, b = make(env), make(env)
    a.reset(infos[0])
    b.reset(infos[0])
    for k in range(1, 7):
        if k == 3:
            with pytest.raises(ValueError) as exc:
                a.act(None, _corrupt(infos[k], where, n - 1))
            text = str(exc.value)
            who = (type(a).__name__, getattr(getattr(a, "observer", None), "name", type(a).__name__))
            assert "\n" not in text and text.startswith(who)  # the agent, or its observer for a key it reads
            assert ("info['setpoint']" if where == "setpoint" else f"measurement['{where}']") in text
        np.testing.assert_array_equal(a.act(None, infos[k]), b.act(None, infos[k]))
        if isinstance(a, PX4ObserverAgent):
            np.testing.assert_array_equal(a.raw_estimate[0], b.raw_estimate[0])


@pytest.mark.parametrize("n", [1, 3])
def test_a_bad_setpoint_reads_the_same_at_every_n(n):
    env, infos = _infos(n, 1)
    agent = PX4ObserverAgent.for_env(env, observer="ffts_eso")
    agent.reset(infos[0])
    info = copy.deepcopy(infos[1])
    info["setpoint"] = np.array([0.0, np.inf, -1.5])
    with pytest.raises(ValueError) as exc:
        agent.act(None, info)
    assert str(exc.value) == ("PX4ObserverAgent: info['setpoint'] row 0 is not finite NED coordinates [m] within "
                              "10000 m: [0.0, inf, -1.5]")
    info["setpoint"] = np.array([0.0, 1e300, -1.5])
    with pytest.raises(ValueError, match=r"row 0 is not finite NED coordinates \[m\] within 10000 m"):
        agent.act(None, info)
    for bad in ([1.0, 2.0], "abc", [[1.0, 2.0, 3.0]] * (n + 1), [1j, 0, -1], [[0.0, 0.0], [1.0]]):
        info["setpoint"] = bad
        with pytest.raises(ValueError) as exc:
            agent.act(None, info)
        shapes = "(3,) or (1, 3)" if n == 1 else f"(3,), (1, 3) or ({n}, 3)"
        assert str(exc.value) == (f"PX4ObserverAgent: info['setpoint'] must be real NED coordinates [m] of shape "
                                  f"{shapes}, got {bad!r}")


@pytest.mark.parametrize("name", sorted(AGENTS))
def test_rows_of_different_lengths_are_refused(name):
    env, infos = _infos(3, 1)
    agent = AGENTS[name](env)
    agent.reset(infos[0])
    for key in ("velocity", "angular_velocity", "attitude", "specific_force"):
        info = copy.deepcopy(infos[1])
        info["measurement"][key] = info["measurement"][key][:2]
        who = (type(agent).__name__, getattr(getattr(agent, "observer", None), "name", type(agent).__name__))
        with pytest.raises(ValueError) as exc:
            agent.act(None, info)  # the agent, or its observer for a key it reads, names the key
        assert str(exc.value).startswith(tuple(f"{w}: measurement['{key}']" for w in who)), str(exc.value)
    np.testing.assert_array_equal(agent.act(None, infos[1]), _act(name, env, infos))


def _act(name, env, infos):
    fresh = AGENTS[name](env)
    fresh.reset(infos[0])
    return fresh.act(None, infos[1])


@pytest.mark.parametrize("name", sorted(AGENTS))
@pytest.mark.parametrize("where", ["velocity", "attitude", "setpoint"])
def test_a_refused_reset_changes_nothing(name, where):
    """A full reset and a per-row reset refused for a bad measurement or setpoint leave the agent as it was."""
    env, infos = _infos(3)
    a, b = AGENTS[name](env), AGENTS[name](env)
    a.reset(infos[0])
    b.reset(infos[0])
    for k in (1, 2):
        a.act(None, infos[k])
        b.act(None, infos[k])
    bad = _corrupt(infos[2], where, 1)
    with pytest.raises(ValueError):
        a.reset(bad)
    with pytest.raises(ValueError):
        a.reset(bad, rows=np.array([False, True, False]))
    a.reset(bad, rows=np.array([True, False, False]) if where != "setpoint" else np.array([False, False, False]))
    b.reset(bad, rows=np.array([True, False, False]) if where != "setpoint" else np.array([False, False, False]))
    for k in (3, 4, 5):
        np.testing.assert_array_equal(a.act(None, infos[k]), b.act(None, infos[k]))


@pytest.mark.parametrize("seed", ["a", -1, True, 1.5])
def test_reset_refuses_a_bad_seed_and_changes_nothing(seed):
    env, infos = _infos(1, 1)
    agent = PX4ObserverAgent.for_env(env, observer="ffts_eso")
    with pytest.raises(ValueError) as exc:
        agent.reset(infos[0], seed=seed)
    assert str(exc.value) == f"PX4ObserverAgent.reset: seed must be None or an int >= 0, got {seed!r}"
    with pytest.raises(RuntimeError, match=r"before reset\(\)"):
        agent.act(None, infos[1])
