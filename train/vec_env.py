"""``SB3VecEnv``: a Stable-Baselines3 ``VecEnv`` over a same-step gymnasium vector env (a batched hover env).

Stable-Baselines3 steps a ``VecEnv`` and expects what its ``DummyVecEnv`` gives: rows that end are reset
inside the same ``step`` (no reward-0 step), ``dones = terminated | truncated``, float32 rewards, and one
info dict per row with ``infos[i]["terminal_observation"]`` (the ended row's last observation, for
bootstrapping a truncated episode) and ``infos[i]["TimeLimit.truncated"]`` on the rows that ended.  This
adapter gives exactly that over a gymnasium ``VectorEnv`` in ``AutoresetMode.SAME_STEP`` -- a
:class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv` built with ``autoreset_mode="same_step"`` or any
vector wrapper stack over one (:mod:`fawtgym.train.wrappers`) -- with no loop over rows in the step path
except the per-row info dicts SB3 needs: an empty dict per row (VecMonitor writes its ``"episode"``
into them) and, on the rows that ended, ``terminal_observation``, ``TimeLimit.truncated`` and
``failure`` (the env's failure string, ``""`` on truncation).  The batched info of the last step or reset
is kept in :attr:`SB3VecEnv.last_info`.

Seeding and options follow SB3's conventions: :meth:`seed` (or the algorithm's ``seed=``) and
:meth:`set_options` apply at the next :meth:`reset` only; per-row seeds ``[s, s + 1, ...]`` reach the
env as a list (``HoverBatchEnv.reset(seed=s)`` gives row i seed s + i, so both are the same); per-row
option dicts are merged into the env's batch options (equal dicts pass as they are; a key given for
every row with different values is stacked, e.g. per-row ``setpoint`` (N, 3)).

Batch semantics of the VecEnv attribute API: the rows are one env, so :meth:`get_attr`,
:meth:`set_attr` and :meth:`env_method` act once on the first layer of the wrapper stack that has the
attribute (outermost first, down to the base env) and return that one value repeated for each index
asked for; ``indices`` only shape the returned list (a method that acts on rows, such as
``set_external_wrench``, takes per-row arrays itself).  :meth:`env_is_wrapped` tells whether any layer of
the stack is an instance of the class.

Works under ``VecNormalize`` (which normalizes ``terminal_observation`` too) and ``VecMonitor``; PPO, SAC and
TD3 accept it (continuous Box actions).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from numpy.typing import NDArray
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from fawtgym.core.checks import check_int, shown


def _layers(env: Any) -> Iterator[Any]:
    """The wrapper stack of a gymnasium vector env, outermost first, down to the base env."""
    while True:
        yield env
        inner = getattr(env, "env", None)
        if inner is None or inner is env:
            return
        env = inner


class SB3VecEnv(VecEnv):
    """SB3 ``VecEnv`` over a same-step gymnasium ``VectorEnv`` (module docstring)."""

    def __init__(self, env: VectorEnv) -> None:
        if not isinstance(env, VectorEnv):
            raise TypeError(f"SB3VecEnv wraps a gymnasium VectorEnv (e.g. HoverBatchEnv), got {type(env).__name__}")
        mode = env.metadata.get("autoreset_mode")
        if mode is not AutoresetMode.SAME_STEP:
            raise ValueError(f"SB3VecEnv needs a vector env with same-step autoreset (SB3 resets rows inside step); "
                             f"this one has {mode}: build it with HoverBatchEnv(..., autoreset_mode='same_step')")
        self.env = env
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
        self.last_info: dict[str, Any] = {}
        self._actions: NDArray[Any] | None = None

    # ---- stepping ------------------------------------------------------------------------------------------
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """SB3's seeding (row ``i`` gets ``seed + i`` at the next reset), the seed checked first: an int in
        [0, 2**32 - N] or None (a random one)."""
        if seed is not None:
            check_int(seed, "seed", 0, 2**32 - self.num_envs)
        return super().seed(None if seed is None else int(seed))

    def reset(self) -> VecEnvObs:
        seeds = self._seeds
        seed: Any = None if all(s is None for s in seeds) else list(seeds)
        options = _merge_options(self._options, self.num_envs)
        obs, info = self.env.reset(seed=seed, options=options or None)
        self._reset_seeds()
        self._reset_options()
        self.last_info = info
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async(actions) before it")
        actions, self._actions = self._actions, None
        obs, reward, terminated, truncated, info = self.env.step(actions)
        self.last_info = info
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if dones.any():
            final_obs = info["final_obs"]
            failure = info.get("final_info", {}).get("failure")
            for i in np.flatnonzero(dones).tolist():  # ended rows only
                infos[i] = {"terminal_observation": final_obs[i],
                            "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
                            "failure": "" if failure is None else str(failure[i])}
        return obs, reward.astype(np.float32), dones, infos

    def close(self) -> None:
        self.env.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs  # the batched env does not render (render a single fawtgym/Hover-v0)

    # ---- attribute API (one env: act once, answer per index; module docstring) -------------------------------
    def _count(self, indices: VecEnvIndices) -> int:
        return len(list(self._get_indices(indices)))

    def _owner(self, name: str) -> Any:
        for layer in _layers(self.env):
            if hasattr(layer, name):
                return layer
        raise AttributeError(f"no layer of {self.env} has an attribute {shown(name)}")

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self._owner(attr_name), attr_name)
        return [value] * self._count(indices)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        try:
            owner = self._owner(attr_name)
        except AttributeError:
            owner = self.env.unwrapped
        setattr(owner, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        result = getattr(self._owner(method_name), method_name)(*method_args, **method_kwargs)
        return [result] * self._count(indices)

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        wrapped = any(isinstance(layer, wrapper_class) for layer in _layers(self.env))
        return [wrapped] * self._count(indices)


def _merge_options(options: Sequence[dict[str, Any]], n: int) -> dict[str, Any]:
    """SB3's per-row option dicts as the batch env's one options dict (module docstring)."""
    if all(_equal(o, options[0]) for o in options):
        return dict(options[0])
    merged: dict[str, Any] = {}
    for key in sorted({k for o in options for k in o}):
        if not all(key in o for o in options):
            raise ValueError(f"reset option {shown(key)} is set for some rows only; the batched env takes each "
                             f"option for all {n} rows (one value, or one per row)")
        merged[key] = np.stack([np.asarray(o[key]) for o in options])
    return merged


def _equal(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(np.asarray(a[k]), np.asarray(b[k])) for k in a)
