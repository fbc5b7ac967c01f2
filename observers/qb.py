"""Runtime QB disturbance observer (Cayero et al. (2019)): no cvxpy, no solver.

The gain ``L`` is designed offline by the SDP of :mod:`fawtgym.observers.qb_design` (eqs. 7, 30, 31,
line search of eq. 25) on the momentum model of :mod:`fawtgym.observers.qb_uav_model` and saved
in an ``.npz`` file TOGETHER WITH its design inputs (A, B, C, D, W1, W2, Q, E1, r, alpha, mu, the
vehicle mass/inertia the noise ellipsoid Q2 refers to, the volume and P).  Running the observer
only loads that file.

Mapping to the env (``info["measurement"]`` and ``info["applied"]``): at each control step, with the measurement
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
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm

from fawtgym.core import measurement as M
from fawtgym.core.checks import shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.kernel_types import NO_REFCOUNT
from fawtgym.core.rows import write_rows

from ._checks import first_bad_wrench
from .base import DIVIDING_MIN_DT, BufferStates, Observer, ObserverEstimate, register_observer
from .qb_uav_model import momentum_input_row, momentum_output, momentum_output_row

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
            raise ValueError(f"QB gain files are .npz, got {shown(path.name)}")
        meta = dict(self.meta)
        meta.update(alpha=self.alpha, mu=self.mu, log_volume=self.log_volume)
        np.savez(path, meta=np.array(json.dumps(meta, sort_keys=True)),
                 **{k: getattr(self, k) for k in _ARRAYS})
        return path


def resolve_gain_path(gain_file: str | os.PathLike[str] | None) -> Path:
    """A path, or a shipped gain's name (``"qb_gain_hummingbird_mu0p2"``), or None for the default."""
    if gain_file is None:
        gain_file = DEFAULT_GAIN
    if not isinstance(gain_file, (str, os.PathLike)):
        raise ValueError(f"gain_file must be None (the shipped gain for the vehicle), a path or a shipped gain's name, "
                         f"got {shown(gain_file)} ({type(gain_file).__name__})")
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


@njit(cache=True, **NO_REFCOUNT)
def _estimate_row(x, R, mass, J_inv, force, torque, velocity, omega, derivs):
    """The estimate of one row from its state x = (p_lin, p_ang, d_f, d_tau, d', ...) (eqs. 35, 42) and attitude R:
    force d_f (world NED), torque R^T d_tau (body FRD), velocity p_lin / m, Omega = J^-1 R^T p_ang."""
    for k in range(3):
        force[k] = x[6 + k]
        torque[k] = R[0, k] * x[9] + R[1, k] * x[10] + R[2, k] * x[11]
        velocity[k] = x[k] / mass
    b0 = R[0, 0] * x[3] + R[1, 0] * x[4] + R[2, 0] * x[5]
    b1 = R[0, 1] * x[3] + R[1, 1] * x[4] + R[2, 1] * x[5]
    b2 = R[0, 2] * x[3] + R[1, 2] * x[4] + R[2, 2] * x[5]
    for k in range(3):
        omega[k] = J_inv[k, 0] * b0 + J_inv[k, 1] * b1 + J_inv[k, 2] * b2
    for k in range(derivs.shape[0]):
        derivs[k] = x[12 + k]


@njit(cache=True, **NO_REFCOUNT)
def _estimate_rows(x, R, mass, J_inv, out):
    """:func:`_estimate_row` of every row into ``out`` (N, 12 + n_d): force | torque | velocity | Omega | d', ..."""
    for i in range(x.shape[0]):
        o = out[i]
        _estimate_row(x[i], R[i], mass, J_inv, o[0:3], o[3:6], o[6:9], o[9:12], o[12:])


def _estimate_views(out: NDArray[np.float64]) -> ObserverEstimate:
    """The estimate as views of the one buffer the kernels write (:func:`_estimate_rows`)."""
    return ObserverEstimate(force=out[:, 0:3], torque=out[:, 3:6], states=BufferStates(out, _STATES))


#: the estimate's states: columns of the buffer (the derivatives: the rest) and trailing shapes
_STATES = {"velocity": (6, 9, (3,)), "angular_velocity": (9, 12, (3,)), "disturbance_derivatives": (12, None, (-1,))}


