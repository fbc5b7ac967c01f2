"""``fawtgym bench qb-sdp``: one QB-observer SDP (Cayero et al. (2019) eq. 31 at fixed alpha) and the runtime update.

The SDP is the Sec. 4 design (r = 3: n = 24, LMI (7) of size 39, log-det over 6x6), timed from
problem construction to solution (cvxpy compilation + solver), best of ``--rounds``.  The runtime
:class:`~fawtgym.observers.qb.QBObserver` update is timed at N = 1 and N = 1024 in the
same run; the ratio (time per vehicle at N = 1024) / (time at N = 1) shows what batching buys,
and (SDP time) / (one update) the offline/online split.  Best round kept (least disturbed by load).
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Sequence

import numpy as np

from fawtgym.cli_parser import ArgumentParser, positive_float, positive_int
from fawtgym.core.constants import GRAVITY
from fawtgym.core.so3 import exp_so3
from fawtgym.observers.qb import QBObserver
from fawtgym.observers.qb_design import lmi_residuals, solve_qb_lmi
from fawtgym.observers.qb_uav_model import HUMMINGBIRD_INERTIA, HUMMINGBIRD_MASS, uav_model


def time_sdp(alpha: float, r: int, solver: str | None, rounds: int) -> dict[str, float]:
    best, sol, best_solver = np.inf, None, np.inf
    pr = uav_model(r=r)
    for _ in range(rounds):
        t0 = time.perf_counter()
        sol = solve_qb_lmi(pr, alpha, solver=solver)
        took = time.perf_counter() - t0
        if took < best:
            best, best_solver = took, sol.solve_seconds
    assert sol is not None
    res = lmi_residuals(pr, sol)
    return {"seconds": best, "solver_seconds": best_solver, "log_volume": sol.log_volume,
            "lmi7_rel": res["lmi7_max_eig"] / res["lmi7_scale"], "n": pr.n}


def time_update(n: int, steps: int, rounds: int) -> float:
    """Best seconds per update call for a batch of n vehicles."""
    rng = np.random.default_rng(0)
    meas = {"velocity": rng.normal(size=(n, 3)), "attitude": exp_so3(0.1 * rng.normal(size=(n, 3))),
            "angular_velocity": 0.1 * rng.normal(size=(n, 3)),
            "specific_force": np.tile([0.0, 0.0, -GRAVITY], (n, 1))}
    thrust = np.full(n, HUMMINGBIRD_MASS * GRAVITY)
    torque = np.zeros((n, 3))
    obs = QBObserver(HUMMINGBIRD_MASS, HUMMINGBIRD_INERTIA)
    obs.reset(meas)
    obs.update(meas, thrust, torque, 0.01)  # builds the discretization cache
    best = np.inf
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(steps):
            obs.update(meas, thrust, torque, 0.01)
        best = min(best, (time.perf_counter() - t0) / steps)
    return best


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="fawtgym bench qb-sdp", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--alpha", type=positive_float, default=5.0, help="decay rate alpha (default 5)")
    parser.add_argument("--order", type=positive_int, default=3, help="disturbance order r (paper: 3)")
    parser.add_argument("--solver", default=None, help="CLARABEL (default) or SCS")
    parser.add_argument("--rounds", type=positive_int, default=3, help="timing rounds (default 3)")
    parser.add_argument("--steps", type=positive_int, default=500, help="update calls per timing round")
    ns = parser.parse_args(list(argv) if argv is not None else None)
    from fawtgym.eval.reproduce.qb_observer import _check_solver

    _check_solver(parser, ns.solver)
    sdp = time_sdp(ns.alpha, ns.order, ns.solver, ns.rounds)
    t1 = time_update(1, ns.steps, ns.rounds)
    tn = time_update(1024, max(ns.steps // 10, 10), ns.rounds)
    print(f"QB observer SDP (eq. 31), r = {ns.order} (n = {sdp['n']}), alpha = {ns.alpha:g}, "
          f"solver {ns.solver or 'CLARABEL'}:")
    print(f"  one SDP, best of {ns.rounds}            {sdp['seconds']:10.3f} s  (solver part "
          f"{sdp['solver_seconds']:.3f} s; LMI (7) max eig / scale {sdp['lmi7_rel']:.1e})")
    print(f"  runtime update, N = 1            {t1 * 1e6:10.1f} us")
    print(f"  runtime update, N = 1024         {tn * 1e6:10.1f} us  ({tn / 1024 * 1e6:.2f} us per vehicle)")
    print(f"  ratio per-vehicle cost N=1024 / N=1   {tn / 1024 / t1:8.4f}")
    print(f"  ratio SDP / one N=1 update            {sdp['seconds'] / t1:10.3g}")
    print(f"  target: one SDP in seconds on this machine ; load average now "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return 0 if np.isfinite(sdp["seconds"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
