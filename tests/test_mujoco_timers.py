"""fawtgym.envs.mujoco_timers: MuJoCo's profiler timers off while an env's physics runs (and set back after)."""

from __future__ import annotations

import copy
import ctypes
import pickle
import threading

import mujoco
import numpy as np
import pytest

from fawtgym.envs import mujoco_timers as T
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv

pytestmark = pytest.mark.skipif(not T.AVAILABLE, reason="libmujoco's mjcb_time not reachable on this platform")

STEP = int(mujoco.mjtTimer.mjTIMER_STEP)


def _stepped_duration(active: bool) -> tuple[float, int]:
    """The STEP timer's (duration, count) added by 50 mj_steps of a fresh MjData, timers suspended or not."""
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><freejoint/><geom size='.1'/></body>"
                                           "</worldbody></mujoco>")
    data = mujoco.MjData(model)
    with T.suspended(active):
        for _ in range(50):
            mujoco.mj_step(model, data)
    return data.timer[STEP].duration, data.timer[STEP].number


#: the C type of ``mjcb_time``: ``mjtNum (*)(void)``
_TIMER = ctypes.CFUNCTYPE(ctypes.c_double)


def test_an_envs_physics_runs_without_the_timers_unless_asked():
    """A counting timer callback in MuJoCo's slot is called by every timed stage: never while a default env's
    physics runs, many times for an env built with mujoco_timers=True (the bindings' clock is put back after)."""
    calls = [0]

    def clock() -> float:
        calls[0] += 1
        return 0.0

    counting = _TIMER(clock)  # kept alive until the slot holds the bindings' clock again
    before = T.timer_callback()
    T._SLOT.value = ctypes.cast(counting, ctypes.c_void_p).value
    try:
        for timers, expect_calls in ((False, False), (True, True)):
            env = HoverBatchEnv(2, wind="fawt-50", physics_threads=0, mujoco_timers=timers)
            env.reset(seed=0)
            calls[0] = 0
            for _ in range(5):
                env.step(env.hover_action())
            env.close()
            assert (calls[0] > 0) is expect_calls, (timers, calls[0])
            assert T.timer_callback() == ctypes.cast(counting, ctypes.c_void_p).value  # set back after each step
    finally:
        T._SLOT.value = before
def test_suspended_stops_the_timers_and_sets_the_callback_back():
    before = T.timer_callback()
    assert before is not None  # the bindings' clock (set by `import mujoco`)
    duration, count = _stepped_duration(True)
    assert count == 50 and duration == 0.0  # stepped, but no stage was timed
    assert T.timer_callback() == before
    duration, count = _stepped_duration(False)
    assert count == 50 and duration > 0.0


def test_nested_and_concurrent_uses_share_one_count():
    before = T.timer_callback()
    T.timers_off()
    T.timers_off()
    assert T.timer_callback() is None
    T.timers_on()
    assert T.timer_callback() is None  # one still running
    T.timers_on()
    assert T.timer_callback() == before
    with pytest.raises(RuntimeError, match=r"^mujoco_timers\.timers_on\(\) without a timers_off\(\) before it$"):
        T.timers_on()
    barrier = threading.Barrier(4, timeout=30)
    errors: list[BaseException] = []

    def worker() -> None:
        try:
            for k in range(200):
                with T.suspended():
                    if k == 0:
                        barrier.wait()  # all four inside at once
                    assert T.timer_callback() is None
        except BaseException as exc:  # re-raised by the main thread below
            errors.append(exc)
            barrier.abort()

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert T.timer_callback() == before


def test_a_callback_set_meanwhile_is_kept():
    before = T.timer_callback()
    other = ctypes.cast(ctypes.CDLL(None).drand48, ctypes.c_void_p).value  # a double(void) function (never called)
    T.timers_off()
    T._SLOT.value = other  # someone sets a timer callback while an env's physics runs
    T.timers_on()
    try:
        assert T.timer_callback() == other
    finally:
        T._SLOT.value = before


@pytest.mark.parametrize("n", [1, 3])
def test_the_physics_is_the_same_bit_for_bit_with_or_without_timers(n):
    kw = dict(wind="fawt-50", sensors="mocap_imu", control_rate=200.0, init_noise=1.0, physics_threads=0)
    fast, timed = HoverBatchEnv(n, **kw), HoverBatchEnv(n, mujoco_timers=True, **kw)
    assert not fast.mujoco_timers and timed.mujoco_timers
    callback = T.timer_callback()
    outs = []
    for env in (fast, timed):
        obs, info = env.reset(seed=4)
        rng = np.random.default_rng(0)
        for _ in range(30):
            obs, *_, info = env.step(env.hover_action() + 0.05 * rng.standard_normal((n, 4)))
        outs.append((obs, info["truth"]["position"], env._mj_state.copy()))
        env.close()
    for a, b in zip(*outs, strict=True):
        np.testing.assert_array_equal(a, b)
    assert T.timer_callback() == callback  # set back after every step


def test_the_option_is_checked_and_kept_by_copies():
    with pytest.raises(ValueError, match=r"^mujoco_timers must be True or False, got 'no' \(str\)$"):
        HoverBatchEnv(2, mujoco_timers="no")
    with pytest.raises(ValueError, match=r"^mujoco_timers must be True or False, got 1 \(int\)$"):
        HoverEnv(mujoco_timers=1)
    env = HoverBatchEnv(2, mujoco_timers=True)
    assert copy.deepcopy(env).mujoco_timers and pickle.loads(pickle.dumps(env)).mujoco_timers
    assert HoverEnv().mujoco_timers is False and HoverEnv(mujoco_timers=True).mujoco_timers is True
