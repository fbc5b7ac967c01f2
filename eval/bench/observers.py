"""Per-update cost of every registered observer, single (N = 1) and batched (N = 1024).

``fawtgym bench observers [--repeats R] [--n N ...] [--only NAME ...]``

Every observer is built from the registry with its documented defaults (``make_observer(name, m, J)``, Wang et al.
(2024) vehicle m = 4.34 kg, J = diag(0.082, 0.0845, 0.1377)) and updated with a hover-like measurement.  The unit of
comparison is one MuJoCo physics step (``mj_step``) of a 4-rotor free body built inline and measured in the same run.
Times are process CPU time (``time.process_time``, best of ``--repeats`` repeats, default 9), so that other jobs on a
shared machine inflate them less (a VM's steal time still counts); the ratios are the robust figures.  Why 9: on the
2-core VM of 2026-11-24, idle but for this bench, one observer's mean update over 1000 calls swung 8.3 -> 14.9 us
within seconds; the best of 3 repeats (~20 ms each at N = 1) landed in such a slow phase for some observer in most
runs, the best of 9 (the whole bench ~4 s) did not.  Targets (issue 14, every observer): <= 10 us per single update
(N = 1), and per vehicle at N = 1024 cheaper than one mj_step.  Each observer is updated once before timing, so the
compiled kernels are loaded (or compiled) outside the timed loop.  The last lines time the Python validation layer
alone (:meth:`fawtgym.observers.base.Observer.update`'s Python checks in front of and behind the law, N = 1: the path
of inputs the compiled checks refuse), the layer an observer without a checked kernel pays around its law (the
compiled input checks, the estimate check and the store) and the FFTS-ESO's checked update (the checks inside its
kernel, :meth:`~fawtgym.observers.base.Observer._update_checked`) against its law alone.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Sequence

import numpy as np

from fawtgym.cli_parser import ArgumentParser, positive_int
from fawtgym.core.constants import GRAVITY as G

MASS = 4.34
INERTIA = np.diag([0.0820, 0.0845, 0.1377])

QUAD_XML = """
<mujoco model="bench_quad">
  <option timestep="0.001" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="quad" pos="0 0 1">
      <freejoint/>
      <inertial pos="0 0 0" mass="4.34" diaginertia="0.0820 0.0845 0.1377"/>
      <geom type="box" size="0.15 0.15 0.04" contype="0" conaffinity="0"/>
      <site name="r0" pos="0.2 0 0"/>
      <site name="r1" pos="0 0.2 0"/>
      <site name="r2" pos="-0.2 0 0"/>
      <site name="r3" pos="0 -0.2 0"/>
    </body>
  </worldbody>
  <actuator>
    <general site="r0" gear="0 0 1 0 0 0.02" ctrlrange="0 30"/>
    <general site="r1" gear="0 0 1 0 0 -0.02" ctrlrange="0 30"/>
    <general site="r2" gear="0 0 1 0 0 0.02" ctrlrange="0 30"/>
    <general site="r3" gear="0 0 1 0 0 -0.02" ctrlrange="0 30"/>
  </actuator>
