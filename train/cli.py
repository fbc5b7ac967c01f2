"""``fawtgym train``: train a Stable-Baselines3 policy on the batched hover env, or a sweep of them.

Examples::

    fawtgym train --algo ppo --obs state+eso --action ctbr --steps 500000 --out runs/ppo-eso
    fawtgym train --algo ppo --obs state+eso --action ctbr --steps 1000000 --out runs/ppo-eso --resume
    fawtgym train --algo sac --action residual --hp learning_rate=1e-4 --hp n_envs=32 --out runs/sac-res
    fawtgym train --sweep sweep.yaml --workers 2          # a grid of configs x seeds (or --backend ray)

A trained run enters the leaderboard as ``sb3:runs/NAME``.  A sweep file::

    out: runs/study                    # one run folder per grid point and seed, named by its values
    base: {algo: ppo, steps: 300000, scenario: table4-50, randomize: {duty: [0.3, 0.7]}}
    grid: {obs: [state, state+eso], action: [ctbr, residual]}
    seeds: [0, 1, 2]

Finished runs of a sweep are skipped and unfinished ones resumed, so a sweep can be run in pieces.
"""

from __future__ import annotations

import concurrent.futures as cf
import itertools
import multiprocessing
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fawtgym.cli_parser import ArgumentParser, check_output_dir
from fawtgym.core.checks import check_int, check_known, check_number, keyword_names, shown
from fawtgym.core.files import load_data
from fawtgym.envs.options import MAX_EPISODE_SECONDS

from .config import ACTION_MODES, ALGOS, OBS_MODES, TrainConfig, freeze, load_hyperparams, parse_literal


def build_parser() -> ArgumentParser:
    p = ArgumentParser(prog="fawtgym train", description=__doc__.split("\n\n")[0])
    p.add_argument("--algo", default="ppo", help=f"one of {', '.join(ALGOS)} (default ppo)")
    p.add_argument("--obs", default="state+eso", help=f"one of {', '.join(OBS_MODES)} (default state+eso): the env's "
                                                      "state, or with the observer's scaled force/torque estimates")
    p.add_argument("--observer", default="ffts_eso", help="observer for --obs state+eso (default ffts_eso)")
    p.add_argument("--action", default="ctbr", help=f"one of {', '.join(ACTION_MODES)} (default ctbr): normalized "
                                                    "thrust + body rates, normalized motors, or a residual on PX4")
    p.add_argument("--residual-base", default="px4+ffts_eso", help="base agent of --action residual")
    p.add_argument("--residual-bound", type=float, default=0.1, help="residual bound, fraction of the action range")
    p.add_argument("--scenario", default="table4-50", help="training scenario (default table4-50)")
    p.add_argument("--episode-seconds", type=float, default=20.0, help="training episode length [s] (default 20)")
    p.add_argument("--randomize", action="append", default=[], metavar="KEY=VALUE",
                   help="domain randomization, e.g. duty=[0.3,0.7] mass=0.1 (see fawtgym.train.randomization)")
    p.add_argument("--steps", type=int, default=200_000, help="env steps in total (default 200000)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--hp", action="append", default=[], metavar="KEY=VALUE",
                   help="hyperparameter override of train/hyperparams/<algo>.yaml (repeatable)")
    p.add_argument("--out", type=Path, default=None, help="run folder (default runs/<algo>-<obs>-<action>-s<seed>)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its newest checkpoint")
    p.add_argument("--checkpoint-every", type=int, default=50_000, help="steps between checkpoints (default 50000)")
    p.add_argument("--eval-every", type=int, default=None, help="steps between evaluations (default steps / 4)")
    p.add_argument("--eval-scenarios", default="table4-50", help="comma list evaluated during training ('' = none)")
    p.add_argument("--eval-seeds", type=int, default=2)
    p.add_argument("--sweep", type=Path, default=None, help="a sweep file (module docstring): runs a grid instead")
    p.add_argument("--workers", type=int, default=2, help="parallel runs of a sweep (default 2)")
    p.add_argument("--backend", choices=("local", "ray"), default="local", help="sweep runs on local processes or Ray")
    p.add_argument("--ray-address", default=None)
    p.add_argument("--no-progress", action="store_true")
    return p


def _pairs(items: Sequence[str], flag: str) -> dict[str, Any]:
    out = {}
    for text in items:
        key, sep, value = text.partition("=")
        if not sep or not key:
            raise ValueError(f"{flag} takes KEY=VALUE, got {shown(text)}")
        out[key.strip()] = parse_literal(value.strip())
    return out


