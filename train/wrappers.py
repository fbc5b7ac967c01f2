"""Wrappers that make the hover env trainable: a normalized action, observer features, a residual action.

Each transformation is one batch-first *core* of :mod:`fawtgym.agents.policy_io` (a small class holding only
the law and its parameters) used three ways: by a gymnasium ``VectorWrapper`` over a batched env
(:class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv`, the training path), by a ``gymnasium.Wrapper``
over a single :class:`~fawtgym.envs.hover_env.HoverEnv` (the same core at N = 1: ``Single*``
classes), and by a deployed policy agent that must see exactly what the policy saw in training.

==================== ============================================= ==============================================
core                 law                                           wrappers
==================== ============================================= ==============================================
:class:`ActionScale` ``u`` in [-1, 1]^A -> env action, piecewise   :class:`NormalizedAction`,
                     linear per entry: -1 -> low, 0 -> the hover   :class:`SingleNormalizedAction`
                     command, +1 -> high (motors and ctbr)
:class:`EstimateFeatures` an observer on ``info["measurement"]`` and   :class:`ObserverFeatures`,
                     ``info["applied"]``; features force / (m g)    :class:`SingleObserverFeatures`
                     and torque / tau_max appended to the
                     observation
:class:`ResidualScale` ``clip(base + bound (high - low) / 2 u)``     :class:`ResidualAction`,
                     on a base agent's action                      :class:`SingleResidualAction`
==================== ============================================= ==============================================

Episode starts.  The vector wrappers follow the env's autoreset mode (``metadata["autoreset_mode"]``):
with ``same_step`` (what SB3 needs; :class:`fawtgym.train.vec_env.SB3VecEnv` requires it) the rows that
ended in a ``step`` come back already reset, so the observer and the base agent reset those rows from
the returned info in the same call; with ``next_step`` they reset the rows one step later, when the
env returns their reset info.  Terminal observations (``info["final_obs"]``) get the features of the
terminal step, computed on a copy of the observer (so the rows that go on are not advanced twice):
a same-step run gives exactly the observations of a next-step run.

Features (:class:`EstimateFeatures`): every observation carries the estimate of an observer updated
with that observation's info -- at an episode start the observer is reset from the reset info and then
updated with it, as :class:`~fawtgym.agents.px4_agent.PX4ObserverAgent` does (``reset`` then ``act``), with
the same inputs (:func:`~fawtgym.agents.base.applied_from_info`) and ``dt`` = the env's control period.
Scales, from the *nominal* vehicle preset: force ``phi_hat / (m g)`` (world NED), torque
``tau_hat / tau_max`` (body FRD) with ``tau_max = T_max sum_i max(B_ai, 0)`` per axis a, the largest torque the
rotors make about that axis (rotor thrusts in [0, T_max], B the quad-X allocation rows; s500: 3.02, 3.02,
0.32 N m); both clipped to +-:data:`FEATURE_CLIP`.  A channel the observer does not estimate is zero.

Randomized vehicles (:mod:`fawtgym.train.randomization`): the observer of :class:`ObserverFeatures` and the
base agent of :class:`ResidualAction` are built from the nominal preset; they do not know the draws.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv, VectorWrapper
from gymnasium.vector.utils import batch_space
from numpy.typing import ArrayLike, NDArray

from fawtgym.agents.policy_io import (
    FEATURE_CLIP,
    ActionScale,
    EstimateFeatures,
    ResidualScale,
    policy_actions,
)
from fawtgym.core.checks import shown


# ---- helpers shared by the vector wrappers ------------------------------------------------------------------------
def _autoreset_mode(env: VectorEnv) -> AutoresetMode:
    mode = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
    if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        raise ValueError(f"{type(env).__name__}: autoreset mode {mode} is not supported; use next_step or same_step "
                         "(HoverBatchEnv(..., autoreset_mode='same_step'))")
    return mode


def _shape(space: spaces.Space[Any]) -> tuple[int, ...]:
    """The shape of a Box action space (the wrappers' own [-1, 1] spaces)."""
    return _as_box(space, "the action space").shape


def _flag_clipped(info: Mapping[str, Any], clipped: Any) -> dict[str, Any]:
    """``info`` with ``action_clipped`` also set where the policy's action left [-1, 1] (the env sees it clipped)."""
    out = dict(info)
    out["action_clipped"] = np.logical_or(info["action_clipped"], clipped)
    if np.ndim(out["action_clipped"]) == 0:
        out["action_clipped"] = bool(out["action_clipped"])
    return out


def _hover_env(env: Any) -> Any:
    """The HoverBatchEnv / HoverEnv under ``env`` (its preset, dt, hover action, action bounds)."""
    base = env.unwrapped
    for attr in ("preset", "dt", "hover_action"):
        if not hasattr(base, attr):
            raise ValueError(f"{type(base).__name__} is not a fawtgym hover env (it has no {shown(attr)})")
    return base


def _terminal_info(info: Mapping[str, Any], mask: NDArray[np.bool_]) -> dict[str, Any]:
    """What an observer reads of the terminal step: ``final_info``'s measurement and applied inputs on the ended
    rows (``mask``), the returned info's elsewhere."""
    final = info["final_info"]
    out = {}
    for part in ("measurement", "applied"):
        cur, fin = info[part], final[part]
        out[part] = {k: np.where(mask.reshape((-1,) + (1,) * (np.ndim(v) - 1)), fin[k], v) for k, v in cur.items()}
    return out


class _EpisodeStarts:
    """Which rows of a vector env's returned info start a new episode (reset: all; same-step: the rows that ended
    in this step; next-step: the rows that ended in the previous step)."""

    def __init__(self, env: VectorEnv) -> None:
        self.same_step = _autoreset_mode(env) is AutoresetMode.SAME_STEP
        self.pending = np.zeros(env.num_envs, dtype=bool)

    def reset(self) -> None:
        self.pending[:] = False

    def step(self, terminated: NDArray[np.bool_], truncated: NDArray[np.bool_]) -> NDArray[np.bool_]:
        ended = np.logical_or(terminated, truncated)
        if self.same_step:
            return ended
        new, self.pending = self.pending, ended
        return new


def _concat_final_obs(info: dict[str, Any], features: NDArray[np.float32], mask: NDArray[np.bool_]) -> None:
    """Append ``features`` rows to the terminal observations of ``info["final_obs"]`` (rows of ``mask``), in place
    of a new object array."""
    final = np.array(info["final_obs"], dtype=object, copy=True)
    for i in np.flatnonzero(mask).tolist():  # ended rows only
        final[i] = np.concatenate([final[i], features[i]])
    info["final_obs"] = final


def _as_box(space: spaces.Space[Any], what: str) -> spaces.Box:
    """``space`` as a Box (the hover envs' spaces are Boxes); ValueError naming ``what`` for any other space."""
    if not isinstance(space, spaces.Box):
        raise ValueError(f"{what} must be a gymnasium Box, got {type(space).__name__}")
    return space


def _box_concat(a: spaces.Space[Any], b: spaces.Box) -> spaces.Box:
    a = _as_box(a, "the observation space")
    return spaces.Box(np.concatenate([a.low, b.low]).astype(np.float32),
                      np.concatenate([a.high, b.high]).astype(np.float32), dtype=np.float32)


# ---- vector wrappers ---------------------------------------------------------------------------------------------
class NormalizedAction(VectorWrapper):
    """Actions in [-1, 1]^A, 0 = the hover command (:class:`ActionScale`); motors or ctbr."""

    def __init__(self, env: VectorEnv) -> None:
        super().__init__(env)
        base = _hover_env(env)
        space = _as_box(env.single_action_space, "the action space")
        self.scale = ActionScale(space.low, space.high, base.hover_action()[0])
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=space.shape, dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, env.num_envs)

    def step(self, actions: ArrayLike) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        u, clipped = policy_actions(actions, _shape(self.action_space))
        obs, reward, terminated, truncated, info = self.env.step(self.scale(u))
        return obs, reward, terminated, truncated, _flag_clipped(info, clipped)