</mujoco>
"""


def mj_step_seconds(steps: int = 5000, repeats: int = 5) -> float:
    """Best-of-``repeats`` mean CPU time of one mj_step of the inline 4-rotor free body, with MuJoCo's profiler timers
    off as the env runs its physics (``fawtgym/envs/mujoco_timers.py``)."""
    import mujoco

    from fawtgym.envs.mujoco_timers import suspended

    model = mujoco.MjModel.from_xml_string(QUAD_XML)
    data = mujoco.MjData(model)
    data.ctrl[:] = MASS * 9.81 / 4
    best = np.inf
    for _ in range(repeats):
        mujoco.mj_resetData(model, data)
        data.ctrl[:] = MASS * 9.81 / 4
        with suspended():
            t0 = time.process_time()
            for _ in range(steps):
                mujoco.mj_step(model, data)
            best = min(best, (time.process_time() - t0) / steps)
    return best


def hover_measurement(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """A plausible measurement for n vehicles near hover, with every key of fawtgym/core/measurement.py."""
    from fawtgym.core.measurement import EARTH_FIELD_NED
    from fawtgym.core.so3 import exp_so3

    r = exp_so3(0.05 * rng.standard_normal((n, 3)))
    w = 0.1 * rng.standard_normal((n, 3))
    return {"position": 0.01 * rng.standard_normal((n, 3)), "velocity": 0.05 * rng.standard_normal((n, 3)),
            "attitude": r, "angular_velocity": w, "gyro": w.copy(),
            "specific_force": np.einsum("nji,j->ni", r, np.array([0.0, 0.0, -G])),
            "magnetometer": np.einsum("nji,j->ni", r, EARTH_FIELD_NED), "time": np.zeros(n)}


def time_observer(name: str, n: int, repeats: int, rng: np.random.Generator) -> float:
    """Best-of mean CPU seconds per update(); raises what the observer raises."""
    from fawtgym.observers import make_observer

    obs = make_observer(name, MASS, INERTIA)
    meas = hover_measurement(n, rng)
    obs.reset(meas)
    f = np.full(n, MASS * G)
    tau = np.zeros((n, 3))
    dt = 1e-3
    obs.update(meas, f, tau, dt)          # warm-up: load (or compile) the kernels before timing
    # a full collection first: right after the qb observer at N = 1024, the next N = 1 loop timed 3-4 us slower per
    # update, whichever observer it was (ffts_eso too) and on main as on the compiled-checks branch
    # (2026-11-24), until a gc.collect(); each observer is timed from the same clean start
    gc.collect()
    calls = max(5, int(2000 / max(1, n ** 0.5)))
    best = np.inf
    for r in range(repeats):
        meas["time"] = np.full(n, r * calls * dt)
        t0 = time.process_time()
        for _k in range(calls):
            meas["time"] = meas["time"] + dt
            obs.update(meas, f, tau, dt)
        best = min(best, (time.process_time() - t0) / calls)
    return best


def validation_seconds(repeats: int, rng: np.random.Generator) -> float:
    """Best-of mean CPU seconds of the validation layer alone at N = 1: the input checks of
    :meth:`~fawtgym.observers.base.Observer.update` (dt, the four measurement keys of the FFTS-ESO with the
    rotation check, thrust and torque) and the estimate check, on an FFTS-ESO estimate."""
    from fawtgym.observers import make_observer
    from fawtgym.observers.base import check_dt, check_inputs, check_measurement

    obs = make_observer("ffts_eso", MASS, INERTIA)
    meas = hover_measurement(1, rng)
    obs.reset(meas)
    f, tau = np.full(1, MASS * G), np.zeros((1, 3))
    est = obs.update(meas, f, tau, 1e-3)
    keys, who, max_dt = obs.required_keys, obs.name, obs.max_dt
    calls = 5000
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        for _k in range(calls):
            check_dt(1e-3, max_dt, who)
            check_measurement(meas, keys, 1, who)
            check_inputs(f, tau, 1, who)
            obs._check_estimate(est, who)
        best = min(best, (time.process_time() - t0) / calls)
    return best


def layer_seconds(repeats: int, rng: np.random.Generator) -> float:
    """Best-of mean CPU seconds at N = 1 of :meth:`~fawtgym.observers.base.Observer.update` around a law that costs
    nothing: an LESO (the FFTS-ESO's four keys) whose ``_update`` returns a ready estimate and state.  What every
    observer without a checked kernel pays besides its law: the compiled input checks, the estimate check, the store
    and the Python between them."""
    from typing import Any

    from fawtgym.observers.leso import LESO

    meas = hover_measurement(1, rng)
    f, tau, dt = np.full(1, MASS * G), np.zeros((1, 3)), 1e-3
    law = LESO(MASS, INERTIA)
    law.reset(meas)
    ready = law._update({k: meas[k] for k in law.required_keys}, f, tau, dt)

    class Ready(LESO):
        def _update(self, meas: dict[str, np.ndarray], thrust: np.ndarray, torque: np.ndarray,
                    dt: float) -> tuple[Any, Any]:
            return ready

    obs = Ready(MASS, INERTIA)
    obs.reset(meas)
    obs.update(meas, f, tau, dt)
    calls = 5000
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        for _k in range(calls):
            obs.update(meas, f, tau, dt)
        best = min(best, (time.process_time() - t0) / calls)
    return best


def checked_update_seconds(repeats: int, rng: np.random.Generator) -> tuple[float, float]:
    """Best-of mean CPU seconds at N = 1 of an FFTS-ESO update (:meth:`~fawtgym.observers.base.Observer.update`:
    its inputs checked, the law and the estimate check in one compiled call, the estimate built) and of its law alone
    (:func:`~fawtgym.observers.ffts_eso.ffts_eso_step` on ready arrays, with the row checks it makes in its loops):
    the difference is what the shape checks and the Python around the law cost."""
    from fawtgym.observers.ffts_eso import FFTSESO, ffts_eso_step

    obs = FFTSESO(MASS, INERTIA)
    meas = hover_measurement(1, rng)
    obs.reset(meas)
    f, tau, dt = np.full(1, MASS * G), np.zeros((1, 3)), 1e-3
    est = obs.update(meas, f, tau, dt)
    x = np.ascontiguousarray(np.concatenate([est.states["position"], est.states["velocity"], est.force,
                                             est.states["angular_velocity"], est.torque,
                                             est.states["attitude"].reshape(1, 9)], axis=1))
    eps_t, eps_a = obs.eps_at(dt)
    gains = np.asarray(obs._gains)
    out = np.empty((2, 1, x.shape[1]))
    force_bound, torque_bound = obs.estimate_bounds()
    args = (x, meas["position"], meas["velocity"], meas["attitude"], meas["angular_velocity"], f, tau, dt, eps_t,
            eps_a, gains, force_bound, torque_bound, out[0], out[1])
    ffts_eso_step(*args)
    calls = 5000
    best_update = best_law = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        for _k in range(calls):
            obs.update(meas, f, tau, dt)
        best_update = min(best_update, (time.process_time() - t0) / calls)
        t0 = time.process_time()
        for _k in range(calls):
            ffts_eso_step(*args)
        best_law = min(best_law, (time.process_time() - t0) / calls)
    return best_update, best_law


def main(argv: Sequence[str] | None = None) -> int:
    ap = ArgumentParser(prog="fawtgym bench observers", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=positive_int, default=9, help="best-of repeats per measurement (default 9)")
    ap.add_argument("--n", type=positive_int, nargs="+", default=[1, 1024], help="batch sizes")
    ap.add_argument("--only", nargs="*", default=None, help="observer names (default: all registered)")
    ns = ap.parse_args(list(argv) if argv is not None else None)
    if ns.repeats < 1 or any(n < 1 for n in ns.n):
        raise ValueError(f"--repeats and --n must be >= 1, got {ns.repeats}, {ns.n}")
    import warnings

    from fawtgym.observers import observer_names

    names = ns.only or observer_names()
    unknown = sorted(set(names) - set(observer_names()))
    if unknown:
        raise ValueError(f"unknown observers {unknown}; valid: {observer_names()}")
    rng = np.random.default_rng(0)
    step = mj_step_seconds()
    print(f"one mj_step of a 4-rotor free body (inline MJCF): {step * 1e6:.2f} us CPU (the unit of the ratios)")
    header = "observer".ljust(22) + "".join(f"{'N=' + str(n) + ' us/update':>20}{'per-vehicle/mj_step':>22}"
                                           for n in ns.n)
    print(header)
    results: dict[tuple[str, int], float] = {}
    for name in names:
        row = name.ljust(22)
        for n in ns.n:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    sec = time_observer(name, n, ns.repeats, rng)
            except Exception as exc:   # report, don't hide: an observer that cannot run here says why
                row += f"{'error':>20}{type(exc).__name__:>22}"
                print(f"  ({name}, N={n}: {type(exc).__name__}: {exc})")
                continue
            results[(name, n)] = sec
            row += f"{sec * 1e6:>20.1f}{sec / n / step:>22.3f}"
        print(row)
    # targets: <= 10 us per single update, < 1 mj_step per vehicle at the largest N
    singles = {name: results[(name, 1)] * 1e6 for name in names if (name, 1) in results}
    if singles:
        slow = sorted(name for name, us in singles.items() if us > 10.0)
        slowest = max(singles, key=lambda k: singles[k])
        print(f"single update <= 10 us: {'met by all ' + str(len(singles)) if not slow else 'NOT met by ' + str(slow)}"
              f" (slowest {slowest} {singles[slowest]:.1f} us)")
    big = max(ns.n)
    if big >= 1024:  # the target is stated for N = 1024
        per = {name: results[(name, big)] / big / step for name in names if (name, big) in results}
        slow = sorted(name for name, r in per.items() if r >= 1.0)
        if per:
            largest = max(per, key=lambda k: per[k])
            print(f"per vehicle at N={big} < 1 mj_step: "
                  f"{'met by all ' + str(len(per)) if not slow else 'NOT met by ' + str(slow)}"
                  f" (largest {largest} {per[largest]:.3f})")
    layer = validation_seconds(ns.repeats, rng)
    print(f"Python validation layer alone (N = 1, the FFTS-ESO's inputs and estimate; the path of inputs the compiled "
          f"checks refuse): {layer * 1e6:.2f} us ({layer / step:.2f} mj_step)")
    around = layer_seconds(ns.repeats, rng)
    print(f"update around a free law (N = 1, an LESO whose law returns a ready estimate: the compiled input checks, "
          f"the estimate check, the store; what an observer without a checked kernel pays): {around * 1e6:.2f} us "
          f"({around / step:.2f} mj_step)")
    update, law = checked_update_seconds(ns.repeats, rng)
    print(f"ffts_eso checked update (N = 1): {update * 1e6:.2f} us, its law alone {law * 1e6:.2f} us: checks and "
          f"Python around the law {(update - law) * 1e6:.2f} us ({(update - law) / step:.2f} mj_step)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
