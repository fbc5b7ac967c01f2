"""Runtime QB disturbance observer (Cayero et al. (2019)): no cvxpy, no solver.

The gain ``L`` is designed offline by the SDP of :mod:`fawtgym.observers.qb_design` (eqs. 7, 30, 31,
line search of eq. 25) on the momentum model of :mod:`fawtgym.observers.qb_uav_model` and saved
in an ``.npz`` file TOGETHER WITH its design inputs (A, B, C, D, W1, W2, Q, E1, r, alpha, mu, the
vehicle mass/inertia the noise ellipsoid Q2 refers to, the volume and P).  Running the observer
only loads that file.

Mapping to the env (see ``/work/team/ENV_API.md``): at each control step, with the measurement
``R`` (``attitude``), ``v`` (``velocity``), ``Omega`` (``angular_velocity``), ``a_sf``
(``specific_force``) and the applied collective thrust ``f`` and rotor torque ``tau`` of
``info["applied"]``::

    u = (m g e3 - f Rbar e3,  Rbar tau)                (eq. 52; Rbar = mean of the previous and current R)
    y = (m v,  R J Omega,  R (m a_sf + f e3))          (eq. 54, typos corrected, see qb_uav_model)
    xhat_{k+1} = Phi xhat_k + Gu u_k + Gy0 y_k + Gy1 (y_{k+1} - y_k)

i.e. the observer ODE (eq. 3) ``xhat' = (A + L C) xhat + B u - L y`` integrated exactly over the
step with ``u`` held (zero-order hold; the applied inputs are step averages) and ``y`` linearly
interpolated between samples (first-order hold).  The paper does not state a discretization
(its design and simulation are continuous-time); exact discretization keeps the observer stable
at any step for the large gains of fast designs (|L| ~ 1e5 at alpha = 20).

Output: ``force`` = d_f (world NED), ``torque`` = R^T d_tau (body FRD; the model's torque is in the
world frame, eq. 34); ``states``: ``velocity`` = p_lin / m, ``angular_velocity`` = J^-1 R^T p_ang,
``disturbance_derivatives`` (N, 6(r-1)) = world-frame (d', ..., d^(r-1)).

Vehicle: the matrices of the design do not depend on m and J (pure selection/shift matrices), but
the noise ellipsoid Q2 (eq. 58) was identified for the AscTec Hummingbird (m = 1.023 kg) of Sec. 4.
The shipped gains ``qb_gain_hummingbird_mu{0p2,0p5,0p95}.npz`` are for that vehicle;
``qb_gain_{s500,x500,pounds_x4}_mu0p5.npz`` were designed with Q2 rescaled to those
presets (same velocity/rate/accelerometer errors, :func:`~fawtgym.observers.qb_uav_model.scaled_q2`)
and are picked automatically for a matching mass and inertia.  A gain runs on any vehicle (m and J
form u and y) but its guaranteed error ellipsoid refers to the noise it was designed for.
Design for another vehicle with ``fawtgym reproduce qb --design-for <preset>`` or
:func:`design_uav_gain` (which rescales Q2 with :func:`~fawtgym.observers.qb_uav_model.scaled_q2`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm

from fawtgym.core import measurement as M
from fawtgym.core.rows import write_rows

from ._obs_common import floats
from .base import Observer, ObserverEstimate, register_observer
from .qb_uav_model import momentum_input, momentum_output

GAIN_DIR = Path(__file__).resolve().parent
DEFAULT_GAIN = "qb_gain_hummingbird_mu0p5"
_ARRAYS = ("A", "B", "C", "D", "W1", "W2", "Q", "E1", "L", "P")


@dataclasses.dataclass(frozen=True, eq=False)
class QBGain:
    """A designed QB observer: the gain L and every input of its design (Cayero et al. (2019) eqs. 1-2, 7, 31)."""

    A: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    D: NDArray[np.float64]
    W1: NDArray[np.float64]
    W2: NDArray[np.float64]
    Q: NDArray[np.float64]
    E1: NDArray[np.float64]
    L: NDArray[np.float64]
    P: NDArray[np.float64]
    alpha: float
    mu: float | None
    log_volume: float
    meta: Mapping[str, Any]

    def __post_init__(self) -> None:
        n = self.A.shape[0]
        p = self.C.shape[0]
        if self.A.shape != (n, n) or self.C.shape[1] != n or self.L.shape != (n, p) or self.P.shape != (n, n):
            raise ValueError(f"inconsistent QB gain shapes: A {self.A.shape}, C {self.C.shape}, L {self.L.shape}, "
                             f"P {self.P.shape}")
        for k in _ARRAYS:
            if not np.all(np.isfinite(getattr(self, k))):
                raise ValueError(f"QB gain array {k} contains non-finite values")
        eig = np.linalg.eigvals(self.A + self.L @ self.C)
        if eig.real.max() >= 0:
            raise ValueError(f"QB gain is not stabilizing: max Re eig(A + L C) = {eig.real.max():.3g}")

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write an ``.npz`` with all arrays, alpha, mu, log-volume and a JSON ``meta`` string."""
        path = Path(path)
        if path.suffix != ".npz":
            raise ValueError(f"QB gain files are .npz, got {path.name!r}")
        meta = dict(self.meta)
        meta.update(alpha=self.alpha, mu=self.mu, log_volume=self.log_volume)
        np.savez(path, meta=np.array(json.dumps(meta, sort_keys=True)),
                 **{k: getattr(self, k) for k in _ARRAYS})
        return path


