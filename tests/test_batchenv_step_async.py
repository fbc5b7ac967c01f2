"""HoverBatchEnv.step_async / step_wait: the step on a worker thread, the same results as step, the same errors, and
no other use of the env while a started step runs."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from fawtgym.envs.hover_batch_env import HoverBatchEnv

KW = dict(wind="fawt-50", sensors="mocap_imu", control_rate=200.0, episode_seconds=0.05, init_noise=0.3)


def _actions(n: int, k: int) -> np.ndarray:
    return np.random.default_rng(k).uniform(-0.2, 0.6, (n, 4)).astype(np.float32)


def _flatten(result: tuple) -> list[np.ndarray]:
    obs, reward, term, trunc, info = result
    out = [obs, reward, term, trunc, info["action_clipped"], info["failure"].astype(str)]
    out += [np.asarray(v) for part in ("measurement", "applied", "truth") for v in info[part].values()]
    return out


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_step_async_then_wait_is_step_bit_for_bit(mode: str) -> None:
    """Two envs from the same seed, one stepped with step, one with step_async + step_wait, through episode ends
    (10-step episodes, autoreset) with noisy sensors and turbulent wind."""
    a, b = HoverBatchEnv(3, autoreset_mode=mode, **KW), HoverBatchEnv(3, autoreset_mode=mode, **KW)
    ra, rb = a.reset(seed=4), b.reset(seed=4)
    assert all(np.array_equal(x, y) for x, y in zip(ra[0], rb[0], strict=True))
    ended = 0
    for k in range(25):
        sa = a.step(_actions(3, k))
        b.step_async(_actions(3, k))
        sb = b.step_wait()
        assert all(np.array_equal(x, y) for x, y in zip(_flatten(sa), _flatten(sb), strict=True)), k
        ended += int(np.sum(sa[2] | sa[3]))
    assert ended > 0  # the autoreset path was taken
    a.close()
    b.close()


def test_two_half_envs_pipelined_give_the_whole_batch() -> None:
    """The pipelined loop of the bench: rows 0-1 stepped on the worker thread while rows 2-3 step on the caller's,
    each half bitwise the same as the rows of one 4-row env with the same seeds (wind from each row's seed; exact
    sensors: noisy ones draw from one stream shared by an env's rows)."""
    kw = {**KW, "episode_seconds": 10.0, "sensors": "none"}
    whole, low, high = HoverBatchEnv(4, **kw), HoverBatchEnv(2, **kw), HoverBatchEnv(2, **kw)
    whole.reset(seed=[7, 8, 9, 10])
    low.reset(seed=[7, 8])
    high.reset(seed=[9, 10])
    for k in range(12):
        act = _actions(4, k)
        obs, *_ = whole.step(act)
        low.step_async(act[:2])
        if k % 2:  # both halves on their worker threads at once (the README's loop)
            high.step_async(act[2:])
            obs_high, *_ = high.step_wait()
        else:  # the high half on the calling thread meanwhile
            obs_high, *_ = high.step(act[2:])
        obs_low, *_ = low.step_wait()
        assert np.array_equal(obs, np.concatenate([obs_low, obs_high])), k


def test_misuse_is_a_runtime_error_and_leaves_the_started_step_intact() -> None:
    env = HoverBatchEnv(2, **KW)
    with pytest.raises(RuntimeError, match=r"step_async\(\) called before reset\(\)"):
        env.step_async(np.zeros((2, 4)))
    env.reset(seed=0)
    with pytest.raises(RuntimeError, match="no step started: call step_async"):
        env.step_wait()
    env.step_async(np.zeros((2, 4)))
    running = r"while a step_async\(\) step is running: call step_wait\(\) first"
    for call in (lambda: env.step(np.zeros((2, 4))), lambda: env.step_async(np.zeros((2, 4))),
                 lambda: env.reset(seed=1), lambda: copy.deepcopy(env), lambda: pickle.dumps(env)):
        with pytest.raises(RuntimeError, match=running):
            call()
    obs, *_ = env.step_wait()
    assert obs.shape == (2, env.single_observation_space.shape[0])
    twin = copy.deepcopy(env)  # idle again: copies, and the copy steps asynchronously too
    twin.step_async(np.zeros((2, 4)))
    assert np.array_equal(twin.step_wait()[0], env.step(np.zeros((2, 4)))[0])
    env.step_async(np.zeros((2, 4)))
    env.close()  # waits for the started step
    twin.close()


@pytest.mark.parametrize("n", [1, 3])
def test_bad_actions_raise_as_at_step(n: int) -> None:
    """Shape and type at step_async; a non-finite entry (which step finds in its first kernel, before anything
    changes) at step_wait: the same exception type and message as step, and the env steps on unchanged."""
    env = HoverBatchEnv(n, **KW)
    env.reset(seed=0)
    for bad in (np.zeros((n, 3)), "a", [[0.0, 0.0, 0.0]] * n):
        with pytest.raises(Exception) as at_step:
            env.step(bad)
        with pytest.raises(type(at_step.value)) as at_async:
            env.step_async(bad)
        assert str(at_async.value) == str(at_step.value)
    nan = np.zeros((n, 4))
    nan[-1, 2] = np.nan
    with pytest.raises(ValueError) as at_step:
        env.step(nan)
    env.step_async(nan)
    with pytest.raises(ValueError) as at_wait:
        env.step_wait()
    assert str(at_wait.value) == str(at_step.value) and "actions[" in str(at_step.value)
    twin = copy.deepcopy(env)
    env.step_async(np.zeros((n, 4)))  # nothing was left pending by the refused calls
    assert np.array_equal(env.step_wait()[0], twin.step(np.zeros((n, 4)))[0])
