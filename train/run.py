"""One training run: build the env and the algorithm, learn with checkpoints and periodic evaluation, save.

A run directory holds::

    metadata.json               the config (TrainConfig), its key, algorithm and hyperparameters, seed, git commit,
                                package versions, wall time, steps done, the evaluations so far
    model.zip, vecnormalize.pkl the final policy and its observation/reward normalization (written at the end)
    checkpoints/<steps>/        model.zip, vecnormalize.pkl (+ replay_buffer.pkl for SAC/TD3), each checkpoint a
                                directory renamed into place at once (atomic); the newest is the one resumed
    evals.jsonl                 one line per periodic evaluation (the evaluation runner's metrics)
    tb/                         TensorBoard logs

Every checkpoint and the final model are loadable as an agent: ``sb3:runs/NAME`` (final) or
``sb3:runs/NAME/checkpoints/000050000`` in the agent grammar.  ``resume=True`` continues from the newest
checkpoint with the same configuration (the step counter continues; what was learned before that
checkpoint is kept); a run directory of another configuration, a missing or unreadable checkpoint give a
one-line ValueError and leave every file as it was.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from fawtgym.core.checks import check_int

from .config import MAX_TRAIN_STEPS, OWN_KEYS, TrainConfig, algo_class

CHECKPOINTS = "checkpoints"


def git_commit() -> str | None:
    """The package's git commit, if it runs from a checkout."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parent, capture_output=True,
                             text=True, timeout=5)
        return out.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def versions() -> dict[str, str]:
    import importlib.metadata as md
    import platform

    out = {"python": platform.python_version()}
    for pkg in ("fawtgym", "numpy", "scipy", "mujoco", "gymnasium", "stable-baselines3", "torch"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def make_env(cfg: TrainConfig, seed: int | None = None) -> Any:
    """The training VecEnv of ``cfg``: the batched env through the SB3 adapter, VecMonitor, VecNormalize."""
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from .envs import make_train_env

    hp = cfg.hp
    venv = make_train_env(num_envs=int(hp.get("n_envs", 16)), seed=cfg.seed if seed is None else seed,
                          **cfg.env_kwargs())
    venv = VecMonitor(venv)
    if hp.get("normalize", True):
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=float(hp.get("gamma", 0.99)))
    return venv


def build_model(cfg: TrainConfig, venv: Any, tb_dir: Path | None) -> Any:
    """A fresh algorithm instance of ``cfg`` on ``venv``."""
    hp = cfg.hp
    kwargs = {k: v for k, v in hp.items() if k not in OWN_KEYS}
    if isinstance(kwargs.get("train_freq"), list):  # YAML has no tuple: SB3 takes (n, "step" | "episode")
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    if cfg.algo == "td3" and hp.get("action_noise") == "normal":
        from stable_baselines3.common.noise import NormalActionNoise

        dim = venv.action_space.shape[0]
        kwargs["action_noise"] = NormalActionNoise(np.zeros(dim), float(hp.get("action_noise_std", 0.1)) * np.ones(dim))
    cls = algo_class(cfg.algo)
    return cls(hp.get("policy", "MlpPolicy"), venv, seed=cfg.seed, device="cpu", verbose=0,
               tensorboard_log=None if tb_dir is None else str(tb_dir), **kwargs)


def _atomic_json(path: Path, data: Any) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(data, fh, indent=1, default=str)
    os.replace(tmp, path)


def save_policy(model: Any, venv: Any, folder: Path, replay_buffer: bool = False) -> None:
    """model.zip and vecnormalize.pkl (and the replay buffer) into ``folder``."""
    from stable_baselines3.common.vec_env import VecNormalize

    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / "model.zip")
    if isinstance(venv, VecNormalize):
        venv.save(str(folder / "vecnormalize.pkl"))
    if replay_buffer and hasattr(model, "save_replay_buffer"):
        model.save_replay_buffer(folder / "replay_buffer.pkl")


