"""An unknown option name of a wind or an observer is refused with one line listing the valid ones (it was Python's
"takes no arguments" / "unexpected keyword argument" TypeError, which gym.make re-wrapped)."""

from __future__ import annotations

import gymnasium as gym
import pytest

import fawtgym  # noqa: F401  (registers the env)
from fawtgym.agents.px4_agent import PX4ObserverAgent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.wind import make_wind
from fawtgym.observers import make_observer, observer_names
from fawtgym.observers.base import observer_options


@pytest.mark.parametrize("build", [lambda w: make_wind(w), lambda w: HoverEnv(wind=w),
                                   lambda w: HoverBatchEnv(3, wind=w), lambda w: gym.make("fawtgym/Hover-v0", wind=w)],
                         ids=["make_wind", "HoverEnv", "HoverBatchEnv", "gym.make"])
def test_calm_wind_takes_no_options(build):
    with pytest.raises(ValueError, match=r"^unknown option\(s\) \['foo'\] for wind 'calm'; valid options: none$"):
        build({"name": "calm", "foo": 1})
    assert type(make_wind({"name": "calm"})).__name__ == "CalmWind"


@pytest.mark.filterwarnings("ignore:QB gain")  # qb's stored gain was designed for another vehicle: it says so
@pytest.mark.parametrize("name", observer_names())
def test_unknown_observer_option_lists_the_valid_ones(name):
    options = observer_options(name)
    assert options is not None and "gravity" in options
    with pytest.raises(ValueError) as err:
        make_observer(name, 1.2, [0.01, 0.01, 0.02], not_an_option=1)
    assert str(err.value) == (f"unknown option(s) ['not_an_option'] for observer '{name}'; valid options: "
                              f"{', '.join(options)}")
    make_observer(name, 1.2, [0.01, 0.01, 0.02], gravity=9.81)  # a valid option still builds


def test_agent_observer_kwargs_are_checked_alike():
    with pytest.raises(ValueError, match=r"^unknown option\(s\) \['foo'\] for observer 'ffts_eso'; valid options: "):
        PX4ObserverAgent.for_env(HoverBatchEnv(1), observer="ffts_eso", observer_kwargs={"foo": 1})


def test_agent_setpoint_of_another_row_count_is_refused_in_one_line():
    """set_setpoint with (2, 3) for 3 vehicles raised numpy's broadcast error."""
    import numpy as np

    from fawtgym.agents.px4_agent import PX4Agent

    env = HoverBatchEnv(3)
    agent = PX4Agent.for_env(env)
    _, info = env.reset(seed=0)
    agent.reset(info)
    with pytest.raises(ValueError, match=r"^setpoint must be of shape \(3,\), \(1, 3\) or \(3, 3\) \(the 3 "
                                         r"vehicle\(s\) this agent flies\), got shape \(2, 3\)$"):
        agent.set_setpoint(np.full((2, 3), -1.0))
    agent.set_setpoint(np.full((3, 3), -1.0))
    agent.set_setpoint([0.0, 0.0, -1.0])


@pytest.mark.parametrize("build,owner", [
    (lambda **k: HoverEnv(**k), "HoverEnv"),
    (lambda **k: HoverBatchEnv(2, **k), "HoverBatchEnv"),
    (lambda **k: gym.make("fawtgym/Hover-v0", **k), "HoverEnv"),
    (lambda **k: gym.make_vec("fawtgym/Hover-v0", num_envs=2, vectorization_mode="vector_entry_point", **k),
     "HoverBatchEnv"),
], ids=["HoverEnv", "HoverBatchEnv", "gym.make", "gym.make_vec"])
@pytest.mark.parametrize("value", [1, 10**5000], ids=["int", "huge int"])
def test_unknown_env_option_is_one_line_at_every_entry_point(build, owner, value):
    """Python's "unexpected keyword argument" TypeError was re-raised by gym.make with the repr of every keyword
    argument appended (Python's int-to-str error for a huge int, several lines for an array)."""
    with pytest.raises(ValueError) as err:
        build(bogus=value)
    text = str(err.value)
    assert text.startswith(f"unknown option(s) ['bogus'] for {owner}; valid options: "), text
    assert "vehicle, wind, action_type" in text, text
    assert "\n" not in text and "control_rate" in text and ("physics_threads" in text) == (owner == "HoverBatchEnv")


def test_a_wind_mapping_without_a_name_says_so():
    """It said "unknown wind None"."""
    with pytest.raises(ValueError, match=r"^a wind mapping needs its 'name' \(one of \['calm', .*\{'on_time': 1\}$"):
        make_wind({"on_time": 1})
    with pytest.raises(ValueError, match=r"^a wind mapping needs its 'name'"):
        HoverBatchEnv(3, wind={"on_time": 1})
