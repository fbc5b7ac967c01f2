"""A trained Stable-Baselines3 policy as an agent: ``sb3:runs/NAME`` in the agent grammar.

The agent loads a run folder of ``fawtgym train`` (its final ``model.zip``; an unfinished run's newest
checkpoint) or one checkpoint folder (``runs/NAME/checkpoints/000050000``), and flies exactly what the
policy saw and did in training, with the same cores (:mod:`fawtgym.agents.policy_io`):

* observation: the env's observation, plus for ``--obs state+eso`` the observer's scaled estimates
  (:class:`~fawtgym.agents.policy_io.EstimateFeatures`; for a residual policy whose base agent runs that
  observer, the base agent's own estimates), normalized with the run's ``VecNormalize`` statistics;
* action: the deterministic policy output through :class:`~fawtgym.agents.policy_io.ActionScale`
  (``ctbr``/``motors``) or :class:`~fawtgym.agents.policy_io.ResidualScale` on the base agent's action.

Its action type (``ctbr`` or ``motors``) is the run's; the evaluation runner builds the env accordingly
(:func:`fawtgym.agents.spec.agent_action_type`).  The observer and base agent use the env's (nominal)
vehicle; a run trained on another vehicle or control rate flies, with a warning in its name only if the
caller checks :attr:`SB3Agent.trained_on`.
"""

from __future__ import annotations

import json
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown

from .base import Agent, match_batch, measurement_from_info
from .policy_io import ActionScale, EstimateFeatures, ResidualScale, shares_observer


def locate_run(path: str | Path) -> tuple[Path, dict[str, Any]]:
    """(folder holding model.zip, the run's metadata) for a run or checkpoint folder; ValueError otherwise."""
    p = Path(path)
    try:
        folder_exists = p.is_dir()
    except OSError as exc:  # e.g. a name longer than the file system takes
        raise ValueError(f"sb3 agent: {shown(str(p))} is not a folder of 'fawtgym train' ({exc.strerror})") from None
    if not folder_exists:
        raise ValueError(f"sb3 agent: {shown(str(p))} is not a folder of 'fawtgym train' (a run or a checkpoint)")
    meta_path = next((q / "metadata.json" for q in (p, p.parent, p.parent.parent) if (q / "metadata.json").is_file()),
                     None)
    if meta_path is None:
        raise ValueError(f"sb3 agent: no metadata.json in {str(p)!r} or its run folder; is it a 'fawtgym train' run?")
    folder = p
    if not (p / "model.zip").is_file():
        ckpts = sorted(q for q in (p / "checkpoints").glob("[0-9]*") if (q / "model.zip").is_file()) \
            if (p / "checkpoints").is_dir() else []
        if not ckpts:
            raise ValueError(f"sb3 agent: {str(p)!r} has no model.zip and no checkpoint yet")
        folder = ckpts[-1]
    try:
        meta = json.loads(meta_path.read_text())
        meta["config"]["action"]
    except (OSError, json.JSONDecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"sb3 agent: {meta_path} is not a readable run metadata file ({exc})") from exc
    return folder, meta


def run_action_type(path: str | Path) -> str:
    """The env action type a run's policy flies (``ctbr`` or ``motors``)."""
    _, meta = locate_run(path)
    return "ctbr" if meta["config"]["action"] == "ctbr" else "motors"


def run_scenario(path: str | Path) -> Any:
    """The :class:`~fawtgym.eval.scenarios.Scenario` a run was trained on (its metadata's ``config.scenario``): its
    vehicle preset and control rate are the policy's."""
    _, meta = locate_run(path)
    from fawtgym.eval.scenarios import resolve_scenarios

    try:
        return resolve_scenarios([meta["config"]["scenario"]])[0]
    except (KeyError, ValueError, OSError) as exc:
        raise ValueError(f"sb3 agent: {str(path)!r}: cannot read its training scenario ({exc})") from exc