def save_checkpoint(model: Any, venv: Any, run: Path) -> Path:
    """An atomic checkpoint ``checkpoints/<steps>`` (written in a temporary directory, renamed into place)."""
    steps = int(model.num_timesteps)
    root = run / CHECKPOINTS
    root.mkdir(parents=True, exist_ok=True)
    final = root / f"{steps:09d}"
    if final.exists():
        return final
    tmp = Path(tempfile.mkdtemp(dir=root, prefix=".tmp-"))
    try:
        save_policy(model, venv, tmp, replay_buffer=hasattr(model, "replay_buffer"))
        _atomic_json(tmp / "checkpoint.json", {"steps": steps, "saved": time.time()})
        os.replace(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final


def latest_checkpoint(run: Path) -> Path | None:
    """The newest complete checkpoint directory of a run (None if there is none)."""
    root = run / CHECKPOINTS
    if not root.is_dir():
        return None
    done = sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".") and p.name.isdigit())
    return done[-1] if done else None


def load_checkpoint(cfg: TrainConfig, ckpt: Path, venv: Any) -> tuple[Any, Any]:
    """(model, venv with the checkpoint's normalization) from a checkpoint; ValueError if unreadable."""
    from stable_baselines3.common.vec_env import VecNormalize

    try:
        info = json.loads((ckpt / "checkpoint.json").read_text())
        if isinstance(venv, VecNormalize):
            venv = VecNormalize.load(str(ckpt / "vecnormalize.pkl"), venv.venv)
        model = algo_class(cfg.algo).load(ckpt / "model.zip", env=venv, device="cpu")
        if (ckpt / "replay_buffer.pkl").is_file():
            model.load_replay_buffer(ckpt / "replay_buffer.pkl")
    except Exception as exc:  # a truncated zip, a missing file, a pickle of another version
        why = str(exc).splitlines()[0] if str(exc) else ""
        raise ValueError(f"checkpoint {ckpt} is unreadable ({type(exc).__name__}: {why}); delete it to resume from "
                         "the one before, or start a new run") from exc
    if int(model.num_timesteps) != int(info["steps"]):
        model.num_timesteps = int(info["steps"])
    return model, venv


def evaluate_policy_dir(folder: Path, scenarios: tuple[str, ...], seeds: int) -> dict[str, dict[str, float | None]]:
    """The evaluation runner's metrics of the policy in ``folder`` on ``scenarios`` (means over ``seeds`` seeds)."""
    from fawtgym.eval.runner import fly_cell
    from fawtgym.eval.scenarios import get_scenario

    out = {}
    for name in scenarios:
        result, _ = fly_cell(f"sb3:{folder}", get_scenario(name).to_dict(), list(range(1000, 1000 + seeds)))
        eps = result["episodes"]
        done = [e for e in eps if not e["failure"]]
        att = [e["att_err_mean"] for e in done if e["att_err_mean"] is not None]
        tilt = [e["tilt_mean"] for e in done if e["tilt_mean"] is not None]
        out[name] = {"pos_err_mean": float(np.mean([e["pos_err_mean"] for e in done])) if done else None,
                     "att_err_mean": float(np.mean(att)) if att else None,
                     "tilt_mean": float(np.mean(tilt)) if tilt else None,
                     "failures": len(eps) - len(done), "seeds": len(eps),
                     "time_flown": float(np.mean([e["time_flown"] for e in eps]))}
    return out