def resolve_gain_path(gain_file: str | os.PathLike[str] | None) -> Path:
    """A path, or a shipped gain's name (``"qb_gain_hummingbird_mu0p2"``), or None for the default."""
    if gain_file is None:
        gain_file = DEFAULT_GAIN
    p = Path(gain_file)
    if p.suffix == "" and not p.exists():
        p = GAIN_DIR / (p.name + ".npz")
    if not p.is_file():
        shipped = sorted(q.stem for q in GAIN_DIR.glob("qb_gain_*.npz"))
        raise ValueError(f"QB gain file {str(gain_file)!r} not found; shipped gains: {shipped}")
    return p


def shipped_gain_for(mass: float, inertia: ArrayLike, mu: float = 0.5) -> str:
    """Name of the shipped gain designed for this (mass, inertia) and mu (1 % match), else the default."""
    j = np.asarray(inertia, dtype=float)
    j = np.diag(j) if j.shape == (3,) else j
    for path in sorted(GAIN_DIR.glob("qb_gain_*.npz")):
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"])) if "meta" in z.files else {}
        if meta.get("mu") != mu or "mass" not in meta or "inertia" not in meta:
            continue
        jm = np.asarray(meta["inertia"], dtype=float)
        if abs(meta["mass"] - mass) <= 0.01 * mass and np.allclose(jm, j, rtol=0.01, atol=0.0):
            return path.stem
    return DEFAULT_GAIN


def load_gain(gain_file: str | os.PathLike[str] | None = None) -> QBGain:
    """Load a gain saved by :meth:`QBGain.save` (no cvxpy needed)."""
    path = resolve_gain_path(gain_file)
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in (*_ARRAYS, "meta") if k not in z.files]
        if missing:
            raise ValueError(f"QB gain file {path} lacks {missing}")
        arrays = {k: np.asarray(z[k], dtype=float) for k in _ARRAYS}
        meta = json.loads(str(z["meta"]))
    return QBGain(**arrays, alpha=float(meta.pop("alpha")), mu=meta.pop("mu"),
                  log_volume=float(meta.pop("log_volume")), meta=meta)


def discretize(gain: QBGain, dt: float) -> tuple[NDArray[np.float64], ...]:
    """(Phi, Gu, Gy0, Gy1): exact integration of eq. 3 over dt, u zero-order hold, y first-order hold."""
    A_cl = gain.A + gain.L @ gain.C
    Gu = gain.B + gain.L @ gain.D
    Gy = -gain.L
    n, m, p = A_cl.shape[0], Gu.shape[1], Gy.shape[1]
    big = np.zeros((n + m + 2 * p, n + m + 2 * p))
    big[:n, :n] = A_cl
    big[:n, n:n + m] = Gu
    big[:n, n + m:n + m + p] = Gy
    big[n + m:n + m + p, n + m + p:] = np.eye(p) / dt
    e = expm(big * dt)
    return e[:n, :n], e[:n, n:n + m], e[:n, n + m:n + m + p], e[:n, n + m + p:]


