"""The training stack refuses a bad policy action, seed or bound in one line (numpy's broadcast errors, a (4,) action
spread over every row, inf clipped silently and raw Python errors before)."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.train.envs import make_single_env, make_train_env

STACKS = [("state", "ctbr"), ("state", "motors"), ("state+eso", "residual")]


@pytest.mark.parametrize("obs, action", STACKS, ids=[f"{o}-{a}" for o, a in STACKS])
def test_policy_actions_are_checked_like_the_envs(obs: str, action: str) -> None:
    venv = make_train_env(num_envs=3, obs=obs, action=action, seed=0)
    single = make_single_env(obs=obs, action=action, seed=0)
    try:
        venv.reset()
        single.reset()
        for bad, match in [(np.zeros((3, 3)), r"^policy actions must have shape \(3, 4\), got \(3, 3\)$"),
                           (np.zeros(4), r"^policy actions must have shape \(3, 4\), got \(4,\)$"),  # was spread
                           (np.full((3, 4), "a"), r"^policy actions must be real numbers \(int or float\)"),
                           (np.full((3, 4), np.inf), r"^policy actions\[0, 0\] is inf; every action entry must be "
                                                     r"finite \(bounds \[-1.0, -1.0, -1.0, -1.0\] \.\. \[1.0, ")]:
            venv.step_async(bad)
            with pytest.raises(ValueError, match=match):
                venv.step_wait()
        with pytest.raises(ValueError, match=r"^policy actions must have shape \(4,\), got \(3,\)$"):
            single.step(np.zeros(3))
        with pytest.raises(ValueError, match=r"^policy actions\[1\] is nan"):
            single.step(np.array([0.0, np.nan, 0.0, 0.0]))
        big = np.zeros((3, 4))
        big[1, 2] = 5.0  # outside [-1, 1]: clipped, and now flagged for that row
        venv.step_async(big)
        venv.step_wait()
        assert venv.last_info["action_clipped"].tolist() == [False, True, False]
        assert single.step(np.array([0.0, 0.0, -3.0, 0.0]))[4]["action_clipped"] is True
    finally:
        venv.close()


def test_seeds_and_bounds_are_checked_where_given() -> None:
    with pytest.raises(ValueError, match=r"^seed must be an int in \[0, 4294967294\], got 'a' \(str\)$"):
        make_train_env(num_envs=2, seed="a")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^seed must be an int in \[0, 4294967294\], got -1 \(int\)$"):
        make_train_env(num_envs=2, seed=-1)  # it failed at the first reset, naming [-1, 0]
    venv = make_train_env(num_envs=2, action="residual", residual_bound=np.float32(0.1))  # a numpy float is a number
    try:
        with pytest.raises(RuntimeError, match=r"^step_wait\(\) called without step_async\(actions\) before it$"):
            venv.step_wait()
        with pytest.raises(ValueError, match=r"^seed must be an int"):
            venv.seed("a")  # type: ignore[arg-type]
        assert list(venv.seed(7)) == [7, 8]
    finally:
        venv.close()