@njit(cache=True, **NO_REFCOUNT)
def _qb_rows(x, y_prev, R_prev, R, velocity, rate, specific_force, thrust, torque, mass, gravity, J, J_inv,
             stacked, x_out, y_out, out, work):
    """One update of every row: u_k (eq. 52) with Rbar = (R_prev + R) / 2, y_{k+1} (eq. 54), then
    x_{k+1} = Phi x_k + Gu u_k + Gy0 y_k + Gy1 (y_{k+1} - y_k) as the product z @ ``stacked`` of the row
    z = [x, u, y_prev, y] (:func:`discretize`), and the estimate into ``out`` (:func:`_estimate_rows`).

    The product is a loop of its own per row, summed in one fixed order, so a row's result does not depend on the
    other rows (a BLAS product of the whole batch, z (N, k) @ stacked, picks its kernel and blocking by N: row i
    of an N = 5 batch then differed from the same vehicle at N = 1 at rounding level).

    ``work`` (nz + 9,) is scratch: the kernel allocates nothing (it and its row laws are
    :data:`~fawtgym.core.kernel_types.NO_REFCOUNT`)."""
    n, nx = x.shape
    nz = stacked.shape[0]
    z = work[:nz]
    Rbar = work[nz:nz + 9].reshape(3, 3)
    for i in range(n):
        for j in range(nx):
            z[j] = x[i, j]
        for j in range(3):
            for k in range(3):
                Rbar[j, k] = 0.5 * (R_prev[i, j, k] + R[i, j, k])
        momentum_input_row(mass, gravity, Rbar, thrust[i], torque[i], z[nx:nx + 6])
        for j in range(9):
            z[nx + 6 + j] = y_prev[i, j]
        momentum_output_row(mass, J, R[i], velocity[i], rate[i], specific_force[i], thrust[i], y_out[i])
        for j in range(nz - nx - 15):
            z[nx + 15 + j] = y_out[i, j]
        xi = x_out[i]
        for j in range(nx):
            xi[j] = 0.0
        for k in range(nz):          # x_{k+1} = sum_k z_k stacked[k, :], k in order (eq. 3 discretized)
            zk = z[k]
            for j in range(nx):
                xi[j] += zk * stacked[k, j]
    _estimate_rows(x_out, R, mass, J_inv, out)


#: distinct step lengths whose discretization (one matrix exponential each) is kept
_DISC_CACHE = 8


