"""Benchmark: wind, aerodynamics, sensors and motor lag update cost per step, single (N = 1) and batched (N = 1024).

``fawtgym bench wind`` prints, measured in one run on this machine:

* ``wind.step``, ``AeroModel.wrench``, the sensor law (``mocap_imu``) and the motor lag of one control step (5
  substeps) per call for N = 1 and N = 1024 (and per env); each is a compiled kernel over rows, called once
  before timing so that compilation (or loading it from the cache) is not timed;
* the env's own call into the wind (:meth:`~fawtgym.envs.wind_cohorts.BatchWind.step`, shared mode: no input
  re-validation), averaged over a whole noise block (so the per-row refill of the gust normals is included),
  and the wind's part of a reset: all N rows (``HoverBatchEnv.reset``) and 1/8 of them restarting while the
  others fly (autoreset), each row from its own seed;
* the env step cost with ``wind="calm"`` and ``wind="fawt-50"``, alternating single steps so that
  machine load affects both alike, and their ratio (target: the FAWT wind adds <= 20 %).  Both hover at the
  FAWT point under the PX4 cascade (:class:`~fawtgym.agents.PX4Agent`, not timed), so the FAWT env meets the
  airspeeds of a real hover in the jet (an open-loop vehicle is blown away: its ever-new airspeeds would
  time the one-off filling of the Dryden step-matrix table instead of the wind);
* the same comparison for the batched env (:class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv`, N vehicles,
  one batch-first PX4 agent, not timed), per vehicle-step;
* a numpy reference op (``a + b`` on a (1, 3) array) so numbers from loaded machines can be compared.

Times are CPU time of this process (``time.process_time``), best of several repeats, so other jobs on
a shared machine distort them less than wall-clock time.  The first env block of each wind is a
warm-up (it fills the Dryden step-matrix table for the airspeeds met) and is not counted.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from fawtgym.cli_parser import ArgumentParser, positive_int
from fawtgym.core.frames import FAWT_HOVER_POINT_NED
from fawtgym.envs.aero import AeroModel
from fawtgym.envs.motors import decay_factors, lag_thrusts, substep_times
from fawtgym.envs.sensors_batch import BatchSensorModel
from fawtgym.envs.vehicles import make_vehicle
from fawtgym.envs.wind import make_wind
from fawtgym.envs.wind_cohorts import BatchWind


def _best_per_call(fn: Callable[[], object], calls: int, repeats: int = 5) -> float:
    """Best-of-``repeats`` mean time per call [s] (the minimum is the least load-disturbed estimate)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        for _ in range(calls):
            fn()
        best = min(best, (time.process_time() - t0) / calls)
    return best


def wind_aero_costs(n: int, calls: int, preset: str = "fawt-50", vehicle: str = "s500") -> dict[str, float]:
    """Per-call seconds of ``wind.step``, ``aero.wrench``, both, the sensor law and the motor lag of one 5 ms step (5
    substeps) with ``n`` vehicles hovering at the FAWT point (each called once first: compile/warm-up)."""
    p = make_vehicle(vehicle)
    wind = make_wind(preset)
    wind.reset(n, seed=0)
    aero = AeroModel(p)
    pts = np.broadcast_to(np.vstack([FAWT_HOVER_POINT_NED, FAWT_HOVER_POINT_NED + p.rotor_positions]),
                          (n, 5, 3)).copy()
    vel = np.zeros((n, 3))
    rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    rate = np.zeros((n, 3))
    omega = np.full((n, 4), p.hover_omega)
    state: dict[str, Any] = {"t": 0.0, "w": wind.step(0.01, 0.01, pts, vel)}
    sensor = BatchSensorModel("mocap_imu", 0.005, n)
    sensor.reset_rows(np.arange(n), [np.random.default_rng(i) for i in range(n)])
    times = np.zeros(n)
    up, down = decay_factors(p, substep_times(0.005, 5))
    ref = np.full((n, 4), 1.01 * p.hover_omega)
    ctrl, speeds, mean = np.zeros((n, 5, 10)), np.empty((n, 4)), np.empty((n, 4))

    def step_wind() -> None:
        state["t"] += 0.01
        state["w"] = wind.step(state["t"], 0.01, pts, vel)

    def step_aero() -> None:
        aero.wrench(rot, vel, rate, omega, state["w"])

    def both() -> None:
        step_wind()
        step_aero()

    def measure() -> None:
        sensor.measure(times, pts[:, 0], vel, rot, rate, vel)

    def lag() -> None:
        lag_thrusts(ref, omega, up, down, p.k_thrust, ctrl, speeds, mean)

    for fn in (step_aero, measure, lag):  # compile (or load from the cache) before timing
        fn()
    return {"wind": _best_per_call(step_wind, calls), "aero": _best_per_call(step_aero, calls),
            "both": _best_per_call(both, calls), "sensors": _best_per_call(measure, calls),
            "motors": _best_per_call(lag, calls)}


