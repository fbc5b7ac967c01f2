"""Agents' bad input: one-line ValueErrors naming the bad value and what is allowed, the same text at every N,
and a refused call changes nothing (audit of issue 14: D4, D9-agent)."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.agents.px4_agent import PX4ObserverAgent
from fawtgym.agents.spec import make_agent
from fawtgym.envs.hover_batch_env import HoverBatchEnv

FLAGS = ("force_ff", "torque_ff")
STAND_INS = [("False", "'False' (str)"), ("True", "'True' (str)"), (-1, "-1 (int)"), (0, "0 (int)"), (1, "1 (int)"),
             (1.0, "1.0 (float)"), (None, "None (NoneType)"), ("no", "'no' (str)")]


# ---- D4: Boolean options are booleans ---------------------------------------------------------------------------
@pytest.mark.parametrize("flag", FLAGS)
@pytest.mark.parametrize("value, shown", STAND_INS)
def test_observer_agent_refuses_truthy_stand_ins(flag: str, value: object, shown: str) -> None:
    with pytest.raises(ValueError) as exc:
        PX4ObserverAgent(observer="leso", **{flag: value})
    assert str(exc.value) == f"{flag} must be True or False, got {shown}"


@pytest.mark.parametrize("flag", FLAGS)
@pytest.mark.parametrize("value", [True, False, np.bool_(True), np.bool_(False)])
def test_observer_agent_takes_python_and_numpy_booleans(flag: str, value: object) -> None:
    agent = PX4ObserverAgent(observer="ffts_eso", **{flag: value})
    assert getattr(agent, flag) is bool(value)


def test_a_channel_the_observer_lacks_is_never_fed_forward() -> None:
    from fawtgym.observers.base import observer_class

    name = next(n for n in ("leso", "geso", "ffts_eso") if "force" in observer_class(n).channels)
    agent = PX4ObserverAgent(observer=name, force_ff=True, torque_ff=False)
    assert agent.force_ff is True and agent.torque_ff is False


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("flag", FLAGS)
def test_agent_spec_refuses_a_string_flag(n: int, flag: str) -> None:
    env = HoverBatchEnv(n)
    spec = f"px4+ffts_eso({flag}='False')"
    with pytest.raises(ValueError) as exc:
        make_agent(spec, env)
    assert str(exc.value) == f"agent {spec!r}: {flag} must be True or False, got 'False' (str)"
    assert getattr(make_agent(f"px4+ffts_eso({flag}=False)", env), flag) is False
