"""Hyperparameters are checked before Stable-Baselines3 sees them (it asserted, divided by zero or trained on NaN)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fawtgym.train.config import TrainConfig, load_hyperparams
from fawtgym.train.run import train


@pytest.mark.parametrize("algo, override, match", [
    ("ppo", "n_steps=0", r"^ppo hyperparameter n_steps must be an int in \[1, 10000000\], got 0 \(int\)$"),
    ("ppo", "n_steps=1.5", r"n_steps must be an int .* got 1.5 \(float\)$"),
    ("ppo", "batch_size=1", r"batch_size must be at least 2"),
    ("ppo", "n_epochs=0", r"n_epochs must be an int in \[1, 10000\]"),
    ("ppo", "learning_rate=x", r"learning_rate must be a finite real number in \(0, 10\], got 'x' \(str\)$"),
    ("ppo", "clip_range=.nan", r"clip_range must be a finite real number in \(0, 10\], got nan"),  # trained on NaN
    ("ppo", "ent_coef=-1", r"ent_coef must be a finite real number in \[0, 1000\], got -1"),  # trained silently
    ("ppo", "gamma=2", r"gamma must be a finite real number in \[0, 1\], got 2"),
    ("ppo", "policy_kwargs=5", r"policy_kwargs must be a mapping, got 5$"),
    ("ppo", "policy_kwargs={'net_arch': 'x'}", r"net_arch must be a list of layer widths"),
    ("ppo", "policy_kwargs.net_arch=[64, 0]", r"layer width must be an int in \[1, 65536\], got 0"),
    ("ppo", "normalize=yes please", r"normalize must be True or False"),
    ("ppo", "learning_rate=" + "9" * 5000, r"^--hp learning_rate holds an integer of more than 4300 digits"),
    ("sac", "ent_coef=auto_x", r"ent_coef must be a number >= 0, 'auto' or 'auto_<initial value > 0>'"),
    ("sac", "buffer_size=0", r"buffer_size must be an int in \[1, 1000000000\]"),
    ("sac", "train_freq=[0, 'step']", r"train_freq's n must be an int in \[1, 1000000\], got 0"),
    ("sac", "train_freq=[1, 'bogus']", r"train_freq must be an int or \[n, 'step' \| 'episode'\]"),
    ("ppo", "policy_kwargs={a: 1, a: 2}", r"--hp policy_kwargs: key 'a' appears twice"),
    ("td3", "tau=0", r"tau must be a finite real number in \(0, 1\]"),
])
def test_bad_hyperparameter_is_one_line(algo: str, override: str, match: str) -> None:
    with pytest.raises(ValueError, match=match) as err:
        load_hyperparams(algo, [override])
    assert "\n" not in str(err.value) and len(str(err.value)) < 400


@pytest.mark.parametrize("algo, overrides", [
    ("ppo", []), ("sac", []), ("td3", []),
    ("sac", ["ent_coef=auto"]), ("sac", ["ent_coef=auto_0.1"]), ("sac", ["ent_coef=0.01"]),
    ("sac", ["gradient_steps=-1"]), ("sac", ["train_freq=[1, 'episode']"]),
    ("ppo", ["n_steps=64", "n_envs=1", "batch_size=64"]), ("ppo", ["target_kl=null"]),
    ("ppo", ["policy_kwargs={'net_arch': {'pi': [32], 'vf': [64, 64]}}"]),
    ("ppo", ["policy_kwargs.net_arch=[]"]), ("ppo", ["policy_kwargs.net_arch=null"]),  # linear; SB3's default
    ("ppo", ["normalize_advantage=false", "batch_size=1"]),  # no minibatch normalization: SB3 takes it
])
def test_valid_hyperparameters_pass(algo: str, overrides: list[str]) -> None:
    load_hyperparams(algo, overrides)


@pytest.mark.parametrize("every", [0, -1, 1.5])
def test_eval_every_is_checked_before_anything_is_written(tmp_path: Path, every: object) -> None:
    """0 divided by zero after the env was built; -1 was accepted."""
    with pytest.raises(ValueError, match=r"eval_every \(--eval-every, env steps\) must be an int in \[1, "):
        train(TrainConfig(steps=10), tmp_path / "run", eval_every=every, progress=False)  # type: ignore[arg-type]
    assert not (tmp_path / "run").exists()


def test_train_freq_list_reaches_sb3_as_its_tuple() -> None:
    """YAML has no tuple and SB3 refuses a list: build_model hands it (n, unit)."""
    from fawtgym.train.cli import make_config
    from fawtgym.train.envs import make_train_env
    from fawtgym.train.run import build_model

    hp = load_hyperparams("sac", ["train_freq=[2, 'episode']", "n_envs=1", "learning_starts=0", "buffer_size=100"])
    cfg = make_config(algo="sac", hyperparams=hp, steps=10)
    venv = make_train_env(num_envs=1, seed=0, **cfg.env_kwargs())
    try:
        model = build_model(cfg, venv, None)
        assert (model.train_freq.frequency, model.train_freq.unit.value) == (2, "episode")
    finally:
        venv.close()
