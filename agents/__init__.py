"""Controllers that act in an env: PX4-style cascade (+ observer feedforward); the common agent API."""

from .base import Agent
from .px4_agent import PX4Agent, PX4ObserverAgent
from .px4_params import PX4Params

__all__ = ["Agent", "PX4Agent", "PX4ObserverAgent", "PX4Params"]
