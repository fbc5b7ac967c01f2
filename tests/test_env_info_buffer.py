"""The step kernels' constants (one array, envs/step_kernels.step_params; the termination box and episode length stay
settable) and the info numbers: one fresh float64 buffer per step (envs/step_kernels.INFO_FIELDS), handed out as
views: the written-out builder matches the layout table, the single env's info is the batch's row 0 with the single
env's Python types, and nothing handed out is written by later steps."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.motors import allocation_matrix
from fawtgym.envs.step_kernels import INFO_FIELDS, INFO_START, INFO_WIDTH, STEP_PARAMS, info_views, step_params

#: the single env's Python scalar types (everything else: numpy arrays of the row's shape)
_SCALARS = {("applied", "thrust"): float, ("measurement", "time"): np.float64, ("", "time"): float,
            **{(group, key): float for group, key, _ in INFO_FIELDS if group == "reward_terms"}}


def _get(info: dict, group: str, key: str) -> object:
    return info[group][key] if group else info[key]


@pytest.mark.parametrize("n", [1, 3])
def test_batch_views_follow_the_layout_table(n: int) -> None:
    buf = np.arange(n * INFO_WIDTH, dtype=float)
    info = info_views(buf, n, single=False)
    seen = 0
    for group, key, shape in INFO_FIELDS:
        width = int(np.prod(shape, dtype=int))
        start = INFO_START[group, key]
        value = _get(info, group, key)
        assert isinstance(value, np.ndarray) and value.shape == (n, *shape) and value.dtype == np.float64
        assert value.flags.c_contiguous and np.shares_memory(value, buf)
        np.testing.assert_array_equal(value.ravel(), buf[start * n:(start + width) * n])
        seen += width
    assert seen == INFO_WIDTH


def test_single_views_are_row_zero_with_python_scalars() -> None:
    buf = np.arange(INFO_WIDTH, dtype=float) + 0.5
    single, batch = info_views(buf, 1, single=True), info_views(buf, 1, single=False)
    for group, key, shape in INFO_FIELDS:
        value, row = _get(single, group, key), _get(batch, group, key)[0]
        kind = _SCALARS.get((group, key))
        if kind is not None:
            assert type(value) is kind and value == row
        else:
            assert isinstance(value, np.ndarray) and value.shape == shape and value.flags.c_contiguous
            np.testing.assert_array_equal(value, row)


def test_single_env_info_is_the_batch_of_one_row_zero() -> None:
    kw = dict(wind="fawt-50", sensors="mocap_imu", init_noise=0.5, control_rate=200.0)
    single, batch = HoverEnv(**kw), HoverBatchEnv(1, **kw)
    outs = [single.reset(seed=4), batch.reset(seed=4)]
    rng = np.random.default_rng(0)
    for _ in range(30):
        a = (single.hover_action() + rng.normal(0.0, 0.03, 4)).astype(np.float32)
        outs = [single.step(a), batch.step(a[None])]
        s_info, b_info = outs[0][-1], outs[1][-1]
        for group, key, _ in INFO_FIELDS:
            np.testing.assert_array_equal(np.asarray(_get(s_info, group, key)), _get(b_info, group, key)[0])
        assert s_info["failure"] == b_info["failure"][0] and s_info["action_clipped"] == b_info["action_clipped"][0]
        np.testing.assert_array_equal(outs[0][0], outs[1][0][0])
        assert outs[0][1] == outs[1][1][0]


def test_applied_thrust_and_torque_are_the_allocation_of_the_rotor_thrusts() -> None:
    env = HoverEnv(wind="fawt-50", sensors="mocap_imu", init_noise=0.5)
    env.reset(seed=1)
    b = allocation_matrix(env.preset)
    for k in range(20):
        a = np.clip(env.hover_action() + 0.05 * np.sin(np.arange(4) + k), 0.0, 1.0).astype(np.float32)
        applied = env.step(a)[-1]["applied"]
        wrench = b @ applied["rotor_thrusts"]
        scale = float(np.abs(b).max() * np.abs(applied["rotor_thrusts"]).sum())
        assert_same_law(np.array([applied["thrust"], *applied["torque"]]), wrench, scale=scale)


def test_single_env_info_is_not_overwritten_by_later_steps() -> None:
    env = HoverEnv(wind="fawt-50", sensors="mocap_imu", init_noise=0.5)
    _, first = env.reset(seed=2)
    _, _, _, _, info = env.step(env.hover_action())
    saved = copy.deepcopy((first, info))
    for _ in range(5):
        env.step(env.hover_action())
    for got, want in zip((first, info), saved, strict=True):
        for group, key, _ in INFO_FIELDS:
            np.testing.assert_array_equal(_get(got, group, key), _get(want, group, key))


def test_step_params_checks_its_names_and_sizes() -> None:
    values = {name: np.zeros(size) for name, size in STEP_PARAMS}
    assert step_params(**values).shape == (sum(size for _, size in STEP_PARAMS),)
    with pytest.raises(ValueError, match="step_params needs exactly"):
        step_params(**{k: v for k, v in values.items() if k != "hull"})
    with pytest.raises(ValueError, match="step parameter 'hull' must have 36 numbers, got 3"):
        step_params(**{**values, "hull": np.zeros(3)})


@pytest.mark.parametrize("n", [1, 3])
def test_termination_box_and_episode_length_set_after_construction_act_from_the_next_step(n: int) -> None:
    env = HoverBatchEnv(n, init_noise=0.0)
    env.reset(seed=0)
    env.set_external_wrench([5.0, 0.0, 0.0])  # pushes every row north
    env.max_position_error = 0.01
    assert env.max_position_error == 0.01
    for _ in range(30):
        _, _, terminated, _, info = env.step(env.hover_action())
        if terminated.any():
            break
    assert terminated.all() and list(info["failure"]) == ["out_of_bounds"] * n
    env.reset(seed=0)
    env.max_steps = 3
    truncated = [env.step(env.hover_action())[3].all() for _ in range(3)]
    assert truncated == [False, False, True] and env.max_steps == 3
    for bad, name in ((float("nan"), "max_position_error"), (-1.0, "max_position_error"), (0, "max_steps"),
                      (2.5, "max_steps")):
        with pytest.raises(ValueError, match=name):
            setattr(env, name, bad)


def test_external_wrench_attributes_assign_through_the_checked_setter() -> None:
    env = HoverBatchEnv(2)
    env.external_force = [1.0, 2.0, 3.0]
    env.external_torque = np.array([[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]])
    np.testing.assert_array_equal(env.external_force, [[1.0, 2.0, 3.0]] * 2)
    np.testing.assert_array_equal(env.external_torque, [[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]])
    with pytest.raises(ValueError, match=r"external wrench must be two \(3,\) or \(2, 3\) arrays of finite real"):
        env.external_force = [np.nan, 0.0, 0.0]
    np.testing.assert_array_equal(env.external_force, [[1.0, 2.0, 3.0]] * 2)  # unchanged by the refused value
