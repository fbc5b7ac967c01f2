"""fawtgym train: runs save, reload and resume; the sb3: agent flies exactly what the policy did in training."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fawtgym.agents.spec import agent_action_type, make_agent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.eval.scenarios import get_scenario
from fawtgym.train.cli import main as train_main
from fawtgym.train.cli import make_config
from fawtgym.train.config import load_hyperparams
from fawtgym.train.run import latest_checkpoint, train

TINY = {"n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 2}
OFF_POLICY = {"n_envs": 2, "learning_starts": 64, "batch_size": 32, "buffer_size": 2000}


def config(algo: str = "ppo", steps: int = 256, **fields: object) -> object:
    hp = load_hyperparams(algo, TINY if algo == "ppo" else OFF_POLICY)
    fields.setdefault("episode_seconds", 0.5)
    return make_config(hyperparams=hp, algo=algo, steps=steps, eval_scenarios=(), **fields)


@pytest.mark.parametrize("algo", ["ppo", "sac", "td3"])
def test_smoke_run_saves_reloads_and_acts_identically(algo: str, tmp_path: Path) -> None:
    cfg = config(algo, steps=256, obs="state+eso")
    meta = train(cfg, tmp_path / "run", checkpoint_every=128, progress=False)
    run = tmp_path / "run"
    assert meta["finished"] and meta["steps_done"] >= 256 and meta["key"] == cfg.key()
    assert (run / "model.zip").is_file() and (run / "vecnormalize.pkl").is_file()
    saved = json.loads((run / "metadata.json").read_text())
    assert saved["config"]["algo"] == algo and saved["versions"]["stable-baselines3"]
    env = HoverBatchEnv(num_envs=3, **get_scenario("table4-50").env_options(),
                        action_type=agent_action_type(f"sb3:{run}"))
    obs, info = env.reset(seed=0)
    a1, a2 = make_agent(f"sb3:{run}", env), make_agent(f"sb3:{run}", env)
    a1.reset(info)
    a2.reset(info)
    for _ in range(5):
        act = a1.act(obs, info)
        assert np.array_equal(act, a2.act(obs, info)) and act.shape == (3, 4)
        obs, _, _, _, info = env.step(act)
    env.close()


def test_resume_continues_and_refuses_other_configs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    cfg = config(steps=256)
    train(cfg, run, checkpoint_every=128, progress=False)
    first = latest_checkpoint(run)
    assert first is not None and int(first.name) >= 256
    longer = config(steps=512)
    meta = train(longer, run, resume=True, checkpoint_every=128, progress=False)
    assert meta["steps_done"] >= 512 and (first / "model.zip").is_file()  # the old checkpoint is kept
    with pytest.raises(ValueError, match="another configuration"):
        train(config(steps=512, obs="state"), run, resume=True, progress=False)
    with pytest.raises(ValueError, match="already holds a run"):
        train(cfg, run, progress=False)
    # a corrupt newest checkpoint: a one-line error, every file left as it was
    newest = latest_checkpoint(run)
    (newest / "model.zip").write_bytes(b"not a zip")
    before = {p: p.read_bytes() for p in run.rglob("*") if p.is_file()}
    with pytest.raises(ValueError, match="unreadable"):
        train(config(steps=1024), run, resume=True, progress=False)
    assert {p: p.read_bytes() for p in run.rglob("*") if p.is_file()} == before


@pytest.mark.parametrize("argv, match", [
    (["--algo", "dqn"], "unknown --algo 'dqn'; valid: ppo, sac, td3"),
    (["--observer", "nope"], "unknown --observer 'nope'"),
    (["--scenario", "table4-55"], "unknown scenario 'table4-55'"),
    (["--action", "thrust"], "unknown --action 'thrust'"),
    (["--hp", "lr=3"], "unknown ppo hyperparameter(s) ['lr']"),
    (["--steps", "0"], "--steps must be >= 1"),
    (["--resume"], "not a training run"),
])
def test_train_cli_errors_are_one_line(argv: list[str], match: str, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        train_main([*argv, "--out", str(tmp_path / "r"), "--no-progress"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and match in err, err


class Recorder:
    """Wraps HoverBatchEnv.step/reset to keep what the env received and returned."""

    def __init__(self, env: HoverBatchEnv) -> None:
        self.env, self.actions, self.outs = env, [], []
        step, reset = env.step, env.reset

        def rec_step(a):
            self.actions.append(np.array(a, dtype=float))
            out = step(a)
            self.outs.append((out[0], out[4]))
            return out

        def rec_reset(**kw):
            out = reset(**kw)
            self.outs.append(out)
            return out

        env.step, env.reset = rec_step, rec_reset


@pytest.mark.parametrize("action, obs", [("ctbr", "state"), ("ctbr", "state+eso"), ("motors", "state+eso"),
                                         ("residual", "state+eso"), ("residual", "state")])
def test_sb3_agent_flies_what_the_policy_did_in_training(action: str, obs: str, tmp_path: Path) -> None:
    """The training stack (wrappers + frozen VecNormalize + deterministic policy) and the sb3: agent on the bare
    env's observations and infos send the same actions to the env."""
    import pickle

    from fawtgym.train.config import algo_class
    from fawtgym.train.envs import make_vector_env

    cfg = config(steps=128, obs=obs, action=action)
    train(cfg, tmp_path / "run", checkpoint_every=128, progress=False)
    run = tmp_path / "run"
    model = algo_class("ppo").load(run / "model.zip", device="cpu")
    with open(run / "vecnormalize.pkl", "rb") as fh:
        norm = pickle.load(fh)
    stack = make_vector_env(**{**cfg.env_kwargs(), "episode_seconds": 5.0}, num_envs=2)
    inner = stack.unwrapped
    rec = Recorder(inner)
    x, _ = stack.reset(seed=7)
    agent = make_agent(f"sb3:{run}", inner)
    raw_obs, raw_info = rec.outs[-1]
    agent.reset(raw_info)
    for _ in range(30):
        mine = agent.act(raw_obs, raw_info)
        u, _ = model.predict(norm.normalize_obs(x), deterministic=True)
        x, _, term, trunc, _ = stack.step(u)
        assert not (term.any() or trunc.any())
        np.testing.assert_array_equal(mine, rec.actions[-1])
        raw_obs, raw_info = rec.outs[-1]
    stack.close()