class ObserverFeatures(VectorWrapper):
    """Appends an observer's scaled force/torque estimates (:class:`EstimateFeatures`) to every observation.

    Default gains for a name: :func:`observer_kwargs_for` (``ffts_eso``: the flight gains of Wang et al. 2024,
    Sec. 7.2).  Per-row reset of the observer on the rows that start an episode (module docstring).
    """

    def __init__(self, env: VectorEnv, observer: Any = "ffts_eso", observer_kwargs: Mapping[str, Any] | None = None,
                 clip: float = FEATURE_CLIP) -> None:
        super().__init__(env)
        base = _hover_env(env)
        self.features = EstimateFeatures(observer, base.preset, base.dt, observer_kwargs, clip)
        self._starts = _EpisodeStarts(env)
        self.single_observation_space = _box_concat(env.single_observation_space, self.features.space())
        self.observation_space = batch_space(self.single_observation_space, env.num_envs)

    def reset(self, *, seed: Any = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._starts.reset()
        self.features.reset(info)
        return np.concatenate([obs, self.features.update(info)], axis=1), info

    def step(self, actions: ArrayLike) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(actions)
        new = self._starts.step(terminated, truncated)
        if new.any():
            if self._starts.same_step:
                info = dict(info)
                _concat_final_obs(info, self.features.peek(_terminal_info(info, new)), new)
            self.features.reset(info, rows=new)
        return np.concatenate([obs, self.features.update(info)], axis=1), reward, terminated, truncated, info


class ResidualAction(VectorWrapper):
    """The policy's ``u`` in [-1, 1]^A corrects a base agent's action: :class:`ResidualScale` (``u = 0`` flies exactly
    the base agent).

    ``base``: an agent name of :mod:`fawtgym.agents.spec` (``px4``, ``px4+ffts_eso``, ...) built for the env (nominal
    vehicle), or an Agent; its action type must be the env's.  The base agent acts on every returned observation
    (reset rows first reset from the returned info), so its action for the next step is ready before the policy's.
    ``features=True`` appends the base agent's own observer estimates (:class:`EstimateFeatures` scales) to the
    observation: the same features as :class:`ObserverFeatures` with that observer, without running it twice.
    """

    def __init__(self, env: VectorEnv, base: Any = "px4+ffts_eso", bound: float = 0.1, features: bool = False,
                 clip: float = FEATURE_CLIP) -> None:
        super().__init__(env)
        hover = _hover_env(env)
        self.agent = _build_agent(base, hover)
        space = _as_box(env.single_action_space, "the action space")
        self.scale = ResidualScale(space.low, space.high, bound)
        self._starts = _EpisodeStarts(env)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=space.shape, dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, env.num_envs)
        self.features = _agent_features(self.agent, hover, clip) if features else None
        if self.features is not None:
            self.single_observation_space = _box_concat(env.single_observation_space, self.features.space())
            self.observation_space = batch_space(self.single_observation_space, env.num_envs)
        self.base_action: NDArray[np.float64] | None = None

    def _observe(self, obs: Any, info: Mapping[str, Any]) -> Any:
        self.base_action = np.asarray(self.agent.act(obs, info), dtype=float)
        if self.features is None:
            return obs
        return np.concatenate([obs, self.features.scale(*self.agent.raw_estimate)], axis=1)

    def reset(self, *, seed: Any = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._starts.reset()
        self.agent.reset(info)
        return self._observe(obs, info), info

    def step(self, actions: ArrayLike) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        if self.base_action is None:
            raise RuntimeError("call reset() before step()")
        u, clipped = policy_actions(actions, _shape(self.action_space))
        obs, reward, terminated, truncated, info = self.env.step(self.scale(self.base_action, u))
        info = _flag_clipped(info, clipped)
        new = self._starts.step(terminated, truncated)
        if new.any():
            if self.features is not None and self._starts.same_step:
                info = dict(info)
                _concat_final_obs(info, self.features.peek(_terminal_info(info, new)), new)
            self.agent.reset(info, rows=new)
        return self._observe(obs, info), reward, terminated, truncated, info


def _build_agent(base: Any, env: Any) -> Any:
    """A base agent for ``env`` (name or Agent), checked to emit the env's action type."""
    from fawtgym.agents.base import Agent
    from fawtgym.agents.spec import make_agent

    agent = base if isinstance(base, Agent) else make_agent(base, env)
    if agent.action_type != env.action_type:
        raise ValueError(f"residual base {shown(base)} emits {shown(agent.action_type)} actions but the env takes "
                         f"{shown(env.action_type)}; build the env with action_type={shown(agent.action_type)}")
    return agent


def _agent_features(agent: Any, env: Any, clip: float) -> EstimateFeatures:
    """Features read from a PX4ObserverAgent's own observer (same inputs and step as the agent's update)."""
    observer = getattr(agent, "observer", None)
    if observer is None:
        raise ValueError(f"residual features need a base agent with an observer (px4+<observer>), got "
                         f"{type(agent).__name__}")
    core = EstimateFeatures(observer, env.preset, agent.dt, clip=clip)
    return core


# ---- single-env wrappers (the same cores at N = 1) -------------------------------------------------------------
class SingleNormalizedAction(gym.ActionWrapper):
    """:class:`NormalizedAction` for one :class:`~fawtgym.envs.hover_env.HoverEnv`."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        base = _hover_env(env)
        space = _as_box(env.action_space, "the action space")
        self.scale = ActionScale(space.low, space.high, base.hover_action())
        self.action_space = spaces.Box(-1.0, 1.0, shape=space.shape, dtype=np.float32)

    def action(self, action: ArrayLike) -> NDArray[np.float64]:
        return self.scale(policy_actions(action, _shape(self.action_space))[0][None])[0]

    def step(self, action: ArrayLike) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        u, clipped = policy_actions(action, _shape(self.action_space))
        obs, reward, terminated, truncated, info = self.env.step(self.scale(u[None])[0])
        return obs, reward, terminated, truncated, _flag_clipped(info, clipped)


class SingleObserverFeatures(gym.Wrapper):
    """:class:`ObserverFeatures` for one :class:`~fawtgym.envs.hover_env.HoverEnv`."""

    def __init__(self, env: gym.Env, observer: Any = "ffts_eso", observer_kwargs: Mapping[str, Any] | None = None,
                 clip: float = FEATURE_CLIP) -> None:
        super().__init__(env)
        base = _hover_env(env)
        self.features = EstimateFeatures(observer, base.preset, base.dt, observer_kwargs, clip)
        self.observation_space = _box_concat(env.observation_space, self.features.space())

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.features.reset(info)
        return np.concatenate([obs, self.features.update(info)[0]]), info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return np.concatenate([obs, self.features.update(info)[0]]), reward, terminated, truncated, info


class SingleResidualAction(gym.Wrapper):
    """:class:`ResidualAction` for one :class:`~fawtgym.envs.hover_env.HoverEnv` (``features`` as there)."""

    def __init__(self, env: gym.Env, base: Any = "px4+ffts_eso", bound: float = 0.1, features: bool = False,
                 clip: float = FEATURE_CLIP) -> None:
        super().__init__(env)
        hover = _hover_env(env)
        self.agent = _build_agent(base, hover)
        space = _as_box(env.action_space, "the action space")
        self.scale = ResidualScale(space.low, space.high, bound)
        self.action_space = spaces.Box(-1.0, 1.0, shape=space.shape, dtype=np.float32)
        self.features = _agent_features(self.agent, hover, clip) if features else None
        if self.features is not None:
            self.observation_space = _box_concat(env.observation_space, self.features.space())
        self.base_action: NDArray[np.float64] | None = None

    def _observe(self, obs: Any, info: Mapping[str, Any]) -> Any:
        self.base_action = np.asarray(self.agent.act(obs, info), dtype=float)
        if self.features is None:
            return obs
        return np.concatenate([obs, self.features.scale(*self.agent.raw_estimate)[0]])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.agent.reset(info)
        return self._observe(obs, info), info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        if self.base_action is None:
            raise RuntimeError("call reset() before step()")
        u, clipped = policy_actions(action, _shape(self.action_space))
        obs, reward, terminated, truncated, info = self.env.step(self.scale(self.base_action[None], u[None])[0])
        info = _flag_clipped(info, clipped)
        return self._observe(obs, info), reward, terminated, truncated, info
