"""Bad input to the hover envs: one clear ValueError naming the value, the same text for HoverEnv and HoverBatchEnv
at every N (one validation layer, envs/options.py); nothing accepted silently; a failed reset changes nothing."""

import copy
import pickle
import re

import numpy as np
import pytest

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.vehicles import make_vehicle


def _message(make):
    with pytest.raises(ValueError) as err:
        make()
    text = str(err.value)
    assert "\n" not in text
    return text


#: the s500's hover thrust ratio m g / (4 k_T omega_max^2) per kg (T_max = 1.15e-5 * 880^2 = 8.9056 N per rotor)
S500_RATIO_PER_KG = 9.80665 / (4 * 1.15e-5 * 880.0**2)

BAD_OPTIONS = [
    ({"control_rate": "100"}, r"control_rate must be a finite real number in \[1, 100000\] Hz, got '100' \(str\)"),
    ({"control_rate": None}, r"control_rate must be a finite real number in \[1, 100000\] Hz, got None"),
    ({"control_rate": True}, r"control_rate must be a finite real number in \[1, 100000\] Hz, got True"),
    ({"physics_rate": 1e-3}, r"physics_rate must be a finite real number in \[100, 100000\] Hz, got 0.001"),
    ({"render_width": -5}, r"render_width must be an int in \[1, 8192\] pixels, got -5"),
    ({"render_height": 2.5}, r"render_height must be an int"),
    ({"reward_weights": [1, 2]}, r"reward_weights must be a mapping"),
    ({"reward_weights": {"pos": "a"}}, r"reward weight 'pos' must be a finite real number in \[0, 1e\+06\], got 'a'"),
    ({"reward_weights": {"speed": 1.0}}, r"unknown reward weight 'speed'"),
    ({"sensors": {"base": "mocap_imu", "gyro_sigma": 0.1}}, r"unknown sensors field\(s\) \['gyro_sigma'\]"),
    ({"sensors": {"gyro_density": "a"}}, r"sensor field 'gyro_density' must be a finite real number in \[0, 10\] "
     r"\(rad/s\)/sqrt\(Hz\), got 'a'"),
    ({"setpoint": [0.0, 0.0, 0.5]}, r"setpoint z must be above the floor"),
    ({"episode_seconds": 1e300}, r"episode_seconds must be a finite real number in \(0, 1e\+09\] s"),
    ({"setpoint": [0.0, 0.0, 0.0]}, r"setpoint z must be above the floor \(z_NED < 0"),
    ({"setpoint": [0.0, np.nan, -1.0]}, r"setpoint must be 3 finite NED coordinates"),
    ({"setpoint": ["a", 0.0, -1.0]}, r"setpoint must be 3 finite NED coordinates"),
    ({"init_noise": True}, r"init_noise must be a finite real number in \[0, 10\] .*, got True"),
    ({"episode_seconds": "10"},
     r"episode_seconds must be a finite real number in \(0, 1e\+09\] s .*, got '10' \(str\)"),
    ({"vehicle": {"base": "s500", "mass": 100.0}},
     rf"vehicle 's500' cannot hover: hover thrust ratio m g / \(4 T_max\) = {100.0 * S500_RATIO_PER_KG:.4g} "
     r"\(mass 100 kg\)"),
    ({"vehicle": {"base": "s500", "mass": 0.001}},
     rf"vehicle 's500' cannot hover: hover thrust ratio m g / \(4 T_max\) = {0.001 * S500_RATIO_PER_KG:.4g} "
     r"\(mass 0.001 kg\) must be in \(0.01, 1\)"),
]


@pytest.mark.parametrize(("kwargs", "pattern"), BAD_OPTIONS)
def test_bad_option_same_error_for_every_env_and_batch_size(kwargs, pattern):
    texts = {_message(lambda: HoverEnv(**kwargs)), _message(lambda: HoverBatchEnv(1, **kwargs)),
             _message(lambda: HoverBatchEnv(3, **kwargs))}
    assert len(texts) == 1, texts
    text = texts.pop()
    assert re.search(pattern, text), text


def test_vehicle_fields_accept_numpy_scalars():
    p = make_vehicle({"base": "s500", "mass": np.float32(1.2), "omega_max": np.int64(900)})
    assert p.mass == pytest.approx(1.2) and type(p.mass) is float and p.omega_max == 900.0
    env = HoverEnv(vehicle=p, init_noise=0.0)
    env.reset(seed=0)
    assert 0.0 < env.hover_action()[0] < 1.0
    with pytest.raises(ValueError,
                       match=r"vehicle field 'mass' must be a finite real number in \[0.0001, 10000\] kg, got True"):
        make_vehicle({"base": "s500", "mass": True})


