"""A user's own agent, registered through the agent grammar as ``_plugin_agent:HoverHold`` (a test plugin).

It holds the hover command and ignores everything: the simplest ``Agent`` subclass a user could write.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.agents import Agent
from fawtgym.agents.base import match_batch, measurement_from_info


class HoverHold(Agent):
    """Sends ``level`` (default: the env's hover command) to every motor."""

    def __init__(self, level: float) -> None:
        self.level = float(level)

    @classmethod
    def for_env(cls, env: Any, **kwargs: Any) -> HoverHold:
        kwargs.setdefault("level", float(env.hover_action()[0][0]))
        return cls(**kwargs)

    def reset(self, info: Mapping[str, Any], seed: int | None = None, rows: ArrayLike | None = None) -> None:
        pass

    def act(self, observation: Any, info: Mapping[str, Any]) -> NDArray[np.float64]:
        meas, batched = measurement_from_info(info)
        return match_batch(np.full((meas["position"].shape[0], 4), self.level), batched)


class NotAnAgent:
    pass