@register_observer("qb")
class QBObserver(Observer):
    """Quadratic-boundedness optimal disturbance observer on the momentum model (Cayero et al. (2019) Secs. 2-4).

    ``make_observer("qb", mass, inertia)`` loads the shipped mu = 0.5, r = 3 gain designed for this
    mass/inertia if there is one (``qb_gain_<vehicle>_mu0p5.npz``: hummingbird, s500, x500,
    pounds_x4), else the Hummingbird gain (with a warning); ``gain_file`` selects another saved gain
    (path or shipped name).  Estimates force and torque.
    """

    channels = frozenset({"force", "torque"})

    def __init__(self, mass: float, inertia: ArrayLike, gain_file: str | os.PathLike[str] | None = None,
                 gravity: float = 9.80665) -> None:
        super().__init__(mass, inertia, gravity)
        if gain_file is None:
            gain_file = shipped_gain_for(self.mass, self.inertia)
        self.gain = load_gain(gain_file)
        if self.gain.C.shape[0] != 9 or self.gain.A.shape[0] < 12 or self.gain.meta.get("model") != "uav_momentum":
            raise ValueError("gain_file must hold a gain designed on the UAV momentum model (qb_uav_model)")
        self.order = (self.gain.A.shape[0] - 6) // 6
        m_d = float(self.gain.meta.get("mass", mass))
        if abs(m_d - self.mass) > 0.01 * m_d:
            warnings.warn(f"QB gain {Path(str(gain_file)).name}: its noise ellipsoid Q2 was designed for "
                          f"m = {m_d} kg, used here with m = {self.mass} kg; for guarantees design for this "
                          f"vehicle (fawtgym reproduce qb --design-for <preset>)", stacklevel=2)
        self._disc: dict[float, NDArray[np.float64]] = {}
        self._x: NDArray[np.float64] | None = None
        self._y: NDArray[np.float64] | None = None
        self._R: NDArray[np.float64] | None = None
        self._single: tuple | None = None    # (x, x as floats, y as floats, R as floats) of the last N = 1 step
        self._synced = True                  # self._y, self._R up to date with self._single
        self._jl = self.inertia.tolist()
        self._jil = self.inertia_inv.tolist()

    # -------------------------------------------------------------------------------
    def _y_of(self, meas: Mapping[str, NDArray[np.float64]], thrust: NDArray[np.float64]) -> NDArray[np.float64]:
        for key in (M.ATTITUDE, M.VELOCITY, M.ANGULAR_VELOCITY, M.SPECIFIC_FORCE):
            if key not in meas:
                raise ValueError(f"QB observer needs measurement[{key!r}]; got keys {sorted(meas)}")
            if not np.all(np.isfinite(meas[key])):
                raise ValueError(f"measurement[{key!r}] contains non-finite values")
        return momentum_output(self.mass, self.inertia, meas[M.ATTITUDE], meas[M.VELOCITY],
                               meas[M.ANGULAR_VELOCITY], meas[M.SPECIFIC_FORCE], thrust)

    def reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None = None,
              torque: ArrayLike | None = None, thrust: ArrayLike | None = None, *,
              rows: ArrayLike | None = None) -> None:
        """Start from the measured momenta; d from ``force``/``torque`` if given, else force from the
        accelerometer (needs ``thrust``, default m g) and zero torque; derivatives zero.

        ``thrust``: the collective thrust [N] the accelerometer term of y uses, a number or one per row (N,);
        ``rows``: as :meth:`Observer.reset` (with a mask, a (N,) ``thrust`` still gives all N rows)."""
        super().reset(measurement, force, torque, rows=rows, thrust=thrust)

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None, thrust: ArrayLike | None = None) -> int:
        """State: ``_x`` (N, n_x), the previous output ``_y`` (N, 9) and attitude ``_R`` (N, 3, 3), behind the
        N = 1 float state ``_single`` when not ``_synced`` (synced before a masked write)."""
        if rows is not None and thrust is not None and np.shape(thrust) == rows.shape:
            thrust = np.asarray(thrust, dtype=float)[rows]
        meas = M.batch_measurement(measurement)
        R = meas.get(M.ATTITUDE)
        if R is None:
            raise ValueError("QB observer reset needs measurement['attitude']")
        n_b = R.shape[0]
        f = np.broadcast_to(np.asarray(self.mass * self.gravity if thrust is None else thrust, dtype=float),
                            (n_b,)).copy()
        y = self._y_of(meas, f)
        x = np.zeros((n_b, self.gain.A.shape[0]))
        x[:, :9] = y
        if force is not None:
            x[:, 6:9] = np.broadcast_to(np.asarray(force, dtype=float), (n_b, 3))
        if torque is not None:
            x[:, 9:12] = np.einsum("nij,nj->ni", R, np.broadcast_to(np.asarray(torque, dtype=float), (n_b, 3)))
        if not np.all(np.isfinite(x)):
            raise ValueError("QB observer reset: non-finite initial force/torque")
        self._sync_single()
        self._x, self._y, self._R = write_rows((self._x, self._y, self._R), (x, y, R.copy()), rows)
        self._single, self._synced = None, True
        return n_b

    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        if self._x is not None and self._x.shape[0] == 1:
            est = self._update_single(measurement, thrust, torque, dt)
            if est is not None:
                return est
        self._sync_single()
        meas, f, tau = self._inputs(measurement, thrust, torque, dt)
        if self._x is None or self._y is None or self._R is None:
            raise RuntimeError("QB observer: call reset(measurement) before update()")
        R = meas[M.ATTITUDE]
        n_b = self._x.shape[0]
        if R.shape[0] != n_b:
            raise ValueError(f"batch size changed from {n_b} (reset) to {R.shape[0]}; reset again")
        if f.shape != (n_b,):
            f = np.broadcast_to(f, (n_b,))
        if tau.shape != (n_b, 3):
            tau = np.broadcast_to(tau, (n_b, 3))
        stacked = self._stacked(dt)
        u = momentum_input(self.mass, self.gravity, 0.5 * (self._R + R), f, tau)
        y = self._y_of(meas, f)
        x = np.concatenate([self._x, u, self._y, y], axis=1) @ stacked
        if not np.all(np.isfinite(x)):
            raise FloatingPointError("QB observer state became non-finite")
        self._x, self._y, self._R = x, y, R.copy()
        return self.estimate()

    def _stacked(self, dt: float) -> NDArray[np.float64]:
        """The discrete step for ``dt`` as one matrix (cached per dt)."""
        key = float(dt)
        stacked = self._disc.get(key)
        if stacked is None:
            phi, gu, gy0, gy1 = discretize(self.gain, key)
            # x+ = Phi x + Gu u + Gy0 y_prev + Gy1 (y - y_prev), as one product with [x, u, y_prev, y]
            stacked = np.vstack([phi.T, gu.T, (gy0 - gy1).T, gy1.T])
            self._disc[key] = stacked
        return stacked

    def _sync_single(self) -> None:
        """Write y and R of the last N = 1 fast step into the numpy state (self._y, self._R)."""
        if not self._synced and self._single is not None:
            _, _, y, rm = self._single
            self._y, self._R = np.array([y]), np.array(rm).reshape(1, 3, 3)
        self._synced = True

    def _update_single(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
                       dt: float) -> ObserverEstimate | None:
        """N = 1 fast path: :meth:`update`'s u, y (eqs. 52, 54) and estimate in Python floats, one matrix product.

        Returns None, touching nothing, unless the step is a well-formed, finite N = 1 step; :meth:`update`'s
        general path then runs and raises its usual errors.
        """
        try:
            rm = floats(measurement[M.ATTITUDE])
            vm = floats(measurement[M.VELOCITY])
            om = floats(measurement[M.ANGULAR_VELOCITY])
            am = floats(measurement[M.SPECIFIC_FORCE])
            fl = floats(thrust)
            tq = floats(torque)
        except (KeyError, ValueError, TypeError):
            return None
        if (len(rm) != 9 or len(vm) != 3 or len(om) != 3 or len(am) != 3 or len(fl) != 1 or len(tq) != 3
                or not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0)
                or not math.isfinite(sum(rm) + sum(vm) + sum(om) + sum(am) + fl[0] + sum(tq))):
            return None
        stacked = self._stacked(dt)
        cache = self._single
        if cache is not None and cache[0] is self._x:
            xl, yp, rp = cache[1:]
        else:
            self._sync_single()
            xl, yp, rp = self._x[0].tolist(), self._y[0].tolist(), self._R[0].ravel().tolist()
        mass, f = self.mass, fl[0]
        t0, t1, t2 = tq
        # u (eq. 52) with Rbar = (R_prev + R) / 2
        b00, b01, b02, b10, b11, b12, b20, b21, b22 = (0.5 * (rp[k] + rm[k]) for k in range(9))
        u = [-f * b02, -f * b12, -f * b22 + mass * self.gravity,
             b00 * t0 + b01 * t1 + b02 * t2, b10 * t0 + b11 * t1 + b12 * t2, b20 * t0 + b21 * t1 + b22 * t2]
        # y (eq. 54): (m v, R J Omega, R (m a_sf + f e3))
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rm
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._jl
        w0, w1, w2 = om
        s0, s1, s2 = w0 * j00 + w1 * j01 + w2 * j02, w0 * j10 + w1 * j11 + w2 * j12, w0 * j20 + w1 * j21 + w2 * j22
        a0, a1, a2 = mass * am[0], mass * am[1], mass * am[2] + f
        y = [mass * vm[0], mass * vm[1], mass * vm[2],
             r00 * s0 + r01 * s1 + r02 * s2, r10 * s0 + r11 * s1 + r12 * s2, r20 * s0 + r21 * s1 + r22 * s2,
             r00 * a0 + r01 * a1 + r02 * a2, r10 * a0 + r11 * a1 + r12 * a2, r20 * a0 + r21 * a1 + r22 * a2]
        z = xl + u + yp + y
        x = np.fromiter(z, float, len(z)).reshape(1, -1) @ stacked
        xl = x[0].tolist()
        if not math.isfinite(sum(xl)):
            raise FloatingPointError("QB observer state became non-finite")
        self._x = x
        self._single = (x, xl, y, rm)     # self._y, self._R are written from it when needed (_sync_single)
        self._synced = False
        # estimate: torque = R^T d_tau, Omega = J^-1 R^T p_ang, velocity = p_lin / m
        d0, d1, d2 = xl[9:12]
        p0, p1, p2 = xl[3:6]
        q0, q1, q2 = r00 * p0 + r10 * p1 + r20 * p2, r01 * p0 + r11 * p1 + r21 * p2, r02 * p0 + r12 * p1 + r22 * p2
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self._jil
        out = np.array(xl[6:9] + [r00 * d0 + r10 * d1 + r20 * d2, r01 * d0 + r11 * d1 + r21 * d2,
                                  r02 * d0 + r12 * d1 + r22 * d2,
                                  xl[0] / mass, xl[1] / mass, xl[2] / mass,
                                  q0 * i00 + q1 * i01 + q2 * i02, q0 * i10 + q1 * i11 + q2 * i12,
                                  q0 * i20 + q1 * i21 + q2 * i22] + xl[12:])
        return ObserverEstimate(force=out[None, 0:3], torque=out[None, 3:6], states={
            "velocity": out[None, 6:9], "angular_velocity": out[None, 9:12], "disturbance_derivatives": out[None, 12:]})

    def estimate(self) -> ObserverEstimate:
        """The current estimate (after reset/update)."""
        self._sync_single()
        if self._x is None or self._R is None:
            raise RuntimeError("QB observer: call reset(measurement) first")
        x, R = self._x, self._R
        RT = np.swapaxes(R, 1, 2)
        torque = np.einsum("nij,nj->ni", RT, x[:, 9:12])
        omega = np.einsum("nij,nj->ni", RT, x[:, 3:6]) @ self.inertia_inv.T
        return ObserverEstimate(force=x[:, 6:9].copy(), torque=torque, states={
            "velocity": x[:, 0:3] / self.mass, "angular_velocity": omega,
            "disturbance_derivatives": x[:, 12:].copy()})


