"""HoverBatchEnv as a gymnasium VectorEnv: spaces, registration, autoreset, row independence, bad input."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import fawtgym  # noqa: F401  (registers the ids)
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv

N = 4


def test_make_vec_vector_entry_point_and_spaces():
    env = gym.make_vec("fawtgym/HoverFAWT50-v0", num_envs=N, vectorization_mode="vector_entry_point",
                       sensors="mocap_imu", control_rate=200.0)
    assert isinstance(env, HoverBatchEnv) and env.num_envs == N
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    single = HoverEnv()
    assert env.single_observation_space == single.observation_space
    assert env.single_action_space == single.action_space
    assert env.observation_space.shape == (N, 19) and env.action_space.shape == (N, 4)
    obs, info = env.reset(seed=1)
    assert obs.dtype == np.float32 and obs in env.observation_space
    obs, rew, term, trunc, info = env.step(env.action_space.sample())
    assert obs.dtype == np.float32 and obs.shape == (N, 19) and obs in env.observation_space
    assert rew.shape == (N,) and rew.dtype == np.float64 and np.all(np.abs(rew) <= 1.0)
    assert term.dtype == bool and trunc.dtype == bool and term.shape == trunc.shape == (N,)
    single_info = single.reset(seed=0)[1]
    for part in ("measurement", "applied", "truth"):
        assert set(info[part]) == set(single_info[part])
        for key, val in single_info[part].items():
            assert info[part][key].shape == (N, *np.shape(val)), (part, key)
    assert info["setpoint"].shape == (N, 3) and info["time"].shape == (N,)
    assert info["action_clipped"].shape == (N,) and info["action_clipped"].dtype == bool
    assert info["failure"].shape == (N,) and info["failure"].dtype.kind == "U"
    env.close()
    # the single-env vectorizers still work, and the default mode is the batch env
    for mode in ("sync", "async"):
        venv = gym.make_vec("fawtgym/Hover-v0", num_envs=2, vectorization_mode=mode)
        assert not isinstance(venv, HoverBatchEnv)
        venv.close()
    assert isinstance(gym.make_vec("fawtgym/Hover-v0", num_envs=2), HoverBatchEnv)


def test_checker_style_determinism_and_fresh_arrays():
    """What gymnasium's check_env verifies for an Env, for the vector env (gymnasium has no vector checker)."""
    kw = dict(wind="fawt-50", sensors="mocap_imu")
    a = HoverBatchEnv(N, **kw)
    b = HoverBatchEnv(N, **kw)
    oa, ia = a.reset(seed=5)
    ob, ib = b.reset(seed=5)
    assert np.array_equal(oa, ob)
    acts = np.random.default_rng(0).uniform(0.2, 0.4, (20, N, 4))
    prev = oa
    for act in acts:
        ra, rb = a.step(act), b.step(act)
        for x, y in zip(ra[:4], rb[:4], strict=True):
            assert np.array_equal(x, y)
        assert np.array_equal(ra[4]["measurement"]["gyro"], rb[4]["measurement"]["gyro"])
        assert ra[0] is not prev and not np.shares_memory(ra[0], prev)  # returned data is not reused
        prev = ra[0]
    oc, _ = a.reset(seed=6)
    assert not np.array_equal(oc, oa)


@pytest.mark.parametrize("wind,sensors", [("calm", "mocap_imu"), ("fawt-50", "mocap_imu")])
def test_rows_are_independent(wind, sensors):
    """Perturbing one row's actions leaves every other row bitwise unchanged (per-row streams)."""
    acts = np.random.default_rng(2).uniform(0.25, 0.35, (40, N, 4))
    pert = acts.copy()
    pert[5:, 2] = 0.0  # row 2 falls, hits the ground and resets
    runs = []
    for a in (acts, pert):
        env = HoverBatchEnv(N, wind=wind, sensors=sensors, setpoint=(1.5, 0.0, -0.3), episode_seconds=1.0)
        env.reset(seed=3)
        out = []
        for act in a:
            obs, rew, term, trunc, info = env.step(act)
            out.append((obs, rew, term, info["truth"]["position"], info["measurement"]["gyro"], info["failure"]))
        runs.append(out)
    assert any(step[5][2] == "ground_contact" for step in runs[1])
    keep = [0, 1, 3]
    for x, y in zip(runs[0], runs[1], strict=True):
        for u, v in zip(x, y, strict=True):
            assert np.array_equal(u[keep], v[keep])


