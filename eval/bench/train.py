"""``fawtgym bench train``: PPO end to end (env-steps/s) beside the batched env alone, in one run.

PPO (MlpPolicy 64x64, the hyperparameters of ``train/hyperparams/ppo.yaml``: a 4096-step rollout, 16 rows x
256 steps, as the study trained; ``--rows`` spreads the same rollout and updates over more rows of the batched
env, as ``fawtgym train --hp n_envs=512 --hp n_steps=8`` does; both are measured) learns on the training env of
``fawtgym train`` (the SB3 adapter over the batched env, ctbr, state)
for ``--steps`` env steps; in the same run the same stack is stepped alone with random actions for the
same number of steps.  Printed: end-to-end env-steps/s, env-alone env-steps/s, and the share of PPO's
wall time spent in the env (env-alone time / PPO time).  Targets (the issue's): >= 8,000 env-steps/s end
to end on 2 cores, and the env under a third of the wall time.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np


def measure(steps: int = 65_536, obs: str = "state", action: str = "ctbr", threads: int = 2,
            rows: int | None = None) -> dict[str, float]:
    """End-to-end and env-alone rates for ``steps`` env steps."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from fawtgym.train.config import OWN_KEYS, load_hyperparams
    from fawtgym.train.envs import make_train_env

    torch.set_num_threads(threads)
    hp = load_hyperparams("ppo")
    if rows is not None:  # same rollout size (n_envs x n_steps) and updates, spread over more rows of the batched env
        hp["n_steps"] = max(1, int(hp["n_envs"]) * int(hp["n_steps"]) // rows)
        hp["n_envs"] = rows
    n = int(hp["n_envs"])
    venv = make_train_env(scenario="fawt-50-switching", num_envs=n, action=action, obs=obs, seed=0)
    venv.reset()
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(steps // n):
        venv.step(rng.uniform(-0.2, 0.2, (n, venv.action_space.shape[0])))
    env_alone = time.perf_counter() - t0
    venv = VecNormalize(make_train_env(scenario="fawt-50-switching", num_envs=n, action=action, obs=obs, seed=0))
    model = PPO(hp.get("policy", "MlpPolicy"), venv, seed=0, device="cpu", verbose=0,
                **{k: v for k, v in hp.items() if k not in OWN_KEYS})
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps)
    ppo = time.perf_counter() - t0
    venv.close()
    return {"steps": float(model.num_timesteps), "ppo_steps_per_s": model.num_timesteps / ppo,
            "env_steps_per_s": (steps // n) * n / env_alone, "env_share": env_alone / ppo}


def main(argv: Sequence[str] | None = None) -> int:
    from fawtgym.cli_parser import ArgumentParser

    parser = ArgumentParser(prog="fawtgym bench train", description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=65_536, help="env steps (default 65536)")
    parser.add_argument("--obs", default="state", choices=("state", "state+eso"))
    parser.add_argument("--action", default="ctbr", choices=("ctbr", "motors", "residual"))
    parser.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    parser.add_argument("--rows", type=int, default=512,
                        help="rows of the batched env; the study's rollout (16 rows x 256 steps) and updates are kept, "
                             "spread over the rows (default 512; 16 is how the study trained)")
    ns = parser.parse_args(argv)
    if ns.steps < 4096 or ns.threads < 1 or not 1 <= ns.rows <= 4096:
        parser.error(f"--steps must be >= 4096, --threads >= 1 and --rows in [1, 4096], got {ns.steps}, "
                     f"{ns.threads} and {ns.rows}")
    for rows in dict.fromkeys((16, ns.rows)):
        r = measure(ns.steps, ns.obs, ns.action, ns.threads, rows=rows)
        print(f"PPO 64x64 on the training env ({ns.action}, {ns.obs}), {int(r['steps'])} env steps, {ns.threads} "
              f"threads, {rows} rows x {max(1, 4096 // rows)} steps per rollout"
              + (" (as the study trained):" if rows == 16 else ":"))
        print(f"  end to end      {r['ppo_steps_per_s']:10,.0f} env-steps/s")
        print(f"  env alone       {r['env_steps_per_s']:10,.0f} env-steps/s (same stack, random actions)")
        print(f"  env share of PPO's wall time: {100 * r['env_share']:.0f} %")
        print(f"  targets: >= 8,000 env-steps/s end to end: {'met' if r['ppo_steps_per_s'] >= 8000 else 'NOT met'}; "
              f"env under a third of the wall time: {'met' if r['env_share'] < 1 / 3 else 'NOT met'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