# ------------------------------------------------------------------ design (needs cvxpy) ----
def design_uav_gain(mass: float, inertia: ArrayLike, mu: float, r: int = 3,
                    alphas: Sequence[float] | None = None, solver: str | None = None,
                    q1_scale: float = 1.0e6, vehicle: str = "", sweep: Any = None) -> QBGain:
    """Design a QB gain for a vehicle (Q2 of eq. 58 rescaled by :func:`scaled_q2`) and the trade-off mu.

    Sweeps eq. 31 over ``alphas`` (default 0.05..20, 24 points), then the line search of eq. 25.
    A precomputed ``sweep`` (:class:`~fawtgym.observers.qb_design.AlphaSweep` of the same problem)
    skips the sweep.  Needs cvxpy (``pip install 'fawtgym[design]'``).
    """
    from .qb_design import anchors_from_sweep, optimal_alpha, sweep_alpha
    from .qb_uav_model import scaled_q2, uav_model

    problem = uav_model(r=r, q1_scale=q1_scale, q2=scaled_q2(mass, inertia))
    if sweep is None:
        grid = np.geomspace(0.05, 20.0, 24) if alphas is None else np.asarray(alphas, dtype=float)
        sweep = sweep_alpha(problem, grid, solver=solver)
    sol = optimal_alpha(problem, mu, sweep, solver=solver)
    anchors = anchors_from_sweep(sweep)
    j = np.asarray(inertia, dtype=float)
    j = np.diag(j) if j.shape == (3,) else j
    meta = {"model": "uav_momentum", "seed": "", "r": int(r), "mass": float(mass),
            "inertia": j.tolist(), "q1_scale": float(q1_scale), "vehicle": vehicle, "solver": sol.solver,
            "status": sol.status, "anchors": dataclasses.asdict(anchors),
            "equations": "LMI (7)+(30), max log det X (31), J_mu line search (21-25), Q of (58)-(59), E1 (60)"}
    arrays = problem.as_arrays()
    return QBGain(**arrays, L=sol.L, P=sol.P, alpha=sol.alpha, mu=float(mu), log_volume=sol.log_volume, meta=meta)
