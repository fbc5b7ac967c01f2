"""The hover env: checkers, physics sanity, motors, determinism, rendering, bad input."""

import gymnasium as gym
import numpy as np
import pytest
from _tolerance import assert_same_law
from gymnasium.utils.env_checker import check_env

import fawtgym  # noqa: F401  (registers the ids)
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.motors import hover_command, lag_speeds


def make(**kw):
    return gym.make("fawtgym/Hover-v0", **kw)


@pytest.mark.parametrize("action_type", ["motors", "ctbr"])
def test_gymnasium_and_sb3_checkers(action_type):
    check_env(make(action_type=action_type, sensors="mocap_imu").unwrapped, skip_render_check=True)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    # SB3 only recommends a [-1, 1] action space (ours follows PX4's [0, 1] actuator outputs)
    with pytest.warns(UserWarning, match="symmetric"):
        sb3.check_env(make(action_type=action_type).unwrapped, warn=True)


def test_registered_ids_and_vector_modes():
    assert "fawtgym/Hover-v0" in gym.registry
    for mode in ("sync", "async"):
        venv = gym.make_vec("fawtgym/Hover-v0", num_envs=2, vectorization_mode=mode)
        obs, info = venv.reset(seed=3)
        obs, rew, term, trunc, info = venv.step(venv.action_space.sample())
        assert obs.shape == (2, 19) and rew.shape == (2,)
        assert info["truth"]["force"].shape == (2, 3)
        assert info["measurement"]["attitude"].shape == (2, 3, 3)
        venv.close()


def test_hover_equilibrium_holds():
    env = HoverEnv(init_noise=0.0)
    env.reset(seed=0)
    u = env.hover_action()
    for _ in range(50):
        obs, r, term, trunc, info = env.step(u)
    assert not term
    assert np.abs(env.data.qacc).max() < 1e-6
    assert np.allclose(info["truth"]["position"], env.setpoint, atol=1e-6)
    assert np.isclose(info["applied"]["thrust"], env.preset.mass * 9.80665, rtol=1e-6)  # float32 action
    assert r > 0.999


@pytest.mark.parametrize("up", [True, False])
def test_motor_step_response_time_constant(up):
    env = HoverEnv(init_noise=0.0, control_rate=1000.0)
    env.reset(seed=0)
    p = env.preset
    u0 = hover_command(p)
    u1 = float(np.float32(u0 + (0.2 if up else -0.2)))  # the command the float32 action carries
    w0 = env.rotor_speeds[0]
    w1 = p.omega_min + u1 * (p.omega_max - p.omega_min)
    speeds = []
    for _ in range(150):
        *_, info = env.step(np.full(4, u1, dtype=np.float32))
        speeds.append(info["applied"]["motor_speeds"][0])
    speeds = np.array([w0, *speeds])
    t = np.arange(speeds.size) * env.dt
    # the env's inlined fast path equals the reference closed form of envs/motors.py: two implementations of one
    # law over 150 steps (tests/_tolerance.py)
    assert_same_law(speeds, lag_speeds(p, np.full(4, w0), np.full(4, w1), t)[:, 0], steps=speeds.size,
                    what="motor lag")
    frac = (speeds - w0) / (w1 - w0)
    t63 = np.interp(1 - np.exp(-1), frac, t)
    tau = p.tau_up if up else p.tau_down
    assert abs(t63 - tau) / tau < 0.05


def _spin_after_one_step(env, torque=(0, 0, 0), action=None):
    env.reset(seed=0)
    env.set_external_wrench(torque_frd=torque)
    env.step(env.hover_action())  # the wrench is applied from the next step on
    *_, info = env.step(env.hover_action() if action is None else action)
    return info["truth"]["angular_velocity"]


def test_positive_roll_torque_gives_positive_frd_roll_rate():
    env = HoverEnv(init_noise=0.0)
    w = _spin_after_one_step(env, torque=(0.05, 0, 0))
    assert w[0] > 1e-3 and abs(w[1]) < 1e-9
    w = _spin_after_one_step(env, torque=(0, 0.05, 0))
    assert w[1] > 1e-3