@pytest.mark.parametrize("n", [None, 1, 3])
def test_reset_errors_and_atomic_reset(n):
    env = HoverEnv(init_noise=0.0) if n is None else HoverBatchEnv(n, init_noise=0.0)
    env.reset(seed=0)
    before = np.array(env.setpoint, copy=True)
    with pytest.raises(ValueError, match=r"init_noise must be a finite real number in \[0, 10\] .*, got -1"):
        env.reset(options={"setpoint": [1.0, 0.0, -1.0], "init_noise": -1})
    np.testing.assert_array_equal(env.setpoint, before)  # nothing applied
    assert env.init_noise == 0.0
    with pytest.raises(ValueError, match=r"reset options must be None or a dict with keys .*, got 5"):
        env.reset(options=5)
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['pos'\]"):
        env.reset(options={"pos": "a"})
    for bad in (1.5, True, -1, "1"):
        with pytest.raises(ValueError, match="seed must be None"):
            env.reset(seed=bad)


@pytest.mark.parametrize("n", [1, 3])
def test_batch_setpoint_is_a_checked_property(n):
    env = HoverBatchEnv(n, init_noise=0.0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="setpoint must be 3 finite NED coordinates"):
        env.setpoint = [0.0, np.nan, -1.0]
    with pytest.raises(ValueError, match="setpoint z must be above the floor"):
        env.setpoint = [0.0, 0.0, 1.0]
    env.setpoint = [1.0, 0.0, -1.2]
    assert env.setpoint.shape == (n, 3)
    obs = env.step(env.hover_action())[0]
    assert np.all(np.isfinite(obs))


def test_step_before_reset_is_a_runtime_error():
    import gymnasium as gym

    made = gym.make("fawtgym/Hover-v0")  # no OrderEnforcing / PassiveEnvChecker: the env's own checks answer
    assert made is made.unwrapped
    for env in (HoverEnv(), made, HoverBatchEnv(1), HoverBatchEnv(3)):
        with pytest.raises(RuntimeError, match=r"step\(\) called before reset\(\)"):
            env.step(np.zeros(env.action_space.shape))


BAD_ACTIONS = [
    (lambda n: np.full((n, 2, 2), 0.5), r"must have shape"),
    (lambda n: np.full((n, 1, 4), 0.5), r"must have shape"),
    (lambda n: np.full((n, 5), 0.5), r"must have shape"),
    (lambda n: np.full((n, 4), 0.5 + 0.1j), r"must be real numbers \(int or float\), got dtype complex128"),
    (lambda n: np.ones((n, 4), dtype=bool), r"must be real numbers \(int or float\), got dtype bool"),
    (lambda n: np.full((n, 4), "a"), r"must be real numbers"),
]


@pytest.mark.parametrize(("make", "pattern"), BAD_ACTIONS)
def test_bad_actions_are_refused(make, pattern):
    env = HoverEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action " + pattern):
        env.step(make(1)[0])  # (2, 2), (1, 4), (5,), complex, bool, str: never flattened or cast
    for n in (1, 3):
        batch = HoverBatchEnv(n)
        batch.reset(seed=0)
        with pytest.raises(ValueError, match="actions " + pattern):
            batch.step(make(n))


def test_non_finite_action_names_the_entry_at_every_batch_size():
    texts = []
    for n in (1, 3):
        env = HoverBatchEnv(n)
        env.reset(seed=0)
        a = env.hover_action().astype(float)
        a[0, 2] = np.inf
        texts.append(_message(lambda env=env, a=a: env.step(a)))
    assert texts[0] == texts[1] and texts[0].startswith("actions[0, 2] is inf")


@pytest.mark.parametrize("action_type", ["motors", "ctbr"])
def test_batch_env_deepcopy_and_pickle_continue_identically(action_type):
    env = HoverBatchEnv(2, wind="fawt-50", sensors="mocap_imu", action_type=action_type)
    env.reset(seed=3)
    a = env.hover_action()
    for _ in range(3):
        env.step(a)
    twins = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    ref = [env.step(a) for _ in range(3)]
    for twin in twins:
        got = [twin.step(a) for _ in range(3)]
        for (o1, r1, *_), (o2, r2, *_) in zip(ref, got, strict=True):
            np.testing.assert_array_equal(o1, o2)
            np.testing.assert_array_equal(r1, r2)


@pytest.mark.parametrize("n", [None, 1, 3])
def test_a_1x3_setpoint_is_every_rows_setpoint_at_every_batch_size(n):
    """(1, 3) broadcasts as numpy's shapes do: every row's set point, for the single env and at every N."""
    sp = [[0.1, 1.4, -1.2]]
    env = HoverEnv(setpoint=sp) if n is None else HoverBatchEnv(n, setpoint=sp)
    try:
        env.reset(seed=0)
        np.testing.assert_array_equal(np.broadcast_to(env.setpoint, (n or 1, 3)), np.repeat(sp, n or 1, axis=0))
        env.reset(seed=0, options={"setpoint": [[0.2, 1.5, -1.0]]})
        np.testing.assert_array_equal(np.broadcast_to(env.setpoint, (n or 1, 3))[-1], [0.2, 1.5, -1.0])
    finally:
        env.close()
