"""PPO, SAC and TD3 train on the adapter under VecMonitor + VecNormalize (a few hundred steps each: they accept
the VecEnv, its spaces, its infos and its terminal observations; no learning is claimed)."""

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from fawtgym.train.envs import make_train_env


@pytest.mark.parametrize("algo, kwargs, action, obs", [
    (PPO, dict(n_steps=32, batch_size=64, n_epochs=1), "ctbr", "state+eso"),
    (SAC, dict(learning_starts=100, batch_size=64, buffer_size=2000, train_freq=2, gradient_steps=1), "residual",
     "state+eso"),
    (TD3, dict(learning_starts=100, batch_size=64, buffer_size=2000, train_freq=2, gradient_steps=1), "motors",
     "state"),
], ids=["ppo", "sac", "td3"])
def test_algorithm_runs_on_the_adapter_under_vec_normalize(algo, kwargs, action, obs):
    torch.set_num_threads(1)  # the test machine has 2 cores and pytest-xdist runs 2 workers
    venv = VecNormalize(VecMonitor(make_train_env("table4-50", num_envs=8, action=action, obs=obs,
                                                  episode_seconds=0.15, seed=0)))
    model = algo("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs=dict(net_arch=[32, 32]), **kwargs)
    model.learn(total_timesteps=512)
    assert model.num_timesteps >= 512
    assert len(model.ep_info_buffer) >= 8  # VecMonitor saw the 30-step episodes end
    assert np.all([np.isfinite(ep["r"]) and ep["l"] <= 30 for ep in model.ep_info_buffer])
    assert venv.obs_rms.count > 512
    obs0 = venv.reset()
    act, _ = model.predict(obs0, deterministic=True)
    assert act.shape == (8, 4) and np.all(np.abs(act) <= 1.0)