def test_yaw_reaction_torque_per_rotor_direction():
    env = HoverEnv(init_noise=0.0)
    for i, direction in enumerate(env.preset.rotor_directions):
        a = env.hover_action().copy()
        a[i] += 0.05
        env.reset(seed=0)
        for _ in range(3):
            *_, info = env.step(a)
        # a faster CCW rotor (direction +1) pushes the body clockwise seen from above: positive FRD yaw
        assert np.sign(info["truth"]["angular_velocity"][2]) == direction
        assert np.sign(info["applied"]["torque"][2]) == direction


def test_determinism_bitwise_and_seeding():
    def rollout(seed):
        env = make(sensors="mocap_imu", action_type="motors")
        env.action_space.seed(seed)
        obs, info = env.reset(seed=seed)
        traj = [obs]
        for _ in range(60):
            obs, r, term, trunc, info = env.step(env.unwrapped.hover_action() + 0.02 * env.action_space.sample())
            traj.append(obs)
            traj.append(info["measurement"]["gyro"])
        return np.concatenate([np.ravel(x) for x in traj])

    a, b, c = rollout(5), rollout(5), rollout(6)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_rendering_rgb_array_shape():
    env = make(render_mode="rgb_array", render_width=96, render_height=64)
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (64, 96, 3) and img.dtype == np.uint8 and img.std() > 1.0
    env.close()


def test_record_video(tmp_path):
    pytest.importorskip("moviepy", reason="RecordVideo needs moviepy (gymnasium[other])")
    folder = tmp_path / "videos"  # a folder RecordVideo makes itself (an existing one makes it warn)
    env = gym.wrappers.RecordVideo(make(render_mode="rgb_array", episode_seconds=0.2), str(folder))
    env.reset(seed=0)
    done = False
    while not done:
        *_, term, trunc, _ = env.step(env.unwrapped.hover_action())
        done = term or trunc
    env.close()
    assert list(folder.glob("*.mp4"))


def test_observation_is_built_from_measurements_not_truth():
    env = HoverEnv(sensors="seed000", init_noise=0.0)
    obs, info = env.reset(seed=0)
    m = info["measurement"]
    assert np.allclose(obs[:3], m["position"] - env.setpoint, atol=1e-6)
    assert not np.allclose(m["position"], info["truth"]["position"], atol=1e-9)


def test_bad_actions_and_clipping():
    env = HoverEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action\[2\]"):
        env.step(np.array([0.5, 0.5, np.nan, 0.5]))
    with pytest.raises(ValueError, match=r"shape \(4,\)"):
        env.step(np.zeros(3))
    *_, info = env.step(np.array([0.5, 1.7, 0.5, -0.2]))
    assert info["action_clipped"]
    *_, info = env.step(env.hover_action())
    assert not info["action_clipped"]


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"action_type": "rpm"}, "valid"), ({"sensors": "gps"}, "valid"), ({"control_rate": 300.0}, "divide"),
    ({"vehicle": "nope"}, "valid presets"), ({"wind": "hurricane"}, "valid names"),
    ({"reward_weights": {"speed": 1.0}}, "valid"), ({"render_mode": "human"}, "valid"),
    ({"control_rate": -5.0}, r"control_rate must be a finite real number in \[1, 100000\] Hz, got -5.0"),
    ({"setpoint": [0, 0]}, "setpoint"),
])
def test_bad_options_raise_with_valid_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        HoverEnv(**kwargs)