@register_observer("qb")
class QBObserver(Observer):
    """Quadratic-boundedness optimal disturbance observer on the momentum model (Cayero et al. (2019) Secs. 2-4).

    ``make_observer("qb", mass, inertia)`` loads the shipped mu = 0.5, r = 3 gain designed for this
    mass/inertia if there is one (``qb_gain_<vehicle>_mu0p5.npz``: hummingbird, s500, x500,
    pounds_x4), else the Hummingbird gain (with a warning); ``gain_file`` selects another saved gain
    (path or shipped name).  Estimates force and torque.
    """

    channels = frozenset({"force", "torque"})
    required_keys = (M.ATTITUDE, M.VELOCITY, M.ANGULAR_VELOCITY, M.SPECIFIC_FORCE)
    #: the discretization is exact (stable at any step), but u is held over the step with the attitude averaged,
    #: Rbar = (R_prev + R) / 2, which is second-order accurate only while the vehicle turns little over dt:
    #: 0.1 s at 1 rad/s is 0.1 rad (the paper's simulation is continuous-time)
    max_dt = 0.1
    #: the shortest update step [s] (checked by :meth:`Observer.update`): the first-order hold of y is integrated with
    #: y's rate (y_{k+1} - y_k) / dt (:func:`discretize`), which overflows for a subnormal dt
    min_dt = DIVIDING_MIN_DT
    min_dt_reason = "the first-order hold divides by dt"
    #: the collective thrust [N] of the accelerometer term of y at reset: a number or one per row
    reset_options = {"thrust": ()}

    def __init__(self, mass: float, inertia: ArrayLike, gain_file: str | os.PathLike[str] | None = None,
                 gravity: float = GRAVITY) -> None:
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
        self._J = np.ascontiguousarray(self.inertia)
        self._J_inv = np.ascontiguousarray(self.inertia_inv)
        #: state: x (N, n_x), the previous output y (N, 9) and attitude R (N, 3, 3)
        self._x: NDArray[np.float64] = np.empty((0, 0))
        self._y: NDArray[np.float64] = np.empty((0, 9))
        self._R: NDArray[np.float64] = np.empty((0, 3, 3))

    # -------------------------------------------------------------------------------
    def reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None = None,
              torque: ArrayLike | None = None, thrust: ArrayLike | None = None, *,
              rows: ArrayLike | None = None, **options: Any) -> None:
        """Start from the measured momenta; d from ``force``/``torque`` if given, else force from the
        accelerometer (needs ``thrust``, default m g) and zero torque; derivatives zero.

        ``thrust``: the collective thrust [N] the accelerometer term of y uses, a number or one per row (N,);
        ``rows``: as :meth:`Observer.reset` (with a mask, a (N,) ``thrust`` still gives all N rows)."""
        super().reset(measurement, force, torque, rows=rows, thrust=thrust, **options)

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None, **options: Any) -> int:
        """State: ``_x`` (N, n_x), the previous output ``_y`` (N, 9) and attitude ``_R`` (N, 3, 3)."""
        thrust = options.get("thrust")      # checked by Observer.reset: None, a number or one per row of measurement
        meas = M.batch_measurement(measurement)
        R = meas[M.ATTITUDE]
        n_b = R.shape[0]
        f = np.broadcast_to(self.mass * self.gravity if thrust is None else thrust, (n_b,)).copy()
        y = momentum_output(self.mass, self._J, R, meas[M.VELOCITY], meas[M.ANGULAR_VELOCITY],
                            meas[M.SPECIFIC_FORCE], f)
        x = np.zeros((n_b, self.gain.A.shape[0]))
        x[:, :9] = y
        if force is not None:       # checked by Observer.reset: (3,) or one per row, finite
            x[:, 6:9] = np.broadcast_to(force, (n_b, 3))
        if torque is not None:
            x[:, 9:12] = np.einsum("nij,nj->ni", R, np.broadcast_to(torque, (n_b, 3)))
        if not np.all(np.isfinite(x)):
            raise ValueError("qb: reset: the initial state is not finite (check the measurement and the guesses)")
        self._check_initial_estimate(x, np.ascontiguousarray(R), rows)
        self._x, self._y, self._R = write_rows((self._x, self._y, self._R), (x, y, np.ascontiguousarray(R)), rows)
        return n_b

    def _check_initial_estimate(self, x: NDArray[np.float64], R: NDArray[np.float64],
                                rows: NDArray[np.bool_] | None) -> None:
        """ValueError (before anything is stored) if the estimate of a fresh state ``x`` of the rows reset is beyond the
        divergence bound (:meth:`Observer.estimate_bounds`): without a force guess the initial force comes from the
        accelerometer and ``thrust``, so a finite but absurd thrust would make every later update raise."""
        out = np.empty(x.shape)
        _estimate_rows(x, R, self.mass, self._J_inv, out)
        bounds = self.estimate_bounds()
        code = first_bad_wrench(out[:, 0:3], out[:, 3:6], *bounds)
        if code >= 0:
            row, channel = code // 2, code % 2
            batch_row = row if rows is None else int(np.flatnonzero(rows)[row])
            value = out[row, 3 * channel:3 * channel + 3].tolist()
            raise ValueError(f"qb: reset: the initial {('force', 'torque')[channel]} estimate is beyond the divergence "
                             f"bound of the estimate (row {batch_row}: {value}; "
                             f"allowed: |component| <= {bounds[channel]:.10g}; an update refuses a larger estimate): "
                             "check the measurement and thrust")

    def _update(self, meas: dict[str, NDArray[np.float64]], thrust: NDArray[np.float64],
                torque: NDArray[np.float64], dt: float) -> tuple[ObserverEstimate, Any]:
        """One kernel call (:func:`_qb_rows`); the new state (x, y, R) is stored by :meth:`_commit`."""
        n, nx = self._x.shape
        stacked = self._stacked(dt)
        c = np.ascontiguousarray
        R = c(meas[M.ATTITUDE])
        x, y, out = np.empty((n, nx)), np.empty((n, 9)), np.empty((n, nx))
        _qb_rows(self._x, self._y, self._R, R, c(meas[M.VELOCITY]), c(meas[M.ANGULAR_VELOCITY]),
                 c(meas[M.SPECIFIC_FORCE]), c(thrust), c(torque), self.mass, self.gravity, self._J, self._J_inv,
                 stacked, x, y, out, np.empty(stacked.shape[0] + 9))
        return _estimate_views(out), (x, y, R.copy())

    def _commit(self, state: Any) -> None:
        self._x, self._y, self._R = state

    def snapshot(self) -> Any:
        return self._x, self._y, self._R

    def _stacked(self, dt: float) -> NDArray[np.float64]:
        """The discrete step for ``dt`` (in [:attr:`min_dt`, :attr:`max_dt`], checked by :meth:`Observer.update`) as
        one matrix (cached for the last few distinct dt)."""
        stacked = self._disc.get(dt)
        if stacked is None:
            phi, gu, gy0, gy1 = discretize(self.gain, dt)
            # x+ = Phi x + Gu u + Gy0 y_prev + Gy1 (y - y_prev), as one product with [x, u, y_prev, y]
            stacked = np.ascontiguousarray(np.vstack([phi.T, gu.T, (gy0 - gy1).T, gy1.T]))
            if len(self._disc) >= _DISC_CACHE:
                self._disc.pop(next(iter(self._disc)))
            self._disc[dt] = stacked
        return stacked

    def estimate(self) -> ObserverEstimate:
        """The current estimate (after reset/update)."""
        if self._n_rows is None:
            raise RuntimeError("qb: estimate() before reset(); call reset(measurement) first")
        out = np.empty(self._x.shape)
        _estimate_rows(self._x, self._R, self.mass, self._J_inv, out)
        return _estimate_views(out)


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
