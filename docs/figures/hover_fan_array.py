"""Make ``docs/figures/hover_fan_array.png``: PX4+FFTS-ESO 5 s after the fan (50 % duty) starts, 800 x 600.

Run from the repository root: ``python docs/figures/hover_fan_array.py`` (needs Pillow, which
matplotlib installs).
"""

import gymnasium as gym
from PIL import Image

import fawtgym  # noqa: F401  (registers the env ids)
from fawtgym.agents.spec import make_agent

env = gym.make("fawtgym/Hover-v0", vehicle="s500", wind={"name": "fawt-50", "on_time": 1.0}, sensors="mocap_imu",
               control_rate=200.0, episode_seconds=10.0, init_noise=0.0, render_mode="rgb_array",
               render_width=800, render_height=600)
agent = make_agent("px4+ffts_eso", env.unwrapped)
obs, info = env.reset(seed=0)
agent.reset(info)
for _ in range(1200):  # 6 s at 200 Hz
    obs, reward, terminated, truncated, info = env.step(agent.act(obs, info))
Image.fromarray(env.render()).save("docs/figures/hover_fan_array.png", optimize=True)
env.close()