def test_divergence_terminates_with_finite_observation(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT on its bad-acceleration warning
    env = HoverEnv(init_noise=0.0)
    env.reset(seed=0)
    env.set_external_wrench(force_ned=(1e308, 1e308, 1e308))
    env.step(env.hover_action())
    obs, r, term, trunc, info = env.step(env.hover_action())
    assert term and info["failure"] == "diverged"
    assert np.all(np.isfinite(obs)) and np.isfinite(r)


def test_ground_contact_and_out_of_bounds():
    env = HoverEnv(init_noise=0.0, setpoint=(0.0, 0.0, -0.3))
    env.reset(seed=0)
    for _ in range(100):
        *_, term, trunc, info = env.step(np.zeros(4, dtype=np.float32))
        if term:
            break
    assert term and info["failure"] == "ground_contact"
    env = HoverEnv(init_noise=0.0, max_position_error=0.5)
    env.reset(seed=0)
    env.set_external_wrench(force_ned=(5.0, 0, 0))
    for _ in range(200):
        *_, term, trunc, info = env.step(env.hover_action())
        if term:
            break
    assert term and info["failure"] == "out_of_bounds"


def test_truncation_at_episode_end():
    env = HoverEnv(init_noise=0.0, episode_seconds=0.1)
    env.reset(seed=0)
    flags = [env.step(env.hover_action())[3] for _ in range(10)]
    assert flags == [False] * 9 + [True]


def test_observation_carries_the_action_just_applied():
    env = HoverEnv(init_noise=0.0)
    obs, _ = env.reset(seed=0)
    assert np.allclose(obs[-4:], env.hover_action())
    a = np.array([0.3, 0.4, 0.5, 0.6], dtype=np.float32)
    obs, *_ = env.step(a)
    assert np.allclose(obs[-4:], a)
    obs, *_ = env.step(np.array([0.3, 0.4, 1.5, 0.6]))
    assert np.allclose(obs[-4:], [0.3, 0.4, 1.0, 0.6])  # the clipped action is what was applied


def test_external_wrench_has_its_physical_effect():
    """A world-NED force and a body-FRD torque (held over the step) change v and Omega by F dt / m and J^-1 tau dt."""
    force, torque = np.array([0.6, -0.4, 0.3]), np.array([0.003, -0.002, 0.001])

    def one_step(with_wrench):
        env = HoverEnv(init_noise=0.0, control_rate=100.0)
        env.reset(seed=0)
        if with_wrench:
            env.set_external_wrench(force, torque)
        env.reset(seed=0)  # the wrench is held from the first step on
        _, _, _, _, info = env.step(env.hover_action())
        return info["truth"], env

    (t0, _), (t1, env) = one_step(False), one_step(True)
    dt, p = env.dt, env.preset
    np.testing.assert_allclose(t1["velocity"] - t0["velocity"], force / p.mass * dt, rtol=0.02)
    np.testing.assert_allclose(t1["angular_velocity"] - t0["angular_velocity"],
                               np.linalg.solve(p.inertia_matrix, torque) * dt, rtol=0.02)
    # the reported wrench is the one held over the next step: the external part plus the drag of the new motion
    np.testing.assert_allclose(t1["force"] - t0["force"], force, rtol=0.02)
    np.testing.assert_allclose(t1["torque"] - t0["torque"], torque, rtol=0.02)


def test_render_human_is_one_clear_error_through_gym_make():
    """``gym.make(render_mode="human")`` reaches the env's own error (not Gymnasium's pygame wrapper)."""
    with pytest.raises(ValueError, match="'human' is not supported.*rgb_array"):
        gym.make("fawtgym/Hover-v0", render_mode="human")


def test_render_fps_follows_the_control_rate():
    for rate in (100.0, 200.0, 250.0):
        env = gym.make("fawtgym/Hover-v0", control_rate=rate, render_mode="rgb_array")
        assert env.metadata["render_fps"] == pytest.approx(rate)
        env.close()


def test_frame_shows_the_wind_only_when_it_blows():
    """The wind arrows (sky-blue streaks, an orange arrow) appear in FAWT wind and not in still air.

    Their hues are unlike everything else in the frame: the rotors are pure red/blue (green equal to
    the weaker channel), the pole red and white, the rest grey.
    """

    def wind_pixels(wind):
        env = make(render_mode="rgb_array", render_width=160, render_height=160, wind=wind, init_noise=0.0)
        env.reset(seed=0)
        env.step(env.unwrapped.hover_action())
        img = env.render().astype(int)
        env.close()
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        streaks = (g - r > 50) & (b > 150)
        arrow = (r > 150) & (g - b > 60)
        return int(streaks.sum()), int(arrow.sum())

    assert wind_pixels("calm") == (0, 0)
    streaks, arrow = wind_pixels({"name": "fawt-50", "on_time": 0.0})
    assert streaks > 30 and arrow > 10
