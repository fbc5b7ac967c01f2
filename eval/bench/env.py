"""``fawtgym bench env``: calm hover-env steps per second against the raw MuJoCo stepping it wraps.

Both are timed in the same process, interleaved over several rounds, best round kept (the least
disturbed by other load).  The raw figure is ``n_substeps`` bare ``mj_step`` calls on the env's own
model/data (the physics the env cannot avoid); the ratio env/raw is the env's total cost in units of
that physics, so ``ratio - 1`` is the env's overhead.  Every MuJoCo baseline (raw, bare, batched) runs with MuJoCo's
profiler timers as the env runs its own physics (off by default: `fawtgym/envs/mujoco_timers.py`).  The reference
machine's bare figure below was measured with the Python bindings' timers on: with them off here, the projection to
that machine is conservative (the bare step it divides by is cheaper by the clock's share).

The absolute target (>= 10,000 env steps/s) was set on a machine where a bare 4-rotor free body steps at
about 350k ``mj_step``/s; this machine's speed varies with its load, so the same rounds also time that
bare body (the observer benchmark's inline model, contacts disabled, Euler) and the env step is expressed in
its units: the target holds on the reference machine iff one env step costs <= 35 bare ``mj_step``.

``--batch N`` (default 1024; 0 skips) also times the batched env's physics, the ``mujoco.rollout`` call of
:class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv` for N vehicles, on the calling thread and on the env's
threads (one per core, one ``MjData`` each), interleaved in the same rounds: their ratio is what the
threads buy (about the number of free cores), and the batched env alone (calm, hover action) in
vehicle-steps per second.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import mujoco
import numpy as np

from fawtgym.cli_parser import ArgumentParser, bounded_int, positive_float, positive_int
from fawtgym.core.constants import GRAVITY
from fawtgym.envs import mujoco_timers
from fawtgym.envs.hover_env import HoverEnv


def _time_env(env: HoverEnv, steps: int) -> float:
    a = env.hover_action()
    env.reset(seed=0)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return time.perf_counter() - t0


def _time_mj_steps(model: mujoco.MjModel, data: mujoco.MjData, steps: int, timers: bool) -> float:
    """Wall seconds of ``steps`` bare ``mj_step`` calls, with MuJoCo's profiler timers as an env with
    ``mujoco_timers=timers`` runs its physics."""
    with mujoco_timers.suspended(not timers):
        t0 = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(model, data)
        return time.perf_counter() - t0


def _time_raw(env: HoverEnv, steps: int) -> float:
    d = env.data
    d.ctrl[:4] = env.preset.mass * GRAVITY / 4
    return _time_mj_steps(env.model, d, steps * env.n_substeps, env.mujoco_timers)


#: bare-body mj_step/s of the machine the issue's absolute target was set on
REFERENCE_BARE_STEPS_PER_S = 350_000.0


def _bare_model() -> tuple[mujoco.MjModel, mujoco.MjData]:
    from fawtgym.eval.bench.observers import QUAD_XML

    xml = QUAD_XML.replace('<option timestep="0.001" gravity="0 0 -9.81"/>',
                           '<option timestep="0.001" gravity="0 0 -9.81" integrator="Euler">'
                           '<flag contact="disable"/></option>')
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def _time_bare(model: mujoco.MjModel, data: mujoco.MjData, steps: int, timers: bool) -> float:
    mujoco.mj_resetData(model, data)
    data.ctrl[:] = 4.34 * 9.81 / 4
    return _time_mj_steps(model, data, steps, timers)


def measure(control_rate: float = 100.0, physics_rate: float = 1000.0, steps: int = 2000, rounds: int = 5,
            **env_kwargs) -> dict[str, float]:
    """Best-of-``rounds`` env and raw timings for ``steps`` control steps; returns rates and the ratio."""
    env = HoverEnv(control_rate=control_rate, physics_rate=physics_rate, episode_seconds=1e6, init_noise=0.0,
                   **env_kwargs)
    env.reset(seed=0)
    bare_m, bare_d = _bare_model()
    env_t, raw_t, bare_t = [], [], []
    for _ in range(rounds):
        env_t.append(_time_env(env, steps))
        raw_t.append(_time_raw(env, steps))
        bare_t.append(_time_bare(bare_m, bare_d, steps * env.n_substeps, env.mujoco_timers))
    te, tr = min(env_t), min(raw_t)
    t_bare = min(bare_t) / (steps * env.n_substeps)  # one bare mj_step [s]
    bare_units = te / steps / t_bare  # one env step in bare mj_steps
    return {"env_steps_per_s": steps / te, "raw_equiv_steps_per_s": steps / tr,
            "raw_mj_steps_per_s": steps * env.n_substeps / tr, "ratio": te / tr,
            "bare_mj_steps_per_s": 1.0 / t_bare,
            "env_step_in_bare_steps": bare_units,
            "reference_env_steps_per_s": REFERENCE_BARE_STEPS_PER_S / bare_units,
            "n_substeps": env.n_substeps, "integrator": int(env.model.opt.integrator)}


def measure_batch(n: int = 1024, steps: int = 20, rounds: int = 5) -> dict[str, float]:
    """Best-of-``rounds`` physics of ``n`` vehicles (rollout of one control step) on 0 and on the env's threads,
    and the batched env alone; vehicle-steps per second."""
    from mujoco import rollout

    from fawtgym.envs.hover_batch_env import _CONTROL_SPEC, HoverBatchEnv, default_physics_threads

    env = HoverBatchEnv(n, episode_seconds=1e6, init_noise=0.0)
    env.reset(seed=0)
    hover = env.hover_action()
    env.step(hover)
    state, ctrl, out = env._mj_state.copy(), env._ctrl.copy(), env._out.copy()
    threads = default_physics_threads(n)
    pools = {}
    for k in sorted({0, threads}):
        pools[k] = (rollout.Rollout(nthread=k), [mujoco.MjData(env.model) for _ in range(max(k, 1))],
                    -(-n // k) if k else None)
    best = {k: np.inf for k in [*pools, "env"]}
    for _ in range(rounds):
        for k, (pool, datas, chunk) in pools.items():
            with mujoco_timers.suspended(not env.mujoco_timers):  # the env's own physics setting
                t0 = time.perf_counter()
                for _ in range(steps):
                    pool.rollout([env.model] * n, datas, state, ctrl, control_spec=_CONTROL_SPEC, skip_checks=True,
                                 nstep=env.n_substeps, state=out, chunk_size=chunk)
                best[k] = min(best[k], time.perf_counter() - t0)
        t0 = time.perf_counter()
        for _ in range(steps):
            env.step(hover)
        best["env"] = min(best["env"], time.perf_counter() - t0)
    for pool, _, _ in pools.values():
        pool.close()
    env.close()
    return {"threads": float(threads), "physics_1": n * steps / best[0],
            "physics_threads": n * steps / best[threads], "env": n * steps / best["env"]}


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="fawtgym bench env", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=positive_int, default=2000, help="control steps per round")
    parser.add_argument("--rounds", type=positive_int, default=5, help="timing rounds (default 5)")
    parser.add_argument("--control-rate", type=positive_float, default=100.0, help="control rate [Hz] (default 100)")
    parser.add_argument("--physics-rate", type=positive_float, default=1000.0, help="physics rate [Hz] (default 1000)")
    parser.add_argument("--integrator", default="Euler", choices=["Euler", "RK4", "implicit", "implicitfast"],
                        help="MuJoCo integrator (default Euler)")
    parser.add_argument("--action-type", default="motors", choices=["motors", "ctbr"],
                        help="ctbr: the inner rate loop runs at the physics rate (the targets are for motors)")
    parser.add_argument("--batch", type=bounded_int(0, 1_000_000), default=1024,
                        help="N of the batched physics / env timing (default 1024; 0 skips)")
    args = parser.parse_args(argv)
    r = measure(args.control_rate, args.physics_rate, args.steps, args.rounds, integrator=args.integrator,
                action_type=args.action_type)
    print(f"calm hover env ({args.action_type}), {args.control_rate:g} Hz control, {args.physics_rate:g} Hz physics "
          f"({r['n_substeps']} substeps, integrator {args.integrator}):")
    print(f"  env steps/s                         {r['env_steps_per_s']:12,.0f}")
    print(f"  raw mj_step/s                       {r['raw_mj_steps_per_s']:12,.0f}")
    print(f"  raw-equivalent control steps/s      {r['raw_equiv_steps_per_s']:12,.0f}")
    print(f"  env / raw cost ratio                {r['ratio']:12.2f}   (overhead {r['ratio'] - 1:.2f}x raw)")
    print(f"  bare 4-rotor body mj_step/s (same rounds) {r['bare_mj_steps_per_s']:12,.0f}")
    print(f"  one env step in bare mj_steps           {r['env_step_in_bare_steps']:12.1f}")
    print(f"  env steps/s at {REFERENCE_BARE_STEPS_PER_S:,.0f} bare mj_step/s (the target's machine) "
          f"{r['reference_env_steps_per_s']:9,.0f}")
    over, ref = r["ratio"] - 1.0, r["reference_env_steps_per_s"]
    print(f"  targets: overhead <= 2x raw physics ({'met' if over <= 2.0 else 'NOT met'}); >= 10,000 env steps/s: "
          f"{'met' if r['env_steps_per_s'] >= 1e4 else 'not met'} on this machine now, "
          f"{'met' if ref >= 1e4 else 'NOT met'} at the reference speed")
    if args.batch:
        b = measure_batch(args.batch, rounds=args.rounds)
        print(f"batched, N = {args.batch} (calm, {r['n_substeps']} substeps per control step), vehicle-steps/s:")
        print(f"  physics only, calling thread           {b['physics_1']:12,.0f}")
        print(f"  physics only, {int(b['threads']) or 1} thread(s) (the env's)     {b['physics_threads']:12,.0f}"
              f"   ({b['physics_threads'] / b['physics_1']:.2f}x)")
        print(f"  env alone (hover action)               {b['env']:12,.0f}"
              f"   ({b['env'] / b['physics_threads']:.2f} of its physics)")
    return 0 if np.isfinite(r["ratio"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