def train(cfg: TrainConfig, run: Path, *, resume: bool = False, checkpoint_every: int = 50_000,
          eval_every: int | None = None, progress: bool = True, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Train ``cfg`` into ``run`` (module docstring); returns the metadata written."""
    from stable_baselines3.common.callbacks import BaseCallback

    checkpoint_every = check_int(checkpoint_every, "checkpoint_every (--checkpoint-every, env steps)", 1,
                                 MAX_TRAIN_STEPS)
    if eval_every is not None:
        eval_every = check_int(eval_every, "eval_every (--eval-every, env steps)", 1, MAX_TRAIN_STEPS)
    run = Path(run)
    meta_path = run / "metadata.json"
    if resume:
        if not meta_path.is_file():
            raise ValueError(f"--resume: {run} is not a training run (no metadata.json)")
        meta = json.loads(meta_path.read_text())
        if meta.get("key") != cfg.key():
            raise ValueError(f"--resume: {run} was trained with another configuration (key {meta.get('key')} != "
                             f"{cfg.key()}); use the same options or another --out")
        ckpt = latest_checkpoint(run)
        if ckpt is None:
            raise ValueError(f"--resume: {run} has no checkpoint to resume from")
    else:
        if meta_path.exists() or (run / CHECKPOINTS).exists():
            raise ValueError(f"{run} already holds a run; add --resume to continue it, or choose another --out")
        meta = {"config": cfg.to_dict(), "key": cfg.key(), "created": time.time(), "evals": [], "wall_seconds": 0.0}
        ckpt = None
    meta.update({"algo": cfg.algo, "hyperparams": cfg.hp, "seed": cfg.seed, "git_commit": git_commit(),
                 "versions": versions(), "config": cfg.to_dict()})
    run.mkdir(parents=True, exist_ok=True)
    venv = make_env(cfg)
    if ckpt is not None:
        model, venv = load_checkpoint(cfg, ckpt, venv)
        model.tensorboard_log = str(run / "tb")
        log(f"resuming {run} from {ckpt.name} ({model.num_timesteps} steps)")
    else:
        model = build_model(cfg, venv, run / "tb")
    _atomic_json(meta_path, meta)
    t0 = time.perf_counter()
    wall0 = float(meta.get("wall_seconds", 0.0))
    every_eval = eval_every if eval_every is not None else max(checkpoint_every, cfg.steps // 4)

    class Periodic(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.next_ckpt = (model.num_timesteps // checkpoint_every + 1) * checkpoint_every
            self.next_eval = (model.num_timesteps // every_eval + 1) * every_eval
            self.bar = None

        def _on_training_start(self) -> None:
            if progress:
                from tqdm.auto import tqdm

                self.bar = tqdm(total=cfg.steps, initial=min(model.num_timesteps, cfg.steps), unit="step",
                                desc=f"{cfg.algo} {cfg.obs} {cfg.action}", dynamic_ncols=True)

        def _on_step(self) -> bool:
            n = self.model.num_timesteps
            if self.bar is not None:
                self.bar.update(max(0, min(n, cfg.steps) - self.bar.n))
            if n >= self.next_ckpt:
                save_checkpoint(self.model, self.model.get_env(), run)
                self.next_ckpt = (n // checkpoint_every + 1) * checkpoint_every
                meta["wall_seconds"] = wall0 + time.perf_counter() - t0
                meta["steps_done"] = int(n)
                _atomic_json(meta_path, meta)
            if n >= self.next_eval and cfg.eval_scenarios:
                folder = save_checkpoint(self.model, self.model.get_env(), run)
                res = evaluate_policy_dir(folder, cfg.eval_scenarios, cfg.eval_seeds)
                entry = {"steps": int(n), "results": res}
                meta.setdefault("evals", []).append(entry)
                with open(run / "evals.jsonl", "a") as fh:
                    fh.write(json.dumps(entry) + "\n")
                for sc, r in res.items():
                    if r["pos_err_mean"] is not None:
                        self.logger.record(f"eval/{sc}/pos_err_mean", r["pos_err_mean"])
                    self.logger.record(f"eval/{sc}/failures", r["failures"])
                self.next_eval = (n // every_eval + 1) * every_eval
                _atomic_json(meta_path, meta)
            return True

        def _on_training_end(self) -> None:
            if self.bar is not None:
                self.bar.close()

    remaining = cfg.steps - int(model.num_timesteps)
    if remaining > 0:
        model.learn(total_timesteps=remaining, callback=Periodic(), reset_num_timesteps=False,
                    tb_log_name="run")
    save_checkpoint(model, model.get_env(), run)
    tmp = Path(tempfile.mkdtemp(dir=run, prefix=".final-"))
    try:
        save_policy(model, model.get_env(), tmp)
        for name in ("model.zip", "vecnormalize.pkl"):
            if (tmp / name).exists():
                os.replace(tmp / name, run / name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    meta["wall_seconds"] = wall0 + time.perf_counter() - t0
    meta["steps_done"] = int(model.num_timesteps)
    meta["finished"] = True
    _atomic_json(meta_path, meta)
    model.get_env().close()
    return meta