def test_sweep_trains_a_grid_and_skips_finished_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"out: {tmp_path / 'runs'}\n"
                     "base: {algo: ppo, steps: 128, episode_seconds: 0.5, eval_scenarios: []}\n"
                     "grid: {obs: [state, state+eso]}\nseeds: [0]\n"
                     "hp: {n_envs: 2, n_steps: 64, batch_size: 64, n_epochs: 1}\n")
    assert train_main(["--sweep", str(sweep), "--workers", "2"]) == 0
    runs = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert runs == ["state-s0", "state_eso-s0"]
    for r in runs:
        assert json.loads((tmp_path / "runs" / r / "metadata.json").read_text())["finished"]
    capsys.readouterr()
    assert train_main(["--sweep", str(sweep)]) == 0
    assert "2 runs, 2 finished, 0 to train" in capsys.readouterr().out


@pytest.mark.long
def test_ppo_learns_to_hover_in_calm_air(tmp_path: Path) -> None:
    """PPO (the study's hyperparameters) with the normalized motor action on calm hover: the deterministic return of
    a 5 s episode (at most 1000, 1 per step at the set point) after 200k steps is at least 200 above the policy's
    at its first checkpoint (10k steps).  Measured in two runs on 2 cores: 265 -> 563 and ~200 -> 804 (PPO's
    outcome at 200k steps varies with the thread count's rounding; the margin holds in both).  With the ctbr
    action the same budget gives ~300: its policies still fall out of bounds after ~3 s, so this test flies
    motors."""
    from fawtgym.train.config import algo_class
    from fawtgym.train.envs import make_vector_env

    cfg = make_config(hyperparams=load_hyperparams("ppo"), algo="ppo", obs="state", action="motors",
                      scenario="calm", episode_seconds=5.0, steps=200_000, eval_scenarios=())

    def deterministic_return(folder: Path) -> float:
        import pickle

        model = algo_class("ppo").load(folder / "model.zip", device="cpu")
        with open(folder / "vecnormalize.pkl", "rb") as fh:
            norm = pickle.load(fh)
        env = make_vector_env(**cfg.env_kwargs(), num_envs=4)
        x, _ = env.reset(seed=123)
        total = np.zeros(4)
        alive = np.ones(4, dtype=bool)
        for _ in range(1000):
            u, _ = model.predict(norm.normalize_obs(x), deterministic=True)
            x, r, term, trunc, _ = env.step(u)
            total += np.where(alive, r, 0.0)
            alive &= ~(term | trunc)
            if not alive.any():
                break
        return float(total.mean())

    train(cfg, tmp_path / "run", checkpoint_every=10_000, progress=False)
    first = sorted((tmp_path / "run" / "checkpoints").iterdir())[0]
    before, after = deterministic_return(first), deterministic_return(tmp_path / "run")
    print(f"deterministic return after {first.name} steps: {before:.1f}; after 200k: {after:.1f}")
    assert after >= before + 200.0, (before, after)


def test_sweep_on_ray(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("ray")
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"out: {tmp_path / 'runs'}\n"
                     "base: {algo: ppo, steps: 128, episode_seconds: 0.5, eval_scenarios: [], obs: state}\n"
                     "grid: {action: [ctbr, motors]}\nseeds: [0]\n"
                     "hp: {n_envs: 2, n_steps: 64, batch_size: 64, n_epochs: 1}\n")
    import ray

    try:
        assert train_main(["--sweep", str(sweep), "--backend", "ray"]) == 0
    finally:
        ray.shutdown()
    for r in ("ctbr-s0", "motors-s0"):
        assert json.loads((tmp_path / "runs" / r / "metadata.json").read_text())["finished"]
