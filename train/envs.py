"""The training env in one call: a scenario, an action mode, an observation mode, optional randomization.

:func:`make_train_env` builds, for ``num_envs`` rows::

    HoverBatchEnv(num_envs, **scenario.env_options(), autoreset_mode="same_step", randomizer=...)
      -> NormalizedAction                  (action "motors" / "ctbr": [-1, 1]^4, 0 = hover)
         or ResidualAction(base, bound)    (action "residual": the env flies motors, the policy adds a correction)
      -> ObserverFeatures(observer)        (obs "state+eso": 6 scaled force/torque estimates appended)
      -> SB3VecEnv                         (Stable-Baselines3's VecEnv API)

With ``action="residual"`` and ``obs="state+eso"`` whose observer (name and gains) is the base agent's own
(``px4+ffts_eso`` with ``ffts_eso``, the default), the features are read from the base agent's observer
instead of running a second copy (the same numbers, one observer update per step).

:func:`make_single_env` takes the same arguments and returns that stack at N = 1 as a ``gymnasium.Env``
(:class:`OneRowEnv`; ``HoverBatchEnv`` at N = 1 reproduces ``fawtgym/Hover-v0``), for gymnasium's and
SB3's env checkers and for code that wants one vehicle.  To wrap your own
:class:`~fawtgym.envs.hover_env.HoverEnv` (e.g. to render it), use the ``Single*`` wrappers of
:mod:`fawtgym.train.wrappers`.

One scenario per call (a built-in name, a ``.yaml``/``.json`` file holding one scenario, or a
:class:`~fawtgym.eval.scenarios.Scenario`); to train over FAWT duties, randomize the duty of one FAWT
scenario (``randomize={"duty": [0.3, 0.7]}``).  ``episode_seconds`` overrides the scenario's length.
Unknown names raise a one-line ValueError listing the valid ones.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from fawtgym.agents.policy_io import policy_actions
from fawtgym.core.checks import shown

#: the action modes: normalized collective thrust + body rates, normalized motors, a residual on a PX4 agent
ACTIONS = ("ctbr", "motors", "residual")
#: the observation modes: the env's state, or with an observer's scaled force/torque estimates
OBS_MODES = ("state", "state+eso")


def _scenario(scenario: Any) -> Any:
    from fawtgym.eval.scenarios import Scenario, resolve_scenarios

    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, (list, tuple)):
        if len(scenario) != 1:
            raise ValueError(f"make_train_env takes one scenario per call, got {len(scenario)}; to train over FAWT "
                             "duties randomize the duty of one FAWT scenario (randomize={'duty': [0.3, 0.7]})")
        return _scenario(scenario[0])
    if not isinstance(scenario, str):
        raise ValueError(f"scenario must be a scenario name, a .yaml/.json file or a Scenario, got "
                         f"{type(scenario).__name__}")
    found = resolve_scenarios([scenario])
    if len(found) != 1:
        raise ValueError(f"scenario file {shown(scenario)} holds {len(found)} scenarios; make_train_env takes one")
    return found[0]


def _check_choice(what: str, value: Any, valid: tuple[str, ...]) -> None:
    if value not in valid:
        raise ValueError(f"unknown {what} {shown(value)}; valid: {', '.join(valid)}")


def _check_observer(name: Any) -> None:
    import fawtgym.observers  # noqa: F401  (registers every observer)
    from fawtgym.observers.base import observer_names

    if not isinstance(name, str) or name not in observer_names():
        raise ValueError(f"unknown observer {shown(name)}; valid: {', '.join(observer_names())}")


def make_vector_env(scenario: Any = "table4-50", num_envs: int = 16, action: str = "ctbr", obs: str = "state",
                    observer: str = "ffts_eso", observer_kwargs: Mapping[str, Any] | None = None,
                    residual_base: str = "px4+ffts_eso", residual_bound: float = 0.1,
                    randomize: Mapping[str, Any] | None = None, episode_seconds: float | None = None) -> Any:
    """The gymnasium vector-env stack of :func:`make_train_env` (same-step autoreset), without the SB3 adapter."""
    from fawtgym.agents.policy_io import shares_observer
    from fawtgym.envs.hover_batch_env import HoverBatchEnv

    from .randomization import Randomization
    from .wrappers import NormalizedAction, ObserverFeatures, ResidualAction

    _check_choice("action", action, ACTIONS)
    _check_choice("obs", obs, OBS_MODES)
    if obs == "state+eso":
        _check_observer(observer)
    sc = _scenario(scenario)
    options = sc.env_options()
    if episode_seconds is not None:
        options["episode_seconds"] = episode_seconds
    config = Randomization.from_options(randomize)
    sampler = None if config is None else config.sampler(options["wind"])
    shared = False
    if action == "residual":
        from fawtgym.agents.spec import make_agent, parse_agent

        spec = parse_agent(residual_base)
        if spec.kind not in ("px4", "px4+observer"):
            raise ValueError(f"residual base must be px4 or px4+<observer>, got {shown(residual_base)}")
        shared = shares_observer(residual_base, obs, observer, observer_kwargs)
        options["action_type"] = "motors"  # the PX4 agents fly motor commands
    else:
        options["action_type"] = action
    env: Any = HoverBatchEnv(num_envs, **options, autoreset_mode="same_step", randomizer=sampler)
    if action == "residual":
        env = ResidualAction(env, make_agent(residual_base, env), bound=residual_bound, features=shared)
    else:
        env = NormalizedAction(env)
    if obs == "state+eso" and not shared:
        env = ObserverFeatures(env, observer, observer_kwargs)
    return env


def make_train_env(scenario: Any = "table4-50", num_envs: int = 16, action: str = "ctbr", obs: str = "state",
                   observer: str = "ffts_eso", observer_kwargs: Mapping[str, Any] | None = None,
                   residual_base: str = "px4+ffts_eso", residual_bound: float = 0.1,
                   randomize: Mapping[str, Any] | None = None, seed: int | None = 0,
                   episode_seconds: float | None = None) -> Any:
    """The SB3 training VecEnv (module docstring): :class:`~fawtgym.train.vec_env.SB3VecEnv` over the stack.

    Args:
        scenario: a built-in scenario name (``fawtgym.eval.scenarios.scenario_names()``), a ``.yaml``/``.json`` file
            with one scenario, or a Scenario.
        num_envs: rows (vehicles) stepped together.
        action: ``"ctbr"`` / ``"motors"`` (normalized to [-1, 1], 0 = hover) or ``"residual"`` (a correction of
            ``residual_bound`` times the half range on ``residual_base``'s motor commands).
        obs: ``"state"`` (the env's 19 numbers) or ``"state+eso"`` (+ 6 scaled estimates of ``observer``).
        observer, observer_kwargs: a registered observer and gain overrides (default gains as the agent grammar's).
        residual_base, residual_bound: the base agent (``px4`` or ``px4+<observer>``) and the bound of
            ``action="residual"``.
        randomize: domain randomization options (:mod:`fawtgym.train.randomization`), or None.
        seed: the seed of the first ``reset()`` (rows get seed, seed + 1, ...); None: unseeded.
        episode_seconds: episode length [s] instead of the scenario's.
    """
    from .vec_env import SB3VecEnv

    venv = SB3VecEnv(make_vector_env(scenario, num_envs, action, obs, observer, observer_kwargs, residual_base,
                                     residual_bound, randomize, episode_seconds))
    if seed is not None:
        venv.seed(seed)  # checked there
    return venv


def make_single_env(scenario: Any = "table4-50", action: str = "ctbr", obs: str = "state",
                    observer: str = "ffts_eso", observer_kwargs: Mapping[str, Any] | None = None,
                    residual_base: str = "px4+ffts_eso", residual_bound: float = 0.1,
                    randomize: Mapping[str, Any] | None = None, seed: int | None = 0,
                    episode_seconds: float | None = None) -> OneRowEnv:
    """:func:`make_train_env`'s stack at N = 1 as a ``gymnasium.Env`` (:class:`OneRowEnv`); ``seed`` seeds the first
    ``reset()`` that passes none."""
    env = make_vector_env(scenario, 1, action, obs, observer, observer_kwargs, residual_base, residual_bound,
                          randomize, episode_seconds)
    return OneRowEnv(env, seed=seed)


def _row(x: Any, i: int) -> Any:
    """Row ``i`` of a batched info (without gymnasium's ``_key`` masks and the autoreset's terminal entries)."""
    if isinstance(x, Mapping):
        return {k: _row(v, i) for k, v in x.items()
                if not (isinstance(k, str) and (k.startswith("_") or k in ("final_obs", "final_info")))}
    if isinstance(x, np.ndarray) and x.ndim >= 1:
        v = x[i]
        return v.item() if isinstance(v, np.generic) else v
    return x


class OneRowEnv(gym.Env):
    """A one-row same-step vector env seen as a ``gymnasium.Env`` (observation, reward, flags and info of row 0).

    After a step that ends the episode (the vector env has already started the next one), the terminal
    observation and info are returned, and the next ``reset()`` without seed or options returns the episode the
    vector env started (so the episodes are the vector row's); ``reset(seed=...)`` resets the vector env.
    """

    metadata = {"render_modes": []}

    def __init__(self, env: Any, seed: int | None = None) -> None:
        if env.num_envs != 1:
            raise ValueError(f"OneRowEnv needs a one-row vector env, got num_envs={env.num_envs}")
        self.env = env
        self.observation_space = env.single_observation_space
        self.action_space = env.single_action_space
        self._first_seed = seed
        self._next: tuple[Any, dict[str, Any]] | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is None and options is None and self._next is not None:
            obs, info = self._next
        else:
            if seed is None and self._first_seed is not None:
                seed, self._first_seed = self._first_seed, None
            obs, info = self.env.reset(seed=seed, options=options)
        self._next = None
        return obs[0], _row(info, 0)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self._next = None
        u, _ = policy_actions(action, tuple(self.action_space.shape or ()))  # the single env's shape in its message
        obs, reward, terminated, truncated, info = self.env.step(u[None])
        if terminated[0] or truncated[0]:
            self._next = (obs, info)
            obs, info = np.asarray([info["final_obs"][0]]), info["final_info"]
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), _row(info, 0)

    def close(self) -> None:
        self.env.close()