def test_autoreset_and_truncation_per_row():
    env = HoverBatchEnv(N, init_noise=0.0, episode_seconds=0.5, setpoint=(0.0, 0.0, -0.3))
    obs0, _ = env.reset(seed=0)
    hover = env.hover_action()
    act = hover.copy()
    act[1] = 0.0  # row 1 falls
    for _ in range(100):
        obs, rew, term, trunc, info = env.step(act)
        if term[1]:
            break
    assert term[1] and info["failure"][1] == "ground_contact" and rew[1] == -1.0
    assert not term[[0, 2, 3]].any() and not trunc.any() and (info["failure"][[0, 2, 3]] == "").all()
    t_before = info["time"].copy()
    obs, rew, term, trunc, info = env.step(act)  # NEXT_STEP: row 1 resets, its action is ignored
    assert rew[1] == 0.0 and not term[1] and not trunc[1] and info["time"][1] == 0.0
    assert np.array_equal(obs[1], obs0[1])  # init_noise 0: the same start
    assert np.allclose(info["time"][[0, 2, 3]], t_before[[0, 2, 3]] + env.dt)
    steps_left = env.max_steps - int(round(info["time"][0] / env.dt))
    for _ in range(steps_left):
        obs, rew, term, trunc, info = env.step(hover)
    assert trunc[[0, 2, 3]].all() and not trunc[1] and not term.any()
    obs, rew, term, trunc, info = env.step(hover)
    assert np.array_equal(info["time"][[0, 2, 3]], np.zeros(3)) and info["time"][1] > 0


def test_divergence_ends_one_row_only():
    env = HoverBatchEnv(N, init_noise=0.0)
    ref = HoverBatchEnv(N, init_noise=0.0)
    _, info0 = env.reset(seed=0)
    ref.reset(seed=0)
    force = np.zeros((N, 3))
    force[3] = 1e308
    env.set_external_wrench(force)  # acts from the next step on
    a = env.hover_action()
    pos_before = info0["truth"]["position"][3]
    r1, r2 = env.step(a), ref.step(a)
    obs, rew, term, trunc, info = r1
    assert term[3] and info["failure"][3] == "diverged" and rew[3] == -1.0
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(info["truth"]["position"]))
    assert np.array_equal(info["truth"]["position"][3], pos_before)  # the last finite state is kept
    for x, y in zip(r1[:3], r2[:3], strict=True):
        assert np.array_equal(x[:3], y[:3])
    assert not term[:3].any()


def test_bad_input():
    env = HoverBatchEnv(3)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((3, 4)))
    env.reset(seed=0)
    a = np.full((3, 4), 0.3)
    a[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"actions\[1, 2\] is nan"):
        env.step(a)
    a[1, 2] = np.inf
    with pytest.raises(ValueError, match=r"actions\[1, 2\] is inf"):
        env.step(a)
    with pytest.raises(ValueError, match=r"shape \(3, 4\)"):
        env.step(np.zeros(4))
    a = np.full((3, 4), 0.3)
    a[2, 0] = 1.5
    *_, info = env.step(a)
    assert info["action_clipped"].tolist() == [False, False, True]
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"nope": 1})
    with pytest.raises(ValueError, match="setpoint"):
        env.reset(options={"setpoint": np.zeros((2, 3))})
    with pytest.raises(ValueError, match="external wrench"):
        env.set_external_wrench((np.nan, 0, 0))
    with pytest.raises(ValueError, match="num_envs"):
        HoverBatchEnv(0)
    with pytest.raises(ValueError, match="render_mode"):
        HoverBatchEnv(2, render_mode="rgb_array")
    with pytest.raises(ValueError, match="unknown wind"):
        HoverBatchEnv(2, wind="hurricane")
    with pytest.raises(ValueError, match="control_rate"):
        HoverBatchEnv(2, control_rate=300.0)
    with pytest.raises(ValueError, match="action_type"):
        HoverBatchEnv(2, action_type="rates")
    ctbr = HoverBatchEnv(2, action_type="ctbr")
    ctbr.reset(seed=0)
    a = np.zeros((2, 4))
    a[0, 3] = -np.inf
    with pytest.raises(ValueError, match=r"actions\[0, 3\] is -inf"):
        ctbr.step(a)


def test_reset_options_per_row_setpoint():
    env = HoverBatchEnv(2, init_noise=0.0)
    sp = np.array([[1.0, 0.0, -1.0], [2.0, 0.5, -2.0]])
    obs, info = env.reset(seed=0, options={"setpoint": sp})
    assert np.array_equal(info["setpoint"], sp)
    assert np.allclose(info["truth"]["position"], sp)
    assert np.allclose(obs[:, :3], 0.0)


