"""PX4 + FFTS-ESO (batch-first agent) flies N vehicles of HoverBatchEnv as well as it flies the single env.

FAWT-50 wind (steady, full speed from t = 0: the vehicle is blown downstream and recovers), mocap_imu
sensors, 200 Hz control, 1 kHz physics, 5 simulated seconds.  The mean position error of the N = 8
batch must agree with the single env's (3 seeds) within 25 %: the wind and noise streams differ, the
deterministic mean-wind transient dominates the error.
"""

import gymnasium as gym
import numpy as np

import fawtgym  # noqa: F401
from fawtgym.agents.px4_agent import PX4ObserverAgent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.eval.reproduce.table4 import FLIGHT_GAINS

KW = dict(vehicle="s500", wind="fawt-50", sensors="mocap_imu", control_rate=200.0, physics_rate=1000.0,
          episode_seconds=100.0, init_noise=0.0)
STEPS = 1000  # 5 s at 200 Hz


def _fly(env, seed):
    agent = PX4ObserverAgent.for_env(env, observer="ffts_eso", observer_kwargs=FLIGHT_GAINS)
    obs, info = env.reset(seed=seed)
    agent.reset(info)
    errors = []
    for _ in range(STEPS):
        obs, rew, term, trunc, info = env.step(agent.act(obs, info))
        assert not np.any(term), info["failure"]
        errors.append(np.linalg.norm(np.asarray(info["truth"]["position"]) - info["setpoint"], axis=-1))
    return np.array(errors)  # (STEPS,) or (STEPS, N)


def test_batched_closed_loop_hover_error_matches_single_env():
    singles = np.array([_fly(gym.make("fawtgym/Hover-v0", **KW), seed) for seed in range(3)]).T  # (STEPS, 3)
    batch = _fly(HoverBatchEnv(8, **KW), 0)
    single = singles.mean()
    per_row = batch.mean(axis=0)
    assert abs(per_row.mean() - single) < 0.25 * single, (per_row, single)
    assert per_row.std() < 0.25 * single  # every row flies alike
    # the same error history: 0.5 s window means of the batch follow the single env's
    windows_b = batch.mean(axis=1).reshape(10, -1).mean(axis=1)
    windows_s = singles.mean(axis=1).reshape(10, -1).mean(axis=1)
    assert np.abs(windows_b - windows_s).max() < 0.3 * single, (windows_b, windows_s)