def config_from_args(ns: Any) -> TrainConfig:
    """The TrainConfig of parsed arguments (ValueError with a one-line reason on bad values)."""
    if ns.algo not in ALGOS:
        raise ValueError(f"unknown --algo {shown(ns.algo)}; valid: {', '.join(ALGOS)}")
    hp = load_hyperparams(ns.algo, ns.hp)
    return make_config(algo=ns.algo, obs=ns.obs, observer=ns.observer, action=ns.action, scenario=ns.scenario,
                       episode_seconds=ns.episode_seconds, randomize=_pairs(ns.randomize, "--randomize"),
                       residual_base=ns.residual_base, residual_bound=ns.residual_bound, steps=ns.steps,
                       seed=ns.seed, hyperparams=hp,
                       eval_scenarios=[s for s in ns.eval_scenarios.split(",") if s.strip()],
                       eval_seeds=ns.eval_seeds)


def make_config(*, hyperparams: Mapping[str, Any] | None = None, **fields: Any) -> TrainConfig:
    """A validated TrainConfig: names checked against the registries, the env built once."""
    from fawtgym.eval.scenarios import get_scenario
    from fawtgym.observers import observer_names

    algo = fields.get("algo", "ppo")
    hp = dict(hyperparams) if hyperparams is not None else load_hyperparams(algo)
    if fields.get("obs", "state+eso") == "state+eso" and fields.get("observer", "ffts_eso") not in observer_names():
        raise ValueError(f"unknown --observer {fields.get('observer')!r}; valid: {', '.join(observer_names())}")
    training = get_scenario(fields.get("scenario", "table4-50"))
    for sc in fields.get("eval_scenarios", ()):
        get_scenario(sc)
    if fields.get("episode_seconds") is not None:  # at least one control step (the env would round it up to one)
        step = 1.0 / training.control_rate
        check_number(fields["episode_seconds"], "--episode-seconds", minimum=step, inclusive_minimum=True,
                     maximum=MAX_EPISODE_SECONDS, note=f"s (at least one control step of the scenario, {step:g} s)")
    for key in ("observer_kwargs", "randomize"):
        fields[key] = freeze(fields.get(key) or {})
    fields["eval_scenarios"] = tuple(fields.get("eval_scenarios", ("table4-50",)))
    return TrainConfig(hyperparams=freeze(hp), **fields)


def default_out(cfg: TrainConfig) -> Path:
    return Path("runs") / f"{cfg.algo}-{cfg.obs.replace('+', '_')}-{cfg.action}-s{cfg.seed}"


def _check_env(cfg: TrainConfig) -> None:
    """Build the training env once (bad observer gains, randomization keys, residual base fail here)."""
    from .envs import make_train_env

    env = make_train_env(num_envs=1, seed=cfg.seed, **cfg.env_kwargs())
    env.close()


def _run_one(cfg_dict: dict[str, Any], out: str, resume: bool, checkpoint_every: int, eval_every: int | None,
             progress: bool) -> dict[str, Any]:
    import torch

    from .run import train

    torch.set_num_threads(1)  # one core per run: the sweep runs several at once
    return train(TrainConfig.from_dict(cfg_dict), Path(out), resume=resume, checkpoint_every=checkpoint_every,
                 eval_every=eval_every, progress=progress, log=lambda s: None)


def sweep_configs(path: Path) -> tuple[Path, list[tuple[TrainConfig, Path]]]:
    """(output folder, [(config, run folder)]) of a sweep file."""
    spec = load_data(path, "sweep file")
    if not isinstance(spec, Mapping) or not set(spec) <= {"out", "base", "grid", "seeds", "hp"}:
        raise ValueError(f"sweep file {path} must be a mapping with keys out, base, grid, seeds, hp")
    out = spec.get("out", f"runs/{path.stem}")
    if not isinstance(out, str) or not out:
        raise ValueError(f"sweep file {path}: out must be a folder name (a non-empty str), got {shown(out)}")
    out = Path(out)
    base, grid, hp_all = (spec.get(key) or {} for key in ("base", "grid", "hp"))
    for key, value in (("base", base), ("grid", grid), ("hp", hp_all)):
        if not isinstance(value, Mapping):
            raise ValueError(f"sweep file {path}: {key} must be a mapping, got {shown(value)}")
    fields = set(keyword_names(TrainConfig)) - {"hyperparams"} | {"hp"}
    check_known({**base, **grid}, sorted(fields), f"sweep file {path} (base, grid)")
    seeds = spec.get("seeds", [0])
    seeds = [seeds] if isinstance(seeds, int) and not isinstance(seeds, bool) else seeds
    if not isinstance(seeds, list) or not seeds:
        raise ValueError(f"sweep file {path}: seeds must be a seed or a non-empty list of seeds, got {shown(seeds)}")
    seeds = [check_int(seed, f"sweep file {path}: a seed", 0, 2**32 - 1) for seed in seeds]
    base, grid = dict(base), dict(grid)
    runs = []
    keys = list(grid)
    for values in itertools.product(*(grid[k] if isinstance(grid[k], list) else [grid[k]] for k in keys)):
        point = {**base, **dict(zip(keys, values, strict=True))}
        point_hp = point.pop("hp", None) or {}  # once per point: every seed of it takes it
        if not isinstance(point_hp, Mapping):
            raise ValueError(f"sweep file {path}: a point's hp must be a mapping, got {shown(point_hp)}")
        algo = point.get("algo", "ppo")
        hp = load_hyperparams(algo, {**hp_all, **point_hp})
        for seed in seeds:
            cfg = make_config(hyperparams=hp, **{**point, "seed": seed})
            name = "-".join(_point_text(v) for v in values).replace("+", "_").replace("/", "_") or "run"
            runs.append((cfg, out / f"{name}-s{seed}"))
    return out, runs