def test_gymnasium_vector_wrappers_work():
    """gymnasium has no vector-env checker; its vector wrappers (which read the autoreset mode) must run."""
    from gymnasium.wrappers.vector import ClipAction, NormalizeObservation, RecordEpisodeStatistics

    env = ClipAction(NormalizeObservation(RecordEpisodeStatistics(HoverBatchEnv(N, episode_seconds=0.2))))
    env.reset(seed=0)
    episodes = 0
    for _ in range(25):
        *_, info = env.step(env.action_space.sample())
        if "episode" in info:
            episodes += int(info["_episode"].sum())
            assert np.all(info["episode"]["l"][info["_episode"]] == 20)
    assert episodes == N


def test_threaded_physics_gives_the_rows_of_the_calling_thread():
    """Physics on one thread per core (one MjData each) from THREADED_ROWS rows on: the rows are independent, so
    the threaded rollout reproduces the single-thread one bitwise (``physics_threads``: the default, or set)."""
    from fawtgym.envs import hover_batch_env

    n = 2 * hover_batch_env.THREADED_ROWS
    assert hover_batch_env.default_physics_threads(1) == 0
    assert hover_batch_env.default_physics_threads(n) in (0, 2)  # 0 on a one-core machine
    threaded = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu", physics_threads=2)
    single = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu", physics_threads=0)
    rng = np.random.default_rng(0)
    for env in (threaded, single):
        env.reset(seed=5)
    for _ in range(5):
        a = (threaded.hover_action() + rng.uniform(-0.1, 0.1, (n, 4))).astype(np.float32)
        out_t, out_s = threaded.step(a), single.step(a)
        np.testing.assert_array_equal(out_t[0], out_s[0])
        np.testing.assert_array_equal(out_t[4]["truth"]["position"], out_s[4]["truth"]["position"])


@pytest.mark.parametrize("bad", [-1, 257, 1.5, "2", True, np.bool_(False), [2]])
def test_physics_threads_refuses_what_is_not_an_int_in_range(bad):
    with pytest.raises(ValueError) as exc:
        HoverBatchEnv(4, physics_threads=bad)
    assert str(exc.value) == ("physics_threads must be None (one per core) or an int in [0, 256] (0: on the calling "
                              f"thread), got {bad!r}")


def test_physics_threads_sets_the_rollout_threads_and_survives_pickling():
    import pickle

    env = HoverBatchEnv(8, physics_threads=np.int64(3))
    env.reset(seed=1)
    copy = pickle.loads(pickle.dumps(env))
    a = env.hover_action()
    np.testing.assert_array_equal(env.step(a)[0], copy.step(a)[0])
    assert env.physics_threads == copy.physics_threads == 3
    assert HoverBatchEnv(1).physics_threads == 0


def test_make_vec_time_limit_truncates_as_the_sync_vector_env_does():
    """gym.make_vec hands a vector entry point the spec's max_episode_steps (it was refused as an unknown option):
    the batch truncates at the shorter of it and episode_seconds, as TimeLimit does around each single env."""
    spec = gym.make("fawtgym/Hover-v0", max_episode_steps=5).spec
    runs = []
    for mode in ("vector_entry_point", "sync"):
        venv = gym.make_vec(spec, num_envs=2, vectorization_mode=mode)
        venv.reset(seed=0)
        runs.append([venv.step(np.zeros((2, 4), dtype=np.float32))[3].tolist() for _ in range(6)])
        venv.close()
    assert runs[0] == runs[1] and runs[0][4] == [True, True] and not any(any(t) for t in runs[0][:4])
    assert HoverBatchEnv(2, episode_seconds=0.03, max_episode_steps=5).max_steps == 3  # the shorter one
    with pytest.raises(ValueError, match=r"^max_steps must be an int in \[1, 2\*\*52\]"):
        HoverBatchEnv(2, max_episode_steps=0)


@pytest.mark.parametrize("make", [lambda: gym.make("fawtgym/Hover-v0", render_mode="rgb_array"),
                                  lambda: HoverBatchEnv(1), lambda: HoverBatchEnv(3)], ids=["single", "N=1", "N=3"])
def test_a_closed_env_refuses_to_step_at_every_batch_size(make):
    """HoverEnv.close() closed only its renderer: step, reset and render went on working."""
    import copy

    env = make()
    env.reset(seed=0)
    env.close()
    env.close()  # twice is allowed
    calls = [lambda: env.step(env.action_space.sample()), lambda: env.reset(seed=0)]
    if isinstance(env.unwrapped, HoverEnv):
        calls.append(env.render)
    else:
        calls.append(lambda: copy.deepcopy(env).step(env.action_space.sample()))  # a closed env's copy is closed
    for call in calls:
        with pytest.raises(RuntimeError, match=r"^the env was closed: step\(\), reset\(\) and render\(\) need a new "
                                               r"env$"):
            call()
