"""HoverBatchEnv's same-step autoreset (what SB3 needs): the episodes of the next-step mode, without the reward-0 step.

A same-step run and a next-step run of the same env, driven by the same per-episode actions, must give the same
episodes row by row -- lengths, every reward and observation, the terminal observation, how they ended -- bitwise
(the same code path: the restart reuses the reset of the next-step mode), with a row pushed out of the box (a
failure that desynchronizes the rows), truncations, a deterministic wind run in cohorts, and the ctbr rate loop.
"""

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv

N = 4


def _episodes(env, table, steps, push=None, push_at=10):
    """Per row, the finished episodes (length, rewards, observations incl. the terminal one, terminated) of a run in
    which row i's action at episode step k is ``table[k % len(table), i]`` (a per-episode action sequence, so the
    next-step mode's reset step does not shift the actions)."""
    n = env.num_envs
    same = env.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    obs, _ = env.reset(seed=3)
    k_ep = np.zeros(n, dtype=int)
    cur = [[obs[i].copy()] for i in range(n)]
    rews = [[] for _ in range(n)]
    eps = [[] for _ in range(n)]
    pending = np.zeros(n, dtype=bool)
    for k in range(steps):
        if push is not None and k == push_at:
            env.set_external_wrench(push)
        if push is not None and k == push_at + 5:
            env.set_external_wrench()
        obs, rew, term, trunc, info = env.step(table[k_ep % len(table), np.arange(n)])
        k_ep += 1
        for i in range(n):
            if not same and pending[i]:  # the next-step mode's reset step
                assert rew[i] == 0.0 and not term[i] and not trunc[i]
                cur[i], rews[i], k_ep[i] = [obs[i].copy()], [], 0
                continue
            rews[i].append(rew[i])
            if term[i] or trunc[i]:
                last = info["final_obs"][i] if same else obs[i]
                eps[i].append((len(rews[i]), np.array(rews[i]), np.array(cur[i] + [last]), bool(term[i])))
                if same:
                    assert info["_final_obs"][i] and info["time"][i] == 0.0
                    cur[i], rews[i], k_ep[i] = [obs[i].copy()], [], 0
            else:
                cur[i].append(obs[i].copy())
        pending = term | trunc
    return eps


@pytest.mark.parametrize("kw", [dict(wind="calm"),
                                dict(wind={"name": "gust-1cos", "start_time": 0.1}),  # cohorts (time-varying)
                                dict(wind="calm", action_type="ctbr")], ids=["calm", "gust-cohorts", "ctbr"])
def test_same_step_episodes_equal_next_step_episodes(kw):
    kw = dict(kw, sensors="none", episode_seconds=0.3)
    hover = HoverBatchEnv(N, **kw).hover_action()
    table = hover + 0.02 * np.random.default_rng(0).standard_normal((40, N, 4))
    push = np.zeros((N, 3))
    push[1, 0] = 400.0  # row 1 leaves the box: a failure, then the rows restart at different times
    ref = _episodes(HoverBatchEnv(N, **kw), table, 200, push)
    got = _episodes(HoverBatchEnv(N, **kw, autoreset_mode="same_step"), table, 200, push)
    assert ref[1][0][3] and ref[1][0][0] < 30  # the failure happened
    for i in range(N):
        m = min(len(ref[i]), len(got[i]))
        assert m >= 5
        for (l1, r1, o1, t1), (l2, r2, o2, t2) in zip(ref[i][:m], got[i][:m], strict=True):
            assert l1 == l2 and t1 == t2
            np.testing.assert_array_equal(r2, r1)
            np.testing.assert_array_equal(o2, o1)
        assert not any(t for *_, t in got[i][1:m])  # the later episodes were truncated


def test_single_row_same_step_equals_next_step_with_noise_and_turbulence():
    """At N = 1 the restart's wind and sensor noise come from the streams the next-step reset uses: bitwise."""
    kw = dict(wind="fawt-50", sensors="mocap_imu", control_rate=200.0, episode_seconds=0.1)
    hover = HoverBatchEnv(1, **kw).hover_action()
    table = hover + 0.02 * np.random.default_rng(1).standard_normal((20, 1, 4))
    ref = _episodes(HoverBatchEnv(1, **kw), table, 100)
    got = _episodes(HoverBatchEnv(1, **kw, autoreset_mode="same_step"), table, 100)
    m = min(len(ref[0]), len(got[0]))
    assert m >= 4
    for a, b in zip(ref[0][:m], got[0][:m], strict=True):
        assert a[0] == b[0] and a[3] == b[3]
        np.testing.assert_array_equal(b[1], a[1])
        np.testing.assert_array_equal(b[2], a[2])


