"""What a training run is: its configuration, and the hyperparameters of each algorithm (one YAML per algorithm).

A :class:`TrainConfig` fixes everything that decides a run's result (env, observation, action, observer,
algorithm, hyperparameters, seed, step budget); its ``key()`` is stored in the run's metadata, so
``--resume`` refuses to continue a run with another configuration.  Hyperparameters come from
``train/hyperparams/<algo>.yaml`` (RL-Zoo keys) with ``key=value`` overrides; the keys that are not the
algorithm's constructor arguments are ours: ``n_envs`` (rows of the batched env), ``normalize``
(observation and reward normalization by ``VecNormalize``), ``action_noise`` / ``action_noise_std``
(TD3).
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fawtgym.core.checks import check_flag, check_int, check_number, listed, shown
from fawtgym.core.files import ParseError, load_data, parse_data
from fawtgym.eval.runner import MAX_SEEDS

ALGOS = ("ppo", "sac", "td3")
OBS_MODES = ("state", "state+eso")
ACTION_MODES = ("ctbr", "motors", "residual")
HYPERPARAMS_DIR = Path(__file__).parent / "hyperparams"
#: our keys in the hyperparameter files (not passed to the algorithm's constructor)
OWN_KEYS = ("policy", "n_envs", "normalize", "action_noise", "action_noise_std")


def load_hyperparams(algo: str, overrides: Sequence[str] | Mapping[str, Any] = ()) -> dict[str, Any]:
    """The algorithm's YAML hyperparameters with ``key=value`` overrides (values are YAML scalars/lists/mappings)."""
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {shown(algo)}; valid: {', '.join(ALGOS)}")
    hp = load_data(HYPERPARAMS_DIR / f"{algo}.yaml", "hyperparameter file")
    items = overrides.items() if isinstance(overrides, Mapping) else [_split(o) for o in overrides]
    for key, value in items:
        if isinstance(value, str):
            try:  # a key given twice or a huge int is refused
                value = parse_data(value, f"--hp {key}")
            except ParseError:  # text that is no YAML stays a str (a policy name)
                pass
            if isinstance(value, str):  # YAML 1.1 reads 1e-4 (no dot) as a string
                try:
                    value = float(value)
                except ValueError:
                    pass
        if key.startswith("policy_kwargs."):
            hp.setdefault("policy_kwargs", {})[key.split(".", 1)[1]] = value
        else:
            hp[key] = value
    _check_hyperparams(algo, hp)
    return hp


