"""PX4's hover-thrust estimator (``mc_hover_thrust_estimator`` + ``ZeroOrderHoverThrustEkf``), batch-first.

A one-state Kalman filter for the normalized hover thrust ``Th`` (enabled by ``MPC_USE_HTE = 1``, PX4's
default), re-derived from PX4's ZeroOrderHoverThrustEkf (Bresciani, PX4 v1.13/v1.14) and its module.
Measurement model, vertical axis positive up::

    a_z = g T_z / Th - g,        H = d a_z / d Th = -g T_z / Th^2

with ``T_z`` the vertical component of the normalized thrust setpoint and ``a_z`` the measured vertical
acceleration.  One step, in PX4's order:

1. predict: ``P += q dt^2`` (``q = HTE_HT_NOISE^2``; the state is a random walk).
2. measurement noise ``R = s * r``: the adapted accelerometer-noise variance ``r`` times a scale
   ``s = max(1, |v_xy| - HTE_VXY_THR + 1, |v_z| - HTE_VZ_THR + 1)`` that *inflates* the noise above the
   velocity thresholds (PX4 keeps fusing, less and less; it never stops).
3. innovation variance ``S = max(H P H + R, R)`` (the floor: never below the measurement noise),
   gain ``K = P H / S``, test ratio ``innov^2 / (gate^2 S)``.
4. if the ratio is < 1: ``Th <- clip(Th + K innov, Th_min, Th_max)``, ``P <- clip((1 - K H) P, 1e-10, 1)``
   and the residual is recomputed with the new ``Th``; else, if the low-passed signed test ratio exceeds
   0.2 in magnitude (a sustained offset: the hover thrust jumped), variance recovery ``P += 1e3 q dt^2``.
5. first-order low-pass filters (1 s) of the residual and of the signed test ratio (clipped to +-1);
   noise adaptation ``r <- clip((1 - a) r + a ((res - res_lpf)^2 + H P H), 1, 400)``, ``a = dt / (2 + dt)``
   (Akhlaghi et al. 2017, the bias-free residual).
6. validity: ``P < 1e-3`` (and, while not yet valid, a passing test ratio), held for 2 s before the
   estimate becomes valid (PX4's hysteresis); the position controller applies only valid estimates.

Bounds: ``[clip(MPC_THR_HOVER - HTE_THR_RANGE, 0, 0.8), clip(MPC_THR_HOVER + HTE_THR_RANGE, 0.2, 0.9)]``,
``MPC_THR_HOVER`` being the hover thrust the estimator starts from (here the agent's initial hover thrust).

Why it matters in the FAWT: any steady vertical aerodynamic force (rotor-disc lift in a cross-flow)
changes the thrust needed to hover.  Without the estimator the vertical velocity integrator absorbs it
(``a_z,sp != 0``), which makes PositionControl's horizontal tracking anti-windup see a "produced"
horizontal acceleration ``(1 - a_z,sp / g)`` times the demanded one and bleed the horizontal integrator,
leaving a steady position offset.  PX4 avoids this by re-estimating ``Th`` (and shifting the integrator,
``PositionControl::updateHoverThrust``).

The step is written once, as the row function :func:`hover_thrust_row` compiled by numba, which the PX4
cascade kernel (:mod:`fawtgym.agents.px4_cascade`) calls per vehicle and :class:`HoverThrustEstimator`
through a batch kernel.  A vehicle's state is one row of :attr:`HoverThrustEstimator.state`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.rows import check_dt

from .px4_params import PX4Params
from .shared_params import InPlaceArray

_ACC_VAR_INIT = 5.0  # (m/s^2)^2 initial accelerometer noise variance (PX4 resetAccelNoise)
_ACC_VAR_MIN, _ACC_VAR_MAX = 1.0, 400.0  # (m/s^2)^2 bounds of the adapted noise (PX4)
_STATE_VAR_MIN, _STATE_VAR_MAX = 1e-10, 1.0
_LPF_TAU = 1.0  # s, residual / test-ratio low-pass
_NOISE_TAU = 2.0  # s, noise learning time constant
_OFFSET_RATIO = 0.2  # |low-passed signed test ratio| above which the state variance is bumped
_BUMP = 1e3  # variance recovery: P += _BUMP q dt^2 (PX4's value; :attr:`HoverThrustEstimator.variance_bump`)
_VALID_VAR = 1e-3  # an estimate is valid when P < this ...
_VALID_HOLD = 2.0  # s ... for this long (PX4's hysteresis from false to true)

#: parameter vector layout (:attr:`HoverThrustEstimator.params`)
PROCESS_VAR, GATE, VXY_THR, VZ_THR, HOVER_MIN, HOVER_MAX, BUMP = 0, 1, 2, 3, 4, 5, 6
N_PARAMS = 7
#: state row layout (:attr:`HoverThrustEstimator.state`); VALID is 0 or 1
HOVER, VAR, ACC_VAR, RESIDUAL_LPF, RATIO_LPF, TEST_RATIO, VALID, VALID_TIME = 0, 1, 2, 3, 4, 5, 6, 7
N_STATE = 8


@njit(cache=True, inline="always")
def hover_thrust_row(acc_z_up: float, thrust_z_up: float, vel: np.ndarray, dt: float, prm: np.ndarray,
                     s: np.ndarray) -> None:
    """One predict + fuse step of one vehicle's estimator (steps 1-6 of the module docstring), state row ``s``.

    A non-finite acceleration or thrust is not fused (PX4's finiteness guard).
    """
    if not (math.isfinite(acc_z_up) and math.isfinite(thrust_z_up)):
        return
    q_dt2 = prm[PROCESS_VAR] * dt * dt
    var = s[VAR] + q_dt2  # 1. predict
    scale = max(1.0, abs(vel[2]) - prm[VZ_THR] + 1.0, math.hypot(vel[0], vel[1]) - prm[VXY_THR] + 1.0)
    r = s[ACC_VAR] * scale  # 2. noise inflation above the velocity thresholds
    th = s[HOVER]
    h = -GRAVITY * thrust_z_up / (th * th)  # 3. fuse
    innov = acc_z_up - (GRAVITY * thrust_z_up / th - GRAVITY)
    s_innov = max(h * var * h + r, r)
    k = var * h / s_innov
    ratio = innov * innov / (prm[GATE] * prm[GATE] * s_innov)
    passing = ratio < 1.0
    residual = innov
    if passing:
        th = min(max(th + k * innov, prm[HOVER_MIN]), prm[HOVER_MAX])
        var = min(max((1.0 - k * h) * var, _STATE_VAR_MIN), _STATE_VAR_MAX)
        residual = acc_z_up - (GRAVITY * thrust_z_up / th - GRAVITY)
    elif abs(s[RATIO_LPF]) > _OFFSET_RATIO:  # 4. variance recovery
        var += prm[BUMP] * q_dt2
    alpha = dt / (_LPF_TAU + dt)  # 5. low-pass filters and noise adaptation
    res_lpf = (1.0 - alpha) * s[RESIDUAL_LPF] + alpha * residual
    signed = ratio if innov > 0.0 else (-ratio if innov < 0.0 else 0.0)
    s[RATIO_LPF] = (1.0 - alpha) * s[RATIO_LPF] + alpha * min(max(signed, -1.0), 1.0)
    beta = dt / (_NOISE_TAU + dt)
    res_nb = residual - res_lpf
    acc_var = (1.0 - beta) * s[ACC_VAR] + beta * (res_nb * res_nb + h * var * h)
    s[ACC_VAR] = min(max(acc_var, _ACC_VAR_MIN), _ACC_VAR_MAX)
    valid = s[VALID] != 0.0
    candidate = var < _VALID_VAR and (valid or passing)  # 6. validity with a 2 s hysteresis
    s[VALID_TIME] = s[VALID_TIME] + dt if candidate else 0.0
    s[VALID] = 1.0 if candidate and (valid or s[VALID_TIME] >= _VALID_HOLD - 1e-9) else 0.0
    s[HOVER], s[VAR], s[RESIDUAL_LPF], s[TEST_RATIO] = th, var, res_lpf, ratio


@njit(cache=True)
def _hover_thrust_kernel(acc: np.ndarray, thr: np.ndarray, vel: np.ndarray, dt: np.ndarray, prm: np.ndarray,
                         state: np.ndarray, rows: np.ndarray) -> None:
    for i in range(state.shape[0]):
        if rows[i]:
            hover_thrust_row(acc[i], thr[i], vel[i], dt[i], prm, state[i])


class HoverThrustEstimator:
    """Zero-order hover-thrust EKF for N vehicles, with PX4's validity logic.

    ``hover_thrust``: the initial estimate, also PX4's ``MPC_THR_HOVER`` that centres the bounds
    ``+- HTE_THR_RANGE``.  After :meth:`update`, ``hover_thrust`` (N,) is the estimate and ``valid`` (N,)
    says whether PX4 would publish it as valid (the position controller uses only valid estimates).
    ``variance_bump`` is the variance-recovery factor (PX4: 1e3; 0 switches the recovery off, for studies).
    """
    params = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place

    def __init__(self, params: PX4Params | None = None, hover_thrust: float = 0.5) -> None:
        p = params if params is not None else PX4Params.s500()
        if not (math.isfinite(hover_thrust) and 0.0 < hover_thrust < 1.0):
            raise ValueError(f"hover_thrust must be in (0, 1) (normalized collective thrust), got "
                             f"{shown(hover_thrust)}")
        self.process_var = p["HTE_HT_NOISE"] ** 2
        self.gate = p["HTE_ACC_GATE"]
        self.init_var = p["HTE_HT_ERR_INIT"] ** 2
        self.vxy_thr = p["HTE_VXY_THR"]
        self.vz_thr = p["HTE_VZ_THR"]
        self.initial = float(hover_thrust)
        rng = p["HTE_THR_RANGE"]
        self.min_hover_thrust = min(max(self.initial - rng, 0.0), 0.8)
        self.max_hover_thrust = min(max(self.initial + rng, 0.2), 0.9)
        self.params = np.array([self.process_var, self.gate, self.vxy_thr, self.vz_thr, self.min_hover_thrust,
                                self.max_hover_thrust, _BUMP])
        self.state: NDArray[np.float64] = np.zeros((0, N_STATE))
        self.reset(1)

    @property
    def variance_bump(self) -> float:
        return float(self.params[BUMP])

    @variance_bump.setter
    def variance_bump(self, value: float) -> None:
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
            raise ValueError(f"variance_bump must be a finite number >= 0, got {shown(value)}")
        self.params[BUMP] = float(value)

    def fresh_state(self) -> NDArray[np.float64]:
        """The state row of a fresh vehicle: initial estimate and variances, filters at 0, not valid."""
        row = np.zeros(N_STATE)
        row[HOVER], row[VAR], row[ACC_VAR] = min(max(self.initial, 0.1), 0.9), self.init_var, _ACC_VAR_INIT
        return row

    hover_thrust = property(lambda self: self.state[:, HOVER], doc="hover-thrust estimate (N,)")
    var = property(lambda self: self.state[:, VAR], doc="estimate variance (N,)")
    acc_var = property(lambda self: self.state[:, ACC_VAR], doc="adapted accelerometer noise variance (N,)")
    residual_lpf = property(lambda self: self.state[:, RESIDUAL_LPF], doc="low-passed residual (N,)")
    ratio_lpf = property(lambda self: self.state[:, RATIO_LPF], doc="low-passed signed test ratio (N,)")
    test_ratio = property(lambda self: self.state[:, TEST_RATIO], doc="last innovation test ratio (N,)")
    valid = property(lambda self: self.state[:, VALID] != 0.0, doc="PX4 would publish the estimate as valid (N,)")
    valid_time = property(lambda self: self.state[:, VALID_TIME], doc="time the validity condition has held (N,)")

    def reset(self, n: int = 1, rows: NDArray[np.bool_] | None = None) -> None:
        """Initial estimate, variances, filters and validity for ``n`` vehicles (only ``rows`` (n,) if given)."""
        if rows is not None and self.state.shape[0] == n:
            self.state[rows] = self.fresh_state()
            return
        self.state = np.tile(self.fresh_state(), (n, 1))

    def update(self, acc_z_up: ArrayLike, thrust_z_up: ArrayLike, velocity: ArrayLike,
               dt: float | ArrayLike, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """One predict + fuse step; returns the hover thrust estimate (N,) (see ``valid``).

        ``acc_z_up`` (N,) measured vertical acceleration [m/s^2] (up positive), ``thrust_z_up`` (N,) the
        vertical normalized thrust setpoint that produced it (up positive), ``velocity`` (N, 3) NED;
        ``dt`` [s] scalar or per row (N,); ``rows`` (N,): only these rows advance.  Rows with a non-finite
        acceleration or thrust are not fused (PX4's finiteness guard).
        """
        n = self.state.shape[0]
        dt_rows = np.ascontiguousarray(np.broadcast_to(check_dt(dt), (n,)), dtype=float)
        acc = np.ascontiguousarray(np.asarray(acc_z_up, dtype=float).reshape(-1))
        thr = np.ascontiguousarray(np.asarray(thrust_z_up, dtype=float).reshape(-1))
        vel = np.ascontiguousarray(np.asarray(velocity, dtype=float).reshape(-1, 3))
        advance = np.ones(n, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
        _hover_thrust_kernel(acc, thr, vel, dt_rows, self.params, self.state, advance)
        return self.hover_thrust