def _point_text(value: Any) -> str:
    """A grid value in a run folder's name: a scalar as written; a mapping as its keys and values (an hp point), a
    list as its items, joined by ``_`` and made file-name safe (``n_steps_64`` rather than ``{'n_steps': 64}``)."""
    from fawtgym.eval.runner import slug

    if isinstance(value, Mapping):
        return slug("_".join(f"{k}_{_point_text(v)}" for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return slug("_".join(_point_text(v) for v in value))
    return f"{value}"


def run_sweep(ns: Any) -> int:
    import json

    out, runs = sweep_configs(ns.sweep)
    todo = []
    for cfg, folder in runs:
        meta = folder / "metadata.json"
        if meta.is_file() and json.loads(meta.read_text()).get("finished"):
            continue
        todo.append((cfg.to_dict(), str(folder), meta.is_file(), ns.checkpoint_every, ns.eval_every, False))
    print(f"sweep {ns.sweep}: {len(runs)} runs, {len(runs) - len(todo)} finished, {len(todo)} to train -> {out}")
    errors = 0
    if ns.backend == "ray":
        import ray

        started = not ray.is_initialized()
        if started:
            ray.init(address=ns.ray_address, include_dashboard=False, log_to_driver=False)
        try:
            task = ray.remote(num_cpus=1, max_retries=0)(_run_one)
            refs = {task.remote(*job): job for job in todo}
            for ref, job in refs.items():
                try:
                    ray.get(ref)
                    print(f"  done {job[1]}")
                except Exception as exc:
                    errors += 1
                    print(f"fawtgym train: run {job[1]} failed: {str(exc).splitlines()[0]}", file=sys.stderr)
        finally:
            if started:
                ray.shutdown()
    else:
        ctx = multiprocessing.get_context("spawn")
        with cf.ProcessPoolExecutor(max_workers=max(1, min(ns.workers, len(todo) or 1)), mp_context=ctx) as pool:
            futures = {pool.submit(_run_one, *job): job for job in todo}
            for fut in cf.as_completed(futures):
                job = futures[fut]
                if fut.exception() is not None:
                    errors += 1
                    print(f"fawtgym train: run {job[1]} failed: {str(fut.exception()).splitlines()[0]}",
                          file=sys.stderr)
                else:
                    print(f"  done {job[1]}", flush=True)
    return 1 if errors else 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    ns = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    check_output_dir(parser, "--out", ns.out)
    for flag in ("steps", "checkpoint_every", "eval_seeds", "workers", "eval_every"):
        if getattr(ns, flag) is not None and getattr(ns, flag) < 1:  # eval_every None: steps / 4
            parser.error(f"--{flag.replace('_', '-')} must be >= 1, got {getattr(ns, flag)}")
    try:
        if ns.sweep is not None:
            return run_sweep(ns)
        cfg = config_from_args(ns)
        _check_env(cfg)
    except ValueError as exc:
        parser.error(str(exc))
    out = ns.out or default_out(cfg)
    from .run import train

    try:
        meta = train(cfg, out, resume=ns.resume, checkpoint_every=ns.checkpoint_every, eval_every=ns.eval_every,
                     progress=not ns.no_progress)
    except ValueError as exc:
        parser.error(str(exc))
    print(f"trained {meta['steps_done']} steps in {meta['wall_seconds']:.0f} s -> {out} "
          f"(leaderboard agent: sb3:{out})")
    for e in meta.get("evals", [])[-1:]:
        for sc, r in e["results"].items():
            print(f"  eval at {e['steps']} steps on {sc}: mean position error {r['pos_err_mean']} m, "
                  f"{r['failures']}/{r['seeds']} failed")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
