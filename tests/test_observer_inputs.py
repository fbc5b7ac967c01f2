"""Realistic observer inputs: a late motion-capture pose, the commanded wrench through a thrust model."""

from __future__ import annotations

import numpy as np
import pytest
from _tolerance import same_law_tol

import fawtgym  # noqa: F401  (registers the env)
from fawtgym.agents.observer_inputs import PoseDelay, commanded_wrench, latency_steps
from fawtgym.agents.px4_agent import PX4ObserverAgent
from fawtgym.agents.spec import make_agent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.motors import allocation_matrix


def _meas(k: float, n: int = 2) -> dict[str, np.ndarray]:
    return {"position": np.full((n, 3), k), "velocity": np.full((n, 3), -k), "attitude": np.full((n, 3, 3), k),
            "specific_force": np.full((n, 3), 10 * k)}


def test_pose_delay_is_exactly_k_steps_and_leaves_the_imu_alone() -> None:
    delay = PoseDelay(3)
    delay.reset(_meas(0.0))
    outs = [delay(_meas(float(k))) for k in range(1, 8)]
    got = [o["position"][0, 0] for o in outs]
    assert got == [0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0]  # filled with the start pose, then 3 steps late
    assert [o["specific_force"][0, 0] for o in outs] == [10.0 * k for k in range(1, 8)]
    assert outs[-1]["velocity"][0, 0] == -4.0 and outs[-1]["attitude"][0, 0, 0] == 4.0
    delay.reset(_meas(9.0), rows=np.array([False, True]))  # row 1 restarts: its history is its new pose
    out = delay(_meas(10.0))
    assert out["position"][1, 0] == 9.0 and out["position"][0, 0] == 5.0
    assert PoseDelay(0)(_meas(2.0))["position"][0, 0] == 2.0


def test_latency_must_be_whole_control_steps() -> None:
    assert latency_steps(0.02, 0.005) == 4
    with pytest.raises(ValueError, match="multiple of the control period"):
        latency_steps(0.012, 0.005)
    with pytest.raises(ValueError, match="pose_latency"):
        latency_steps(-0.01, 0.005)


def test_commanded_wrench_is_the_allocation_scaled_by_the_model_error() -> None:
    from fawtgym.envs.vehicles import make_vehicle

    p = make_vehicle("s500")
    b = allocation_matrix(p)
    rotor = np.array([[0.3, 0.25, 0.3, 0.25], [0.5, 0.5, 0.5, 0.5]])
    f0, t0 = commanded_wrench(rotor, p.max_thrust_per_rotor, b, 0.0)
    np.testing.assert_allclose(f0, rotor.sum(axis=1) * p.max_thrust_per_rotor, rtol=1e-12)
    f1, t1 = commanded_wrench(rotor, p.max_thrust_per_rotor, b, -0.1)
    np.testing.assert_allclose(f1, 0.9 * f0, rtol=1e-12)
    # torques are sums of signed rotor terms (near zero for the balanced row): tolerance scaled by the terms' size
    np.testing.assert_allclose(t1, 0.9 * t0, rtol=1e-12,
                               atol=same_law_tol(scale=float(np.abs(b).max() * rotor.max() * p.max_thrust_per_rotor)))


def _hover(agent_kwargs: dict, seconds: float = 3.0, wind: str = "calm"):
    env = HoverBatchEnv(num_envs=2, vehicle="s500", wind=wind, sensors="mocap_imu", control_rate=200.0,
                        episode_seconds=seconds, init_noise=0.0)
    agent = PX4ObserverAgent.for_env(env, observer="ffts_eso", **agent_kwargs)
    obs, info = env.reset(seed=[0, 1])
    agent.reset(info)
    for _ in range(env.max_steps - 1):
        obs, _, _, _, info = env.step(agent.act(obs, info))
    return agent, info


def test_agent_observer_sees_the_commanded_thrust_through_the_model() -> None:
    agent, info = _hover({"observer_inputs": "commanded", "thrust_model_error": 0.1})
    known = agent.known_inputs(info)["applied"]["thrust"]
    applied = np.asarray(info["applied"]["thrust"])
    # settled calm hover: commanded = applied (no motor transient), so the known thrust is 1.1 x the applied
    np.testing.assert_allclose(known, 1.1 * applied, rtol=0.01)
    agent, info = _hover({})
    assert agent.known_inputs(info) is info  # the default: the env's applied wrench
    with pytest.raises(ValueError, match="observer_inputs"):
        _hover({"observer_inputs": "true"})
    with pytest.raises(ValueError, match="thrust_model_error"):
        _hover({"thrust_model_error": 0.7})


def test_grammar_accepts_the_options() -> None:
    env = HoverBatchEnv(num_envs=1, vehicle="s500", wind="calm", sensors="mocap_imu", control_rate=200.0,
                        episode_seconds=1.0, init_noise=0.0)
    agent = make_agent("px4+ffts_eso(pose_latency=0.02, observer_inputs='commanded', thrust_model_error=-0.05)", env)
    assert agent.pose_latency == 0.02 and agent.observer_inputs == "commanded" and agent.thrust_model_error == -0.05
    with pytest.raises(ValueError, match="pose_latency"):
        make_agent("px4(pose_latency=0.013)", env)