class SB3Agent(Agent):
    """A trained policy (module docstring); build with :meth:`for_env`."""

    def __init__(self, path: str | Path, env: Any) -> None:
        from fawtgym.train.config import algo_class

        self.folder, self.meta = locate_run(path)
        cfg = self.meta["config"]
        self.config = cfg
        self.action_type = "ctbr" if cfg["action"] == "ctbr" else "motors"
        base_env = getattr(env, "unwrapped", env)
        if getattr(base_env, "action_type", self.action_type) != self.action_type:
            raise ValueError(f"sb3 agent {str(path)!r} flies {shown(self.action_type)} actions; the env takes "
                             f"{shown(base_env.action_type)} (build it with action_type={shown(self.action_type)})")
        try:
            self.model = algo_class(cfg["algo"]).load(self.folder / "model.zip", device="cpu")
        except Exception as exc:  # a truncated or foreign zip
            raise ValueError(f"sb3 agent: cannot load {self.folder / 'model.zip'} ({type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else ''})") from exc
        self.normalizer = None
        if (self.folder / "vecnormalize.pkl").is_file():
            with open(self.folder / "vecnormalize.pkl", "rb") as fh:
                self.normalizer = pickle.load(fh)
        self.trained_on = {"scenario": cfg.get("scenario"), "steps": self.meta.get("steps_done")}
        space = base_env.single_action_space if hasattr(base_env, "single_action_space") else base_env.action_space
        hover = np.asarray(base_env.hover_action(), dtype=float).reshape(-1, space.shape[0])[0]
        self.base: Any = None  # the residual base agent (a PX4 agent, possibly with an observer)
        self.features = None
        self.shared = False
        if cfg["action"] == "residual":
            from .spec import make_agent

            self.base = make_agent(cfg["residual_base"], env)
            self.residual = ResidualScale(space.low, space.high, cfg["residual_bound"])
        else:
            self.scale = ActionScale(space.low, space.high, hover)
        if cfg["obs"] == "state+eso":
            obs_kwargs = dict(cfg.get("observer_kwargs") or {})
            self.shared = self.base is not None and shares_observer(cfg["residual_base"], cfg["obs"], cfg["observer"],
                                                                    obs_kwargs)
            observer = self.base.observer if self.shared else cfg["observer"]
            self.features = EstimateFeatures(observer, base_env.preset, base_env.dt,
                                             None if self.shared else obs_kwargs)
        expected = self.model.observation_space.shape[0]
        got = base_env.single_observation_space.shape[0] if hasattr(base_env, "single_observation_space") \
            else base_env.observation_space.shape[0]
        got += 0 if self.features is None else self.features.space().shape[0]
        if got != expected:
            raise ValueError(f"sb3 agent {str(path)!r}: the policy takes {expected} observation entries, this env "
                             f"gives {got}")

    @classmethod
    def for_env(cls, env: Any, path: str | Path = "", **kwargs: Any) -> SB3Agent:
        if kwargs:
            raise ValueError(f"sb3 agents take no options, got {sorted(kwargs)}")
        return cls(path, env)

    def reset(self, info: Mapping[str, Any], seed: int | None = None, rows: ArrayLike | None = None) -> None:
        if self.base is not None:
            self.base.reset(info, seed, rows=rows)
        if self.features is not None and not self.shared:
            self.features.reset(info, rows=None if rows is None else np.asarray(rows))

    def act(self, observation: Any, info: Mapping[str, Any]) -> NDArray[np.float64]:
        _, batched = measurement_from_info(info)
        obs = np.asarray(observation, dtype=np.float32)
        obs = obs if obs.ndim == 2 else obs[None]
        base_action = None
        if self.base is not None:
            base_action = np.asarray(self.base.act(observation, info), dtype=float).reshape(obs.shape[0], -1)
        #: the residual base agent's command of the last call (None without a base): the replay reads it
        self.last_base_action = base_action
        if self.features is not None:
            feats = self.features.scale(*self.base.raw_estimate) if self.shared else self.features.update(info)
            obs = np.concatenate([obs, feats], axis=1)
        if self.normalizer is not None:
            obs = self.normalizer.normalize_obs(obs)
        u, _ = self.model.predict(obs, deterministic=True)
        action = self.residual(base_action, u) if base_action is not None else self.scale(u)
        return match_batch(np.asarray(action, dtype=float), batched)

    def disturbance_estimate(self) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        if self.base is not None:
            return self.base.disturbance_estimate()
        if self.features is not None and self.features.last is not None:
            ch = self.features.observer.channels
            force, tau = self.features.last
            return (force if "force" in ch else None), (tau if "torque" in ch else None)
        return None, None

    @property
    def observer(self) -> Any:
        """The observer whose estimates the policy sees (None for ``--obs state``)."""
        return None if self.features is None else self.features.observer
