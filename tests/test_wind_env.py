"""The wind in the hover env: presets by name and id, truth fields, a custom WindModel (envs/hover_env.py uses
envs/wind and envs/aero; this checks the integration from the wind side)."""

import gymnasium as gym
import numpy as np
import pytest
from _tolerance import assert_same_law

import fawtgym  # noqa: F401  (registers the ids)
from fawtgym.envs.aero import AeroModel
from fawtgym.envs.motors import hover_command
from fawtgym.envs.wind import WindModel


def _steps(env, n=5):
    env.reset(seed=0)
    action = hover_command(env.unwrapped.preset) * np.ones(4)
    infos = []
    for _ in range(n):
        _, _, term, trunc, info = env.step(action)
        infos.append(info)
        assert not (term or trunc)
    return infos


@pytest.mark.parametrize("spec", ["fawtgym/HoverFAWT50-v0", {"wind": "fawt-50"}])
def test_fawt50_wind_and_drag_in_the_truth(spec):
    env = gym.make(spec, init_noise=0.0) if isinstance(spec, str) else gym.make("fawtgym/Hover-v0", init_noise=0.0,
                                                                                 **spec)
    infos = _steps(env)
    wind = np.array([i["truth"]["wind"] for i in infos])
    force = np.array([i["truth"]["force"] for i in infos])
    assert np.all(np.abs(wind[:, 0] - 8.17) < 1.5)  # stream-wise = north, the model's hover-point mean
    assert np.all(force[:, 0] > 2.0)
    env.close()


class _Uniform(WindModel):
    """A custom wind object: uniform 5 m/s toward east."""

    def reset(self, n, seed=None):
        self.n = n

    def step(self, t, dt, points_ned, vehicle_velocity_ned):
        out = np.zeros(points_ned.shape)
        out[..., 1] = 5.0
        return out


def test_custom_wind_object_gives_the_aero_wrench():
    env = gym.make("fawtgym/Hover-v0", wind=_Uniform(), init_noise=0.0)
    info = _steps(env, 1)[0]
    np.testing.assert_allclose(info["truth"]["wind"], [0.0, 5.0, 0.0])
    t = info["truth"]
    f, tau = AeroModel(env.unwrapped.preset).wrench(t["attitude"][None], t["velocity"][None],
                                                   t["angular_velocity"][None],
                                                   info["applied"]["motor_speeds"][None],
                                                   np.tile([0.0, 5.0, 0.0], (1, 5, 1)))
    # the env's step and the batched model: two implementations of one law (tests/_tolerance.py)
    assert_same_law(t["force"], f[0], what="force")
    assert_same_law(t["torque"], tau[0], what="torque")
    env.close()
