"""An int too long for Python's int-to-str limit (4300 digits) in a bad argument gets the package's own one-line error.

Before, ``reset(seed=-10**5000)`` or ``HoverBatchEnv(10**5000)`` raised Python's "Exceeds the limit (4300 digits)
for integer string conversion" from inside our message (its ``{value!r}``), naming neither the argument nor what
is allowed.  Every such message words the value with :func:`fawtgym.core.checks.shown`.
"""

from __future__ import annotations

import sys

import gymnasium as gym
import pytest

import fawtgym  # noqa: F401  (registers the env)
from fawtgym.core.checks import shown
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.eval.sharded import ShardedLoop, shard_sizes

HUGE = 10**5000


def test_shown_words_huge_ints_and_containers_holding_them():
    assert shown(HUGE) == "an int of about 5001 digits"
    assert shown(-HUGE) == "a negative int of about 5001 digits"
    if sys.get_int_max_str_digits():  # the limit is on (Python's default): repr of the list itself raises
        assert shown([1, HUGE]) == f"a list holding an int of more than {sys.get_int_max_str_digits()} digits"
    assert shown(12) == "12" and shown("x") == "'x'"
    assert shown("y" * 300) == "'" + "y" * 199 + "... (302 characters)"


CASES = [
    ("num_envs", lambda: HoverBatchEnv(HUGE), "num_envs must be an int in [1, 1000000], got an int of about 5001 "
                                              "digits"),
    ("physics_threads", lambda: HoverBatchEnv(2, physics_threads=HUGE), "physics_threads must be None (one per core) "
                                                                        "or an int in [0, 256] (0: on the calling "
                                                                        "thread), got an int of about 5001 digits"),
    ("render_width", lambda: HoverBatchEnv(1, render_width=HUGE), "render_width must be an int in [1, 8192] pixels, "
                                                                  "got an int of about 5001 digits"),
    ("single seed", lambda: gym.make("fawtgym/Hover-v0").reset(seed=-HUGE),
     "seed must be None or an int >= 0, got a negative int of about 5001 digits"),
    ("batch seed", lambda: HoverBatchEnv(2).reset(seed=-HUGE), "seed must be None, an int >= 0 or a list of 2 ints "
                                                               ">= 0 / None (one per row), got a negative int of "
                                                               "about 5001 digits"),
    ("batch seed list", lambda: HoverBatchEnv(2).reset(seed=[1, -HUGE]), "seed must be None, an int >= 0 or a list "
                                                                         "of 2 ints >= 0 / None (one per row), got a "
                                                                         "list holding an int of more than"),
    ("setpoint", lambda: HoverBatchEnv(2).reset(options={"setpoint": [HUGE, 0, -1]}), "setpoint must be 3 finite NED "
                                                                                      "coordinates [m] of shape"),
    ("single setpoint", lambda: gym.make("fawtgym/Hover-v0").reset(options={"setpoint": [-HUGE, 0, -1]}),
     "setpoint must be 3 finite NED coordinates [m] of shape"),
    ("shards", lambda: shard_sizes(4, HUGE), "shards must be an int in [1, n = 4] (envs of at least one row each), "
                                             "got an int of about 5001 digits"),
]


@pytest.mark.parametrize(("what", "call", "start"), CASES, ids=[c[0] for c in CASES])
def test_a_huge_int_gets_our_one_line_error(what, call, start):
    with pytest.raises(ValueError) as err:
        call()
    text = str(err.value)
    assert text.startswith(start), text
    assert "\n" not in text and "Exceeds the limit" not in text and len(text) < 400


def test_max_steps_and_sharded_loop_words_huge_ints():
    env = HoverBatchEnv(2)
    with pytest.raises(ValueError, match=r"max_steps must be an int in \[1, 2\*\*52\] .*, got an int of about 5001 "
                                         r"digits$"):
        env.max_steps = HUGE
    with pytest.raises(ValueError, match=r"^seed must be an int >= 0, got a negative int of about 5001 digits$"):
        ShardedLoop([HoverBatchEnv(1, physics_threads=0)], [object()]).reset(seed=-HUGE)


def test_eval_cells_refuse_seeds_and_trace_rates_that_are_not_what_they_say():
    """fly_cell flew seed 1 for a seed of 1.5 (int() truncation) and ran with record_hz = -1."""
    from fawtgym.eval.runner import cell_key, check_record_hz, check_seeds, fly_cell
    from fawtgym.eval.scenarios import get_scenario

    calm = get_scenario("calm").to_dict()
    for bad in ([1.5], ["a"], [True], [-1], [2**32], [1, 1], [], [HUGE], 5):
        with pytest.raises(ValueError, match=r"^seeds must be 1 to 1000000 distinct int seeds in \[0, 2\*\*32\)"):
            fly_cell("px4", calm, bad)
    for bad in (-1, 0, float("nan"), HUGE, "20", 1e6):
        with pytest.raises(ValueError, match=r"^record_hz must be a finite real number in \[0.001, 100000\] Hz"):
            cell_key("px4", calm, [0], bad)
    assert check_seeds((3, 1)) == [3, 1] and check_record_hz(20) == 20.0


