"""The SB3 adapter and the training wrappers: episodes as HoverBatchEnv gives them, env checkers, normalized and
residual actions, observer features with per-row reset, seeding, the VecEnv attribute API, one-line errors."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from fawtgym.agents.policy_io import FEATURE_CLIP, ActionScale, torque_authority
from fawtgym.agents.spec import FFTS_ESO_FLIGHT_GAINS, make_agent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.eval.scenarios import get_scenario
from fawtgym.observers import make_observer
from fawtgym.train.envs import ACTIONS, OBS_MODES, make_single_env, make_train_env, make_vector_env
from fawtgym.train.vec_env import SB3VecEnv
from fawtgym.train.wrappers import (
    NormalizedAction,
    ObserverFeatures,
    ResidualAction,
    SingleNormalizedAction,
    SingleObserverFeatures,
    SingleResidualAction,
)

N = 4
TABLE4 = dict(get_scenario("table4-50").env_options(), episode_seconds=0.3)


def _push(n, row, force=400.0):
    f = np.zeros((n, 3))
    f[row, 0] = force
    return f


def _run_vec(venv, table, steps, push_env, push):
    """SB3 VecEnv run with per-episode actions: per row the episodes (length, float32 rewards, observations,
    terminal observation, truncated flag)."""
    n = venv.num_envs
    obs = venv.reset()
    k_ep = np.zeros(n, dtype=int)
    cur, rews, eps = [[obs[i]] for i in range(n)], [[] for _ in range(n)], [[] for _ in range(n)]
    for k in range(steps):
        if k == 10:
            push_env.set_external_wrench(push)
        if k == 15:
            push_env.set_external_wrench()
        obs, rew, done, infos = venv.step(table[k_ep % len(table), np.arange(n)])
        assert rew.dtype == np.float32 and done.dtype == bool and len(infos) == n
        k_ep += 1
        for i in range(n):
            rews[i].append(rew[i])
            if done[i]:
                assert set(infos[i]) == {"terminal_observation", "TimeLimit.truncated", "failure"}
                eps[i].append((len(rews[i]), np.array(rews[i]), np.array(cur[i] + [infos[i]["terminal_observation"]]),
                               infos[i]["TimeLimit.truncated"], infos[i]["failure"]))
                cur[i], rews[i], k_ep[i] = [obs[i]], [], 0
            else:
                assert infos[i] == {}
                cur[i].append(obs[i])
    return eps


def _run_next_step(env, table, steps, push_env, push):
    """The same run on a next-step vector env (its reset steps skipped)."""
    n = env.num_envs
    obs, _ = env.reset(seed=0)
    k_ep = np.zeros(n, dtype=int)
    cur, rews, eps = [[obs[i]] for i in range(n)], [[] for _ in range(n)], [[] for _ in range(n)]
    pending = np.zeros(n, dtype=bool)
    for k in range(steps):
        if k == 10:
            push_env.set_external_wrench(push)
        if k == 15:
            push_env.set_external_wrench()
        obs, rew, term, trunc, info = env.step(table[k_ep % len(table), np.arange(n)])
        k_ep += 1
        for i in range(n):
            if pending[i]:
                cur[i], rews[i], k_ep[i] = [obs[i]], [], 0
                continue
            rews[i].append(np.float32(rew[i]))
            if term[i] or trunc[i]:
                eps[i].append((len(rews[i]), np.array(rews[i]), np.array(cur[i] + [obs[i]]),
                               bool(trunc[i] and not term[i]), str(info["failure"][i])))
            else:
                cur[i].append(obs[i])
        pending = term | trunc
    return eps


def _assert_same_episodes(got, ref, at_least=3):
    for i in range(len(ref)):
        m = min(len(got[i]), len(ref[i]))
        assert m >= at_least
        for (l1, r1, o1, t1, f1), (l2, r2, o2, t2, f2) in zip(ref[i][:m], got[i][:m], strict=True):
            assert (l1, t1, f1) == (l2, t2, f2)
            np.testing.assert_array_equal(r2, r1)
            np.testing.assert_array_equal(o2, o1)


def test_sb3_vec_env_episodes_match_hover_batch_env_next_step():
    """Lengths, returns, terminal observations, how they ended: as the next-step HoverBatchEnv gives them, for the
    bare env and for the wrapped training stack (normalized action + observer features)."""
    kw = dict(wind="calm", sensors="none", episode_seconds=0.3)
    table = 0.1 * np.random.default_rng(0).standard_normal((40, N, 4))
    push = _push(N, 2)
    hover = HoverBatchEnv(1, **kw).hover_action()[0]

    same = HoverBatchEnv(N, **kw, autoreset_mode="same_step")
    venv = SB3VecEnv(same)
    venv.seed(0)
    got = _run_vec(venv, hover + table, 150, same, push)
    nxt = HoverBatchEnv(N, **kw)
    ref = _run_next_step(nxt, hover + table, 150, nxt, push)
    _assert_same_episodes(got, ref)
    assert ref[2][0][4] == "out_of_bounds" and not ref[2][0][3]  # the pushed row failed, the others truncated
    assert ref[0][0][3] and ref[0][0][4] == ""

    same = HoverBatchEnv(N, **kw, autoreset_mode="same_step")
    venv = SB3VecEnv(ObserverFeatures(NormalizedAction(same)))
    venv.seed(0)
    got = _run_vec(venv, table, 150, same, push)
    nxt = HoverBatchEnv(N, **kw)
    ref = _run_next_step(ObserverFeatures(NormalizedAction(nxt)), table, 150, nxt, push)
    _assert_same_episodes(got, ref)
    assert got[0][0][2].shape[1] == 25


def test_sb3_vec_env_seeding_options_and_attribute_api():
    venv = make_train_env("calm", num_envs=3, action="motors", seed=4, episode_seconds=0.2)
    a = venv.reset()
    venv.seed(4)
    np.testing.assert_array_equal(venv.reset(), a)  # seed() applies at the next reset, once
    assert not np.array_equal(venv.reset(), a)
    base = venv.env.unwrapped
    sp = np.array([[0.0, 0.0, -1.0], [0.5, 0.0, -1.5], [1.0, 0.0, -2.0]])
    venv.set_options([{"setpoint": s} for s in sp])  # per-row options are stacked for the batch
    venv.reset()
    np.testing.assert_array_equal(base.setpoint, sp)
    venv.set_options({"init_noise": 0.0})
    venv.reset()
    np.testing.assert_allclose(venv.last_info["truth"]["position"], sp, atol=1e-12)  # exactly at the set point
    # one env: act once, one value per index asked for
    assert venv.get_attr("dt") == [base.dt] * 3 and venv.get_attr("num_envs", indices=[0, 2]) == [3, 3]
    assert venv.get_attr("render_mode") == [None] * 3
    assert venv.env_method("hover_action", indices=1)[0].shape == (3, 4)
    venv.set_attr("max_position_error", 0.5)
    assert base.max_position_error == 0.5
    assert venv.env_is_wrapped(NormalizedAction) == [True] * 3 and venv.env_is_wrapped(ObserverFeatures) == [False] * 3
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * 3
    with pytest.raises(AttributeError, match="nope"):
        venv.get_attr("nope")
    with pytest.raises(ValueError, match="same-step autoreset"):
        SB3VecEnv(HoverBatchEnv(2))
    with pytest.raises(TypeError, match="gymnasium VectorEnv"):
        SB3VecEnv(HoverEnv())
    venv.close()


def test_sb3_vec_env_under_vec_normalize_and_vec_monitor():
    venv = VecNormalize(VecMonitor(make_train_env("fawt-50-steady", num_envs=N, action="ctbr", obs="state+eso",
                                                  episode_seconds=0.1)), gamma=0.99)
    obs = venv.reset()
    assert obs.shape == (N, 25) and obs.dtype == np.float32
    episodes = 0
    for _ in range(45):
        obs, rew, done, infos = venv.step(np.zeros((N, 4), dtype=np.float32))
        for i in np.flatnonzero(done):
            assert infos[i]["episode"]["l"] == 20 and infos[i]["terminal_observation"].shape == (25,)
            episodes += 1
    assert episodes == 2 * N and np.all(np.isfinite(obs))


@pytest.mark.parametrize("action", ACTIONS)
@pytest.mark.parametrize("obs", OBS_MODES)
def test_env_checkers_pass_for_every_single_env_variant(action, obs):
    env = make_single_env("table4-50", action=action, obs=obs, episode_seconds=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any checker warning fails the test
        gym_check_env(env, skip_render_check=True)
        sb3_check_env(env)
    assert env.observation_space.shape == (19 if obs == "state" else 25,)
    assert env.action_space.low.min() == -1.0 and env.action_space.high.max() == 1.0


@pytest.mark.parametrize("make", [lambda: SingleNormalizedAction(HoverEnv(**TABLE4, action_type="ctbr")),
                                  lambda: SingleObserverFeatures(SingleNormalizedAction(HoverEnv(**TABLE4))),
                                  lambda: SingleResidualAction(HoverEnv(**TABLE4), "px4+ffts_eso", features=True),
                                  lambda: SingleObserverFeatures(SingleResidualAction(HoverEnv(**TABLE4), "px4"),
                                                                 "leso")],
                         ids=["normalized-ctbr", "normalized-motors+eso", "residual+features", "residual-px4+leso"])
def test_env_checkers_pass_for_the_single_env_wrappers(make):
    env = make()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the checker notes that a wrapper is not the raw env
        gym_check_env(env, skip_render_check=True)
        sb3_check_env(env)


@pytest.mark.parametrize("action_type", ["motors", "ctbr"])
def test_normalized_action_zero_is_the_hover_command(action_type):
    env = HoverBatchEnv(3, action_type=action_type, init_noise=0.0, autoreset_mode="same_step")
    hover = env.hover_action()
    low, high = env.single_action_space.low, env.single_action_space.high
    scale = ActionScale(low, high, hover[0])
    np.testing.assert_array_equal(scale(np.zeros((3, 4))), hover.astype(float))
    np.testing.assert_array_equal(scale(-np.ones((3, 4))), np.broadcast_to(low, (3, 4)))
    np.testing.assert_array_equal(scale(np.ones((3, 4))), np.broadcast_to(high, (3, 4)))
    np.testing.assert_allclose(scale(np.full((1, 4), 0.5)), (hover[:1].astype(float) + high) / 2, rtol=1e-15)
    np.testing.assert_allclose(scale.inverse(scale(np.full((1, 4), -0.3))), np.full((1, 4), -0.3), rtol=1e-12)
    # flying u = 0 is flying the hover command
    ref = HoverBatchEnv(3, action_type=action_type, autoreset_mode="same_step")
    wrapped = NormalizedAction(HoverBatchEnv(3, action_type=action_type, autoreset_mode="same_step"))
    ref.reset(seed=2)
    wrapped.reset(seed=2)
    for _ in range(30):
        a, b = ref.step(ref.hover_action()), wrapped.step(np.zeros((3, 4), dtype=np.float32))
        np.testing.assert_array_equal(b[0], a[0])
    single = SingleNormalizedAction(HoverEnv(action_type=action_type))
    np.testing.assert_array_equal(single.action(np.zeros(4, dtype=np.float32)), single.env.hover_action())


def test_residual_zero_flies_exactly_the_base_agent():
    """u = 0: bitwise the trajectory of px4+ffts_eso flying the same-step env itself (resetting its rows)."""
    n = 3
    push = _push(n, 1, force=300.0)

    def pushes(env, k):
        if k == 20:
            env.set_external_wrench(push)
        if k == 30:
            env.set_external_wrench()

    env = HoverBatchEnv(n, **TABLE4, autoreset_mode="same_step")
    agent = make_agent("px4+ffts_eso", env)
    obs, info = env.reset(seed=7)
    agent.reset(info)
    ref = []
    for k in range(180):
        pushes(env, k)
        obs, rew, term, trunc, info = env.step(agent.act(obs, info))
        if (term | trunc).any():
            agent.reset(info, rows=term | trunc)
        ref.append((obs, rew, term, trunc, info["truth"]["position"]))
    assert sum(r[2][1] for r in ref) >= 1 and sum(r[3].sum() for r in ref) >= 2 * n  # a failure and truncations

    env = HoverBatchEnv(n, **TABLE4, autoreset_mode="same_step")
    residual = ResidualAction(env, "px4+ffts_eso", bound=0.1)
    residual.reset(seed=7)
    for k in range(180):
        pushes(env, k)
        obs, rew, term, trunc, info = residual.step(np.zeros((n, 4), dtype=np.float32))
        for x, y in zip((obs, rew, term, trunc, info["truth"]["position"]), ref[k], strict=True):
            np.testing.assert_array_equal(x, y)
    # the bound: u = +-1 moves every command by bound * (high - low) / 2 (inside the bounds)
    base = residual.base_action
    np.testing.assert_allclose(residual.scale(base, np.ones_like(base)), np.minimum(base + 0.05, 1.0), rtol=1e-15)
    single = SingleResidualAction(HoverEnv(**TABLE4), "px4+ffts_eso")
    single.reset(seed=7)
    single_agent = make_agent("px4+ffts_eso", HoverEnv(**TABLE4))
    o, i = single.env.reset(seed=7)
    single_agent.reset(i)
    np.testing.assert_array_equal(single.scale(single_agent.act(o, i)[None], np.zeros((1, 4)))[0], single.base_action)


def test_residual_features_are_the_observer_features():
    """ResidualAction(features=True) reads the base agent's observer: the observations of ObserverFeatures running
    its own copy, bitwise, terminal observations included."""
    n = 3
    envs = [HoverBatchEnv(n, **TABLE4, autoreset_mode="same_step") for _ in range(2)]
    a = ResidualAction(envs[0], "px4+ffts_eso", 0.1, features=True)
    b = ObserverFeatures(ResidualAction(envs[1], "px4+ffts_eso", 0.1), "ffts_eso")
    assert a.single_observation_space == b.single_observation_space
    np.testing.assert_array_equal(a.reset(seed=1)[0], b.reset(seed=1)[0])
    rng = np.random.default_rng(0)
    ended = 0
    for k in range(120):
        if k == 10:
            for e in envs:
                e.set_external_wrench(_push(n, 0, 300.0))
        u = rng.uniform(-1, 1, (n, 4))
        ra, rb = a.step(u), b.step(u)
        np.testing.assert_array_equal(ra[0], rb[0])
        for i in np.flatnonzero(ra[2] | ra[3]):
            np.testing.assert_array_equal(ra[4]["final_obs"][i], rb[4]["final_obs"][i])
            ended += 1
    assert ended >= 2


def test_observer_features_reset_row_equals_a_fresh_observer():
    """The features of a row that restarted are a fresh observer's (reset from the row's reset info, then updated
    with every info of the new episode); the scales are m g and the rotors' torque authority."""
    n = 3
    env = HoverBatchEnv(n, **TABLE4, autoreset_mode="same_step")
    wrapped = ObserverFeatures(NormalizedAction(env))
    obs, info = wrapped.reset(seed=5)
    p = env.preset
    fresh = None
    inv = 1.0 / np.concatenate([[p.mass * 9.80665] * 3, torque_authority(p)])
    np.testing.assert_allclose(torque_authority(p), [3.0226609, 3.0226609, 0.3206016], rtol=1e-6)
    rng = np.random.default_rng(3)
    restarted = None
    for k in range(80):
        if k == 5:
            env.set_external_wrench(_push(n, 1, 400.0))
        if k == 15:
            env.set_external_wrench()
        obs, rew, term, trunc, info = wrapped.step(0.05 * rng.standard_normal((n, 4)))
        if restarted is None and term[1]:
            restarted = k
            fresh = make_observer("ffts_eso", p.mass, p.inertia_matrix, **FFTS_ESO_FLIGHT_GAINS)
            fresh.reset(info["measurement"])  # a fresh observer of the batch, reset from this info
        if fresh is not None:
            est = fresh.update(info["measurement"], info["applied"]["thrust"], info["applied"]["torque"], env.dt)
            want = np.clip(np.concatenate([est.force, est.torque], axis=1) * inv, -FEATURE_CLIP, FEATURE_CLIP)
            np.testing.assert_array_equal(obs[1, 19:], want[1].astype(np.float32))
    assert restarted is not None and restarted < 60


def test_bad_names_give_one_line_errors():
    cases = [
        (dict(scenario="table9-50"), "unknown scenario 'table9-50'; valid: table4-30"),
        (dict(action="thrust"), "unknown action 'thrust'; valid: ctbr, motors, residual"),
        (dict(obs="pixels"), "unknown obs 'pixels'; valid: state, state+eso"),
        (dict(obs="state+eso", observer="kalman"), "unknown observer 'kalman'; valid: "),
        (dict(obs="state+eso", observer_kwargs={"gain": 1.0}),
         "unknown option(s) ['gain'] for observer 'ffts_eso'; valid options: "),
        (dict(action="residual", residual_base="lqr"), "unknown agent 'lqr'"),
        (dict(action="residual", residual_bound=3.0), "residual bound (--residual-bound) must be a finite real number"),
        (dict(randomize={"wind_speed": 1.0}), "unknown randomize key(s) ['wind_speed']; valid: duty, mass"),
        (dict(scenario=["calm", "dryden-light"]), "one scenario per call"),
    ]
    for kwargs, text in cases:
        with pytest.raises(ValueError) as err:
            make_vector_env(**{"num_envs": 2, **kwargs})
        assert text in str(err.value) and "\n" not in str(err.value), (kwargs, str(err.value))