def test_restart_leaves_the_other_rows_streams_untouched():
    """A row restarting while others fly draws its first sensor noise from its own generator: row 0 of a noisy run
    is bitwise the same whether or not row 1 fails and restarts on the way."""
    def run(push_row1):
        env = HoverBatchEnv(3, episode_seconds=0.2, autoreset_mode="same_step", sensors="mocap_imu",
                            control_rate=200.0)
        env.reset(seed=1)
        out = []
        for k in range(39):  # before row 0's own restart
            if k == 5 and push_row1:
                env.set_external_wrench(np.array([[0.0, 0, 0], [500.0, 0, 0], [0, 0, 0]]))
            obs, rew, term, trunc, info = env.step(env.hover_action())
            out += [obs[0], info["measurement"]["specific_force"][0], info["measurement"]["position"][0]]
            if push_row1 and k > 5:
                env.set_external_wrench()
        return out, term

    ref, _ = run(False)
    got, _ = run(True)
    for a, b in zip(ref, got, strict=True):
        np.testing.assert_array_equal(b, a)


def test_same_step_info_format_matches_gymnasium_sync_vector_env():
    """final_obs / final_info and their masks as gymnasium's SyncVectorEnv (SAME_STEP) gives them."""
    kw = dict(episode_seconds=0.05, init_noise=0.0)
    batch = HoverBatchEnv(2, **kw, autoreset_mode="same_step")
    sync = SyncVectorEnv([lambda: HoverEnv(**kw)] * 2, autoreset_mode=AutoresetMode.SAME_STEP)
    assert batch.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    assert HoverBatchEnv(2).metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP  # the default is unchanged
    ob, _ = batch.reset(seed=0)
    os_, _ = sync.reset(seed=0)
    for _ in range(5):
        rb = batch.step(batch.hover_action())
        rs = sync.step(batch.hover_action())
    (ob, rwb, tb, trb, ib), (os_, rws, ts, trs, is_) = rb, rs
    assert trb.all() and trs.all() and not tb.any() and not ts.any()
    np.testing.assert_allclose(rwb, rws, rtol=1e-12)  # the terminal step's rewards
    for key in ("final_obs", "_final_obs", "final_info", "_final_info"):
        assert key in ib and key in is_
    assert ib["final_obs"].dtype == object and is_["final_obs"].dtype == object
    np.testing.assert_array_equal(ib["_final_obs"], is_["_final_obs"])
    np.testing.assert_allclose(np.stack(ib["final_obs"]), np.stack(is_["final_obs"]), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(ob, os_, rtol=1e-6, atol=1e-9)  # the new episodes' first observations
    fb, fs = ib["final_info"], is_["final_info"]
    assert set(fb) == set(fs)  # every key with its "_key" mask, at every level
    for part in ("measurement", "applied", "truth"):
        assert set(fb[part]) == set(fs[part])
        np.testing.assert_array_equal(fb[part]["_position" if part != "applied" else "_thrust"], [True, True])
    np.testing.assert_array_equal(fb["time"], fs["time"])
    assert np.all(ib["time"] == 0.0)


def test_autoreset_mode_validated():
    with pytest.raises(ValueError, match=r"must be one of \['next_step', 'same_step'\], got 'sometimes'"):
        HoverBatchEnv(2, autoreset_mode="sometimes")
    with pytest.raises(ValueError, match="autoreset_mode"):
        HoverBatchEnv(2, autoreset_mode=AutoresetMode.DISABLED)
    assert HoverBatchEnv(2, autoreset_mode=AutoresetMode.SAME_STEP).metadata["autoreset_mode"] \
        is AutoresetMode.SAME_STEP
    with pytest.raises(ValueError, match="randomizer must be None or a callable"):
        HoverBatchEnv(2, randomizer=3)
