"""Shared test helpers (not a test module itself): observers run on the hover env's measurements at its control
rate (tests/test_geso_env.py, test_hc_eso_env.py), a recorded PX4 hover sequence of the single env
(test_hc_eso_tumbling_and_errors.py, test_pdt_sta_quest_cases_and_errors.py) and recorded PX4 flights of a batched
env (test_px4_cascade.py, test_agent_row_reset.py).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import fawtgym  # noqa: F401  (registers the env ids)
from fawtgym.observers import make_observer

EXT_FORCE = np.array([0.5, -0.3, 0.2])
EXT_TORQUE = np.array([0.02, -0.01, 0.005])


def run_hover_with_observers(names: list[str], steps: int = 150, sensors: str = "none") -> list[tuple[dict, dict]]:
    """Hover fawtgym/Hover-v0 (calm wind, CTBR hover thrust, 100 Hz) under the constant external wrench
    (EXT_FORCE world NED, EXT_TORQUE body FRD) and feed every step to the default-gain observers `names`.

    Returns one (estimates by observer name, info["truth"]) pair per step.
    """
    env = gym.make("fawtgym/Hover-v0", wind="calm", sensors=sensors, init_noise=0.0, action_type="ctbr",
                   control_rate=100.0)
    u = env.unwrapped
    _, info = env.reset(seed=0)
    u.set_external_wrench(EXT_FORCE, EXT_TORQUE)
    p = u.preset
    action = np.array([p.mass * 9.80665 / (4 * p.max_thrust_per_rotor), 0.0, 0.0, 0.0])
    observers = {n: make_observer(n, p.mass, p.inertia_matrix) for n in names}
    for o in observers.values():
        o.reset(info["measurement"])
    rows = []
    for _ in range(steps):
        _, _, term, _, info = env.step(action)
        assert not term, info["failure"]
        ap = info["applied"]
        est = {n: o.update(info["measurement"], ap["thrust"], ap["torque"], u.dt) for n, o in observers.items()}
        rows.append((est, info["truth"]))
    env.close()
    return rows


def px4_hover_sequence(seed: int, steps: int = 1000) -> tuple[dict, list[tuple[dict, object, object, dict]], object,
                                                               float]:
    """``steps`` control steps (100 Hz) of fawtgym/Hover-v0 in the fawt-50 wind with the mocap_imu sensors under PX4
    control, from ``reset(seed=seed)``: (the first measurement, one (measurement, applied thrust, applied torque,
    info["truth"]) per step, the vehicle preset, the control step dt).  Used by the observers' on-the-env tests."""
    from fawtgym.agents.px4_agent import PX4Agent

    env = gym.make("fawtgym/Hover-v0", sensors="mocap_imu", wind="fawt-50")
    u = env.unwrapped
    _, info = env.reset(seed=seed)
    agent = PX4Agent.for_env(env)
    agent.reset(info, seed=seed)
    first = info["measurement"]
    rows = []
    for _ in range(steps):
        _, _, term, _, info = env.step(agent.act(None, info))
        assert not term, info["failure"]
        ap = info["applied"]
        rows.append((info["measurement"], ap["thrust"], ap["torque"], info["truth"]))
    env.close()
    return first, rows, u.preset, u.dt


def record_px4_batch(seeds: list[int], on_time: float, steps: int) -> list[dict]:
    """The infos (reset + ``steps`` steps) of a batched env, one row per seed, flown by PX4 in the fawt-50 wind with
    the fan switched on at ``on_time`` s, motion capture + IMU sensors, 200 Hz control, rows perturbed
    (``init_noise=1``): recorded flights the agent tests replay open loop."""
    from fawtgym.agents.spec import make_agent
    from fawtgym.envs.hover_batch_env import HoverBatchEnv

    env = HoverBatchEnv(num_envs=len(seeds), wind={"name": "fawt-50", "on_time": on_time}, sensors="mocap_imu",
                        control_rate=200.0, episode_seconds=5.0, init_noise=1.0)
    agent = make_agent("px4", env)
    obs, info = env.reset(seed=seeds)
    agent.reset(info)
    infos = [info]
    for _ in range(steps):
        obs, _, _, _, info = env.step(agent.act(obs, info))
        infos.append(info)
    env.close()
    return infos
