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
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.rows import check_dt, masked
from fawtgym.envs.vehicles import GRAVITY

from .px4_params import PX4Params

_ACC_VAR_INIT = 5.0  # (m/s^2)^2 initial accelerometer noise variance (PX4 resetAccelNoise)
_ACC_VAR_MIN, _ACC_VAR_MAX = 1.0, 400.0  # (m/s^2)^2 bounds of the adapted noise (PX4)
_STATE_VAR_MIN, _STATE_VAR_MAX = 1e-10, 1.0
_LPF_TAU = 1.0  # s, residual / test-ratio low-pass
_NOISE_TAU = 2.0  # s, noise learning time constant
_OFFSET_RATIO = 0.2  # |low-passed signed test ratio| above which the state variance is bumped
_BUMP = 1e3  # variance recovery: P += _BUMP q dt^2
_VALID_VAR = 1e-3  # an estimate is valid when P < this ...
_VALID_HOLD = 2.0  # s ... for this long (PX4's hysteresis from false to true)


class HoverThrustEstimator:
    """Zero-order hover-thrust EKF for N vehicles, with PX4's validity logic.

    ``hover_thrust``: the initial estimate, also PX4's ``MPC_THR_HOVER`` that centres the bounds
    ``+- HTE_THR_RANGE``.  After :meth:`update`, ``hover_thrust`` (N,) is the estimate and ``valid`` (N,)
    says whether PX4 would publish it as valid (the position controller uses only valid estimates).
    """

    def __init__(self, params: PX4Params | None = None, hover_thrust: float = 0.5) -> None:
        p = params if params is not None else PX4Params.s500()
        if not (math.isfinite(hover_thrust) and 0.0 < hover_thrust < 1.0):
            raise ValueError(f"hover_thrust must be in (0, 1) (normalized collective thrust), got {hover_thrust!r}")
        self.process_var = p["HTE_HT_NOISE"] ** 2
        self.gate = p["HTE_ACC_GATE"]
        self.init_var = p["HTE_HT_ERR_INIT"] ** 2
        self.vxy_thr = p["HTE_VXY_THR"]
        self.vz_thr = p["HTE_VZ_THR"]
        self.initial = float(hover_thrust)
        rng = p["HTE_THR_RANGE"]
        self.min_hover_thrust = min(max(self.initial - rng, 0.0), 0.8)
        self.max_hover_thrust = min(max(self.initial + rng, 0.2), 0.9)
        self.reset(1)

    def reset(self, n: int = 1, rows: NDArray[np.bool_] | None = None) -> None:
        """Initial estimate, variances, filters and validity for ``n`` vehicles (only ``rows`` (n,) if given)."""
        fresh = {"hover_thrust": np.full(n, min(max(self.initial, 0.1), 0.9)), "var": np.full(n, self.init_var),
                 "acc_var": np.full(n, _ACC_VAR_INIT), "residual_lpf": np.zeros(n), "ratio_lpf": np.zeros(n),
                 "test_ratio": np.zeros(n), "valid": np.zeros(n, dtype=bool), "valid_time": np.zeros(n)}
        for name, value in fresh.items():
            old = getattr(self, name, None)
            if rows is not None and old is not None and old.shape == (n,):
                value = masked(old, value, rows)
            setattr(self, name, value)

    def update(self, acc_z_up: ArrayLike, thrust_z_up: ArrayLike, velocity: ArrayLike,
               dt: float | ArrayLike, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """One predict + fuse step; returns the hover thrust estimate (N,) (see ``valid``).

        ``acc_z_up`` (N,) measured vertical acceleration [m/s^2] (up positive), ``thrust_z_up`` (N,) the
        vertical normalized thrust setpoint that produced it (up positive), ``velocity`` (N, 3) NED;
        ``dt`` [s] scalar or per row (N,); ``rows`` (N,): only these rows advance.  Rows with a non-finite
        acceleration or thrust are not fused (PX4's finiteness guard).
        """
        dt = np.broadcast_to(check_dt(dt), self.hover_thrust.shape).astype(float)
        acc = np.asarray(acc_z_up, dtype=float).reshape(-1)
        thr = np.asarray(thrust_z_up, dtype=float).reshape(-1)
        vel = np.asarray(velocity, dtype=float).reshape(-1, 3)
        names = ("hover_thrust", "var", "acc_var", "residual_lpf", "ratio_lpf", "test_ratio", "valid", "valid_time")
        old = {k: getattr(self, k) for k in names}
        ok = np.isfinite(acc) & np.isfinite(thr)
        acc, thr = np.where(ok, acc, 0.0), np.where(ok, thr, 0.0)

        var = self.var + self.process_var * dt * dt  # 1. predict
        scale = np.maximum.reduce([np.ones_like(acc), np.abs(vel[:, 2]) - self.vz_thr + 1.0,
                                   np.hypot(vel[:, 0], vel[:, 1]) - self.vxy_thr + 1.0])  # 2. noise inflation
        r = self.acc_var * scale
        th = self.hover_thrust
        h = -GRAVITY * thr / (th * th)  # 3. fuse
        innov = acc - (GRAVITY * thr / th - GRAVITY)
        s = np.maximum(h * var * h + r, r)
        k = var * h / s
        ratio = innov * innov / (self.gate**2 * s)
        passing = ratio < 1.0
        th_new = np.where(passing, np.clip(th + k * innov, self.min_hover_thrust, self.max_hover_thrust), th)
        var = np.where(passing, np.clip((1.0 - k * h) * var, _STATE_VAR_MIN, _STATE_VAR_MAX), var)
        residual = np.where(passing, acc - (GRAVITY * thr / th_new - GRAVITY), innov)
        bump = ~passing & (np.abs(self.ratio_lpf) > _OFFSET_RATIO)  # 4. variance recovery
        var = np.where(bump, var + _BUMP * self.process_var * dt * dt, var)
        alpha = dt / (_LPF_TAU + dt)  # 5. low-pass filters and noise adaptation
        res_lpf = (1.0 - alpha) * self.residual_lpf + alpha * residual
        ratio_lpf = (1.0 - alpha) * self.ratio_lpf + alpha * np.clip(np.sign(innov) * ratio, -1.0, 1.0)
        beta = dt / (_NOISE_TAU + dt)
        res_nb = residual - res_lpf
        acc_var = np.clip((1.0 - beta) * self.acc_var + beta * (res_nb * res_nb + h * var * h),
                          _ACC_VAR_MIN, _ACC_VAR_MAX)
        candidate = (var < _VALID_VAR) & (self.valid | passing)  # 6. validity with a 2 s hysteresis
        valid_time = np.where(candidate, self.valid_time + dt, 0.0)
        valid = candidate & (self.valid | (valid_time >= _VALID_HOLD - 1e-9))

        new = {"hover_thrust": th_new, "var": var, "acc_var": acc_var, "residual_lpf": res_lpf,
               "ratio_lpf": ratio_lpf, "test_ratio": ratio, "valid": valid, "valid_time": valid_time}
        use = ok if rows is None else ok & rows
        for name in names:
            setattr(self, name, masked(old[name], new[name], use))
        return self.hover_thrust