def _split(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ValueError(f"--hp takes key=value (e.g. learning_rate=1e-4), got {shown(text)}")
    return key.strip(), value.strip()


def _check_hyperparams(algo: str, hp: Mapping[str, Any]) -> None:
    import inspect

    cls = algo_class(algo)
    ours = {"self", "env", "policy", "_init_setup_model", "device", "seed", "verbose", "tensorboard_log"}
    valid = (set(inspect.signature(cls.__init__).parameters) - ours) | set(OWN_KEYS)
    unknown = set(hp) - valid
    if unknown:
        raise ValueError(f"unknown {algo} hyperparameter(s) {listed(unknown)}; valid: {', '.join(sorted(valid))}")
    freq = hp.get("train_freq")
    if isinstance(freq, (list, tuple)):  # SB3's (n, unit) form
        if len(freq) != 2 or freq[1] not in ("step", "episode"):
            raise ValueError(f"{algo} hyperparameter train_freq must be an int or [n, 'step' | 'episode'], got "
                             f"{shown(freq)}")
        check_int(freq[0], f"{algo} hyperparameter train_freq's n", *HP_INTS["train_freq"])
    for key, (count_low, count_high) in HP_INTS.items():
        if key in hp and not (key == "train_freq" and isinstance(hp[key], (list, tuple))):
            check_int(hp[key], f"{algo} hyperparameter {key}", count_low, count_high)
    for key, (low, high, closed_low) in HP_REALS.items():
        if key in hp and hp[key] is not None and not (key == "ent_coef" and algo == "sac"
                                                        and isinstance(hp[key], str)):
            check_number(hp[key], f"{algo} hyperparameter {key}", minimum=low, maximum=high,
                         inclusive_minimum=closed_low)
    if algo == "sac" and isinstance(hp.get("ent_coef"), str):
        coef = hp["ent_coef"]
        if coef != "auto" and not (coef.startswith("auto_") and _positive_text(coef[5:])):
            raise ValueError(f"sac hyperparameter ent_coef must be a number >= 0, 'auto' or 'auto_<initial value > 0>'"
                             f", got {shown(coef)}")
    if "normalize" in hp:
        check_flag(hp["normalize"], f"{algo} hyperparameter normalize")
    if algo == "ppo" and hp.get("normalize_advantage", True):  # SB3 normalizes it over a minibatch: 2 at least
        if hp.get("batch_size", 64) < 2:
            raise ValueError(f"ppo hyperparameter batch_size must be at least 2 with normalize_advantage (the "
                             f"advantage is normalized over a minibatch), got {shown(hp['batch_size'])}")
        if hp.get("n_steps", 2048) * hp.get("n_envs", 1) < 2:
            raise ValueError("ppo's rollout (n_steps * n_envs) must hold at least 2 steps with normalize_advantage, "
                             f"got {hp.get('n_steps', 2048)} * {hp.get('n_envs', 1)}")
    kwargs = hp.get("policy_kwargs", {})
    if not isinstance(kwargs, Mapping):
        raise ValueError(f"{algo} hyperparameter policy_kwargs must be a mapping, got {shown(kwargs)}")
    arch = kwargs.get("net_arch")  # None: the algorithm's default; []: no hidden layer (a linear policy)
    layers = arch.values() if isinstance(arch, Mapping) else [] if arch is None else [arch]
    for sizes in layers:
        if not isinstance(sizes, (list, tuple)):
            raise ValueError(f"policy_kwargs net_arch must be a list of layer widths (or a mapping of such lists: "
                             f"pi, vf, qf), got {shown(arch)}")
        for width in sizes:
            check_int(width, "policy_kwargs net_arch layer width", 1, 65536)
    if "log_std_init" in kwargs:
        check_number(kwargs["log_std_init"], "policy_kwargs log_std_init", minimum=-20.0, maximum=20.0,
                     inclusive_minimum=True)


#: integer hyperparameters and their ranges ([low, high]; ``gradient_steps`` -1: as many as env steps, SB3's meaning)
HP_INTS = {"n_envs": (1, 4096), "n_steps": (1, 10**7), "batch_size": (1, 10**7), "n_epochs": (1, 10**4),
           "buffer_size": (1, 10**9), "learning_starts": (0, 10**12), "train_freq": (1, 10**6),
           "gradient_steps": (-1, 10**4), "policy_delay": (1, 10**4)}
#: real hyperparameters and their ranges (low, high, low included?); None is left to the algorithm (its default)
HP_REALS = {"learning_rate": (0.0, 10.0, False), "gamma": (0.0, 1.0, True), "gae_lambda": (0.0, 1.0, True),
            "clip_range": (0.0, 10.0, False), "clip_range_vf": (0.0, 1e6, False), "ent_coef": (0.0, 1e3, True),
            "vf_coef": (0.0, 1e3, True), "max_grad_norm": (0.0, 1e9, False), "target_kl": (0.0, 1e3, False),
            "tau": (0.0, 1.0, False), "action_noise_std": (0.0, 10.0, True), "target_policy_noise": (0.0, 10.0, True),
            "target_noise_clip": (0.0, 10.0, True)}


def _positive_text(text: str) -> bool:
    try:
        return float(text) > 0.0
    except ValueError:
        return False


def algo_class(algo: str) -> Any:
    """The Stable-Baselines3 class of ``algo``."""
    import stable_baselines3 as sb3

    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {shown(algo)}; valid: {', '.join(ALGOS)}")
    return {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3}[algo]


#: the largest training budget [env steps] (10**12: years of a 2-core machine)
MAX_TRAIN_STEPS = 10**12


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Everything that decides a run (module docstring)."""

    algo: str = "ppo"
    obs: str = "state+eso"
    action: str = "ctbr"
    observer: str = "ffts_eso"
    observer_kwargs: tuple[tuple[str, Any], ...] = ()
    scenario: str = "table4-50"
    episode_seconds: float | None = 20.0
    randomize: tuple[tuple[str, Any], ...] = ()
    residual_base: str = "px4+ffts_eso"
    residual_bound: float = 0.1
    steps: int = 200_000
    seed: int = 0
    hyperparams: tuple[tuple[str, Any], ...] = ()
    eval_scenarios: tuple[str, ...] = ("table4-50",)
    eval_seeds: int = 2

    def __post_init__(self) -> None:
        for name, value, valid in (("algo", self.algo, ALGOS), ("obs", self.obs, OBS_MODES),
                                   ("action", self.action, ACTION_MODES)):
            if value not in valid:
                raise ValueError(f"unknown --{name} {shown(value)}; valid: {', '.join(valid)}")
        for flag, count, low, high in (("steps", self.steps, 1, MAX_TRAIN_STEPS), ("seed", self.seed, 0, 2**32 - 1),
                                       ("eval-seeds", self.eval_seeds, 1, MAX_SEEDS)):
            if isinstance(count, bool) or not isinstance(count, int) or not low <= count <= high:
                raise ValueError(f"--{flag} must be an integer in [{low}, {high}], got {shown(count)}")

    @property
    def hp(self) -> dict[str, Any]:
        return _thaw(dict(self.hyperparams))

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        for k in ("observer_kwargs", "randomize", "hyperparams"):
            d[k] = _thaw(dict(getattr(self, k)))
        d["eval_scenarios"] = list(self.eval_scenarios)
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> TrainConfig:
        d = dict(d)
        for k in ("observer_kwargs", "randomize", "hyperparams"):
            d[k] = freeze(d.get(k) or {})
        d["eval_scenarios"] = tuple(d.get("eval_scenarios", ()))
        return cls(**d)

    def key(self) -> str:
        """A hash of everything but the step budget (a resumed run may train longer)."""
        d = self.to_dict()
        d.pop("steps")
        return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]

    def env_kwargs(self) -> dict[str, Any]:
        """Arguments of :func:`fawtgym.train.envs.make_train_env` (without ``num_envs`` and ``seed``)."""
        return {"scenario": self.scenario, "action": self.action, "obs": self.obs, "observer": self.observer,
                "observer_kwargs": dict(self.observer_kwargs) or None, "residual_base": self.residual_base,
                "residual_bound": self.residual_bound, "randomize": _thaw(dict(self.randomize)) or None,
                "episode_seconds": self.episode_seconds}


def freeze(x: Any) -> Any:
    """Mappings and lists as sorted tuples (hashable, for the frozen config)."""
    if isinstance(x, Mapping):
        return tuple(sorted((k if isinstance(k, str) else shown(k), freeze(v)) for k, v in x.items()))
    if isinstance(x, list):
        return ("__list__", *[freeze(v) for v in x])
    return x


def _thaw(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _thaw(v) for k, v in x.items()}
    if isinstance(x, tuple):
        if x and x[0] == "__list__":
            return [_thaw(v) for v in x[1:]]
        if all(isinstance(p, tuple) and len(p) == 2 and isinstance(p[0], str) for p in x):
            return {k: _thaw(v) for k, v in x}
        return [_thaw(v) for v in x]
    return x


def parse_literal(text: str) -> Any:
    """A command-line value as a Python literal when it reads as one, else the string."""
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text