def batch_wind_costs(n: int, preset: str = "fawt-50", vehicle: str = "s500") -> dict[str, float]:
    """Per-call seconds of the env's wind call ``BatchWind.step`` (averaged over one noise block, refill included),
    of a reset of all ``n`` rows and of a restart of ``n // 8`` rows (at least one), hovering at the FAWT point."""
    p = make_vehicle(vehicle)
    wind = BatchWind(make_wind(preset), n)
    pts = np.broadcast_to(np.vstack([FAWT_HOVER_POINT_NED, FAWT_HOVER_POINT_NED + p.rotor_positions]),
                          (n, 5, 3)).copy()
    vel, times = np.zeros((n, 3)), np.zeros(n)
    rows, some = np.arange(n), np.arange(0, n, 8)
    ints = [1000 + i for i in range(n)]

    seeds = [np.random.SeedSequence(i).spawn(2)[0] for i in ints]  # the env's per-row wind seeds (made untimed)
    some_ints, some_seeds = [ints[i] for i in some.tolist()], [seeds[i] for i in some.tolist()]

    def reset_all() -> None:
        wind.reset_rows(rows, ints, seeds)

    def restart_some() -> None:
        wind.reset_rows(some, some_ints, some_seeds)

    def step() -> None:
        wind.step(times, 0.01, pts, vel)

    reset_all()
    step()  # compile (or load from the cache), fill the step-matrix bins met
    block = getattr(getattr(wind.model, "process", None), "block", 1)
    return {"step": _best_per_call(step, block * max(1, 4096 // (block * n))),
            "reset": _best_per_call(reset_all, 1, 3), "restart": _best_per_call(restart_some, 1, 3)}


def env_costs(steps: int, blocks: int) -> dict[str, float] | None:
    """Per-step seconds of the hover env with calm and FAWT-50 wind, interleaved; None if the env is missing."""
    try:
        import gymnasium as gym

        import fawtgym  # noqa: F401  (registers the ids)
        from fawtgym.agents import PX4Agent
        envs = {name: gym.make("fawtgym/Hover-v0", wind=name, init_noise=0.0, episode_seconds=1e6)
                for name in ("calm", "fawt-50")}
    except Exception as exc:  # report instead of failing
        print(f"env benchmark skipped: {type(exc).__name__}: {exc}")
        return None
    agents = {name: PX4Agent.for_env(env) for name, env in envs.items()}
    infos = {}

    def reset(name: str) -> None:
        _, infos[name] = envs[name].reset(seed=0)
        agents[name].reset(infos[name])

    for name in envs:
        reset(name)
    totals: dict[str, list[float]] = {name: [] for name in envs}
    for _ in range(blocks):
        t_sum = dict.fromkeys(envs, 0.0)
        for _ in range(steps):  # alternate single steps so both envs see the same machine load
            for name, env in envs.items():
                action = agents[name].act(None, infos[name]).astype(np.float32)
                t0 = time.process_time()
                _, _, term, trunc, infos[name] = env.step(action)
                t_sum[name] += time.process_time() - t0
                if term or trunc:
                    reset(name)
        for name in envs:
            totals[name].append(t_sum[name] / steps)
    for env in envs.values():
        env.close()
    return {name: float(np.median(v[1:] if len(v) > 1 else v)) for name, v in totals.items()}


def batch_env_costs(n: int, steps: int, blocks: int) -> dict[str, float]:
    """Per-vehicle-step seconds of HoverBatchEnv(n) with calm and FAWT-50 wind, blocks interleaved, under PX4."""
    from fawtgym.agents import PX4Agent
    from fawtgym.envs.hover_batch_env import HoverBatchEnv

    envs = {name: HoverBatchEnv(n, wind=name, init_noise=0.0, episode_seconds=1e6) for name in ("calm", "fawt-50")}
    agents = {name: PX4Agent.for_env(env) for name, env in envs.items()}
    infos = {}
    for name, env in envs.items():
        _, infos[name] = env.reset(seed=0)
        agents[name].reset(infos[name])
    totals: dict[str, list[float]] = {name: [] for name in envs}
    for _ in range(blocks):
        for name, env in envs.items():
            t_sum = 0.0
            for _ in range(steps):
                actions = agents[name].act(None, infos[name]).astype(np.float32)
                t0 = time.process_time()
                _, _, _, _, infos[name] = env.step(actions)
                t_sum += time.process_time() - t0
            totals[name].append(t_sum / (steps * n))
    return {name: float(np.median(v[1:] if len(v) > 1 else v)) for name, v in totals.items()}


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="fawtgym bench wind", description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=positive_int, default=2000, help="calls per timing repeat for N = 1")
    parser.add_argument("--batch", type=positive_int, default=1024, help="batched N (default 1024)")
    parser.add_argument("--env-steps", type=positive_int, default=200, help="env steps per block")
    parser.add_argument("--env-blocks", type=positive_int, default=5, help="interleaved blocks per wind")
    parser.add_argument("--no-env", action="store_true", help="skip the env comparisons")
    parser.add_argument("--env-batch", type=positive_int, default=256, help="N of the batched env comparison")
    ns = parser.parse_args(argv)
    a, b = np.zeros((1, 3)), np.ones((1, 3))
    ref = _best_per_call(lambda: a + b, 20000)
    print(f"numpy reference op (1,3)+(1,3): {ref * 1e6:.2f} us")
    single = wind_aero_costs(1, ns.calls)
    batch = wind_aero_costs(ns.batch, max(ns.calls // 20, 20))
    print(f"{'':22s}{'N = 1 [us]':>12s}{f'N = {ns.batch} [us]':>16s}{'per env [us]':>14s}")
    for key, label in (("wind", "wind.step (fawt-50)"), ("aero", "aero.wrench"), ("both", "wind + aero"),
                       ("sensors", "sensors (mocap_imu)"), ("motors", "motor lag (5 subst.)")):
        print(f"{label:22s}{single[key] * 1e6:12.1f}{batch[key] * 1e6:16.1f}{batch[key] / ns.batch * 1e6:14.3f}")
    print(f"wind + aero, N = 1, in numpy reference ops: {single['both'] / ref:.0f}")
    bw1, bwn = batch_wind_costs(1), batch_wind_costs(ns.batch)
    print(f"{'env wind call (shared)':22s}{bw1['step'] * 1e6:12.2f}{bwn['step'] * 1e6:16.1f}"
          f"{bwn['step'] / ns.batch * 1e6:14.3f}   (BatchWind.step over a noise block, refill included)")
    print(f"{'wind reset, all rows':22s}{bw1['reset'] * 1e6:12.1f}{bwn['reset'] * 1e6:16.1f}"
          f"{bwn['reset'] / ns.batch * 1e6:14.3f}")
    print(f"{'wind restart 1/8 rows':22s}{'':12s}{bwn['restart'] * 1e6:16.1f}"
          f"{bwn['restart'] / max(ns.batch // 8, 1) * 1e6:14.3f}   (per restarted row)")
    if not ns.no_env:
        env = env_costs(ns.env_steps, ns.env_blocks)
        if env is not None:
            ratio = env["fawt-50"] / env["calm"]
            print(f"env step, calm:    {env['calm'] * 1e6:8.1f} us")
            print(f"env step, fawt-50: {env['fawt-50'] * 1e6:8.1f} us")
            verdict = "meets" if ratio <= 1.20 else "misses"
            print(f"ratio fawt-50 / calm: {ratio:.3f}  (wind adds {100 * (ratio - 1):.1f} %; "
                  f"{verdict} the <= 20 % target)")
        benv = batch_env_costs(ns.env_batch, max(ns.env_steps // 10, 5), ns.env_blocks)
        ratio = benv["fawt-50"] / benv["calm"]
        print(f"batched env (N = {ns.env_batch}), per vehicle-step: calm {benv['calm'] * 1e6:.1f} us, "
              f"fawt-50 {benv['fawt-50'] * 1e6:.1f} us")
        print(f"ratio fawt-50 / calm, batched: {ratio:.3f}  (wind adds {100 * (ratio - 1):.1f} %; "
              f"{'meets' if ratio <= 1.20 else 'misses'} the <= 20 % target)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