def test_scenario_fields_and_train_config_are_checked():
    from fawtgym.eval.scenarios import adhoc_scenario, get_scenario, scenario_from_mapping
    from fawtgym.train.config import TrainConfig

    for field, bad in (("seconds", HUGE), ("seconds", True), ("control_rate", 0.5),
                       ("setpoint", [float("nan"), 0, -1])):
        with pytest.raises(ValueError, match=r"^scenario 'x': (seconds|control_rate|setpoint coordinate) must be a "
                                             r"finite real number"):
            scenario_from_mapping("x", {"wind": "calm", field: bad})
    with pytest.raises(ValueError, match=r"^--duration must be a finite real number in \(0, 1e\+09\] s, got 'a'"):
        adhoc_scenario("calm", "a")
    with pytest.raises(ValueError, match=r"^unknown scenario 5; valid: "):
        get_scenario(5)
    for kw, text in (({"steps": True}, "--steps must be an integer in [1, 1000000000000], got True"),
                     ({"eval_seeds": -HUGE}, "--eval-seeds must be an integer in [1, 1000000], got a negative int of "
                                             "about 5001 digits")):
        with pytest.raises(ValueError) as err:
            TrainConfig(**kw)
        assert str(err.value) == text


def test_an_agent_override_beyond_the_int_to_str_limit_is_refused_by_the_grammar():
    """``px4(MPC_XY_P=0xfff...)``: a hex literal parses to an int without repr, which the agent's name needs."""
    from fawtgym.agents.spec import parse_agent

    text = f"px4(MPC_XY_P=0x{'f' * 5000})"
    with pytest.raises(ValueError, match=r"the value of MPC_XY_P is an int of about 6021 digits, beyond any option's "
                                         r"range$"):
        parse_agent(text)
    assert parse_agent("px4(MPC_XY_P=0xff)").name == "px4(MPC_XY_P=255)"


@pytest.mark.parametrize("key", [5, HUGE], ids=["int", "huge int"])
def test_unknown_option_names_of_any_type_are_listed_alike(key):
    """A non-str option name: sorting it among str names raised TypeError ('<' not supported), and a huge int one
    Python's 'Exceeds the limit'; gym.make and HoverBatchEnv now say the same line."""
    from fawtgym.core.checks import listed

    word = shown(key)
    for options, start in (({"sensors": {"base": "mocap_imu", key: 1, "zz": 2}},
                            f"unknown sensors field(s) ['zz', {word}]; valid: ['base', "),
                           ({"wind": {"name": "fawt-50", key: 1}}, f"unknown option(s) [{word}] for wind 'fawt-50'")):
        texts = set()
        for build in (lambda o=options: gym.make("fawtgym/Hover-v0", **o), lambda o=options: HoverBatchEnv(3, **o)):
            with pytest.raises(ValueError) as err:
                build()
            texts.add(str(err.value))
        assert len(texts) == 1 and texts.pop().startswith(start)
    assert listed({"b", "a"}) == repr(["a", "b"])


@pytest.mark.parametrize(("name", "ok"), [('x"y', True), ("a<b&c", True), ("s500 copy", True), (5, False), ("", False),
                                          ("n" * 201, False), (HUGE, False)],
                         ids=["quote", "xml", "space", "int", "empty", "long", "huge int"])
def test_vehicle_name_is_a_str_and_any_str_builds(name, ok):
    """A name with a quote broke the MJCF (MuJoCo's multi-line XML error); an int name was accepted."""
    from fawtgym.envs.hover_env import HoverEnv

    spec = {"base": "s500", "name": name}
    if ok:
        assert HoverEnv(vehicle=spec).reset(seed=0)[0].shape == (19,)
        return
    with pytest.raises(ValueError, match=r"^vehicle field 'name' must be a non-empty str of at most 200 characters, "
                                         r"got "):
        HoverEnv(vehicle=spec)


def test_arrays_and_unknown_px4_names_in_messages_stay_on_one_line():
    import numpy as np

    from fawtgym.agents.px4_params import PX4Params

    assert shown(np.zeros((3, 3))) == "array([[0., 0., 0.], [0., 0., 0.], [0., 0., 0.]])"
    with pytest.raises(ValueError, match=r"^unknown PX4 parameter an int of about 5001 digits; valid names: "):
        PX4Params.s500().set(HUGE, 1)
    with pytest.raises(ValueError, match=r"^external wrench must be .*, got array\(\[\[1., 1., 1.\], "
                                         r"\[1., 1., 1.\]\]\), \[0, 0, 0\]$"):
        HoverBatchEnv(3).set_external_wrench(np.ones((2, 3)), [0, 0, 0])


def test_scenario_names_and_train_config_keys_of_any_size():
    """A 5000-digit duty in a scenario name and a huge int name or randomize key raised Python's int-limit error."""
    from fawtgym.eval.scenarios import get_scenario, scenario_from_mapping
    from fawtgym.train.config import freeze

    for name in (f"fawt-{'9' * 5000}-steady", f"table4-{'9' * 5000}", "fawt-1000-steady"):
        with pytest.raises(ValueError, match=r"^unknown scenario "):
            get_scenario(name)
    assert get_scenario("fawt-45-steady").name == "fawt-45-steady"
    for bad in (HUGE, 5, ""):
        with pytest.raises(ValueError, match=r"^a scenario's name must be a non-empty str, got "):
            scenario_from_mapping("x", {"wind": "calm", "name": bad})
    assert freeze({HUGE: 1}) == (("an int of about 5001 digits", 1),) and freeze({"a": 1, 2: 3}) == (("2", 3), ("a", 1))
