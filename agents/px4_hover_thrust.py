"""PX4's hover-thrust estimator (``mc_hover_thrust_estimator``, ZeroOrderHoverThrustEkf, v1.13), batch-first.

A one-state Kalman filter for the normalized hover thrust ``Th`` (enabled by ``MPC_USE_HTE = 1``, PX4's
default).  Measurement model, vertical axis positive up::

    a_z = g T_z / Th - g,        H = d a_z / d Th = -g T_z / Th^2

with ``T_z`` the vertical component of the normalized thrust setpoint and ``a_z`` the measured vertical
acceleration.  The state is a random walk (``P += q dt^2``, ``q = HTE_HT_NOISE^2``); measurements whose
innovation exceeds ``HTE_ACC_GATE`` standard deviations are rejected; the acceleration noise variance
is adapted from the post-fit residuals (first-order filter, 1 s time constant, floored), as PX4 does.
The estimator runs only while ``|v_z| < HTE_VZ_THR`` and ``|v_xy| < HTE_VXY_THR``.

Why it matters in the FAWT: any steady vertical aerodynamic force (rotor-disc lift in a cross-flow)
changes the thrust needed to hover.  Without the estimator the vertical velocity integrator absorbs it
(``a_z,sp != 0``), which makes PositionControl's horizontal tracking anti-windup see a "produced"
horizontal acceleration ``(1 - a_z,sp / g)`` times the demanded one and bleed the horizontal integrator,
leaving a steady position offset.  PX4 avoids this by re-estimating ``Th`` (and shifting the integrator,
``PositionControl::updateHoverThrust``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.rows import check_dt, masked
from fawtgym.envs.vehicles import GRAVITY

from .px4_params import PX4Params

_ACC_VAR_MIN = 1e-3  # (m/s^2)^2 floor of the adapted measurement noise
_ACC_VAR_INIT = 5.0  # (m/s^2)^2 initial measurement noise (PX4: 5)


class HoverThrustEstimator:
    """Zero-order hover-thrust EKF for N vehicles."""

    def __init__(self, params: PX4Params | None = None, hover_thrust: float = 0.5) -> None:
        p = params if params is not None else PX4Params.s500()
        self.process_var = p["HTE_HT_NOISE"] ** 2
        self.gate = p["HTE_ACC_GATE"]
        self.init_var = p["HTE_HT_ERR_INIT"] ** 2
        self.vxy_thr = p["HTE_VXY_THR"]
        self.vz_thr = p["HTE_VZ_THR"]
        self.initial = float(hover_thrust)
        self.reset(1)

    def reset(self, n: int = 1, hover_thrust: float | None = None, rows: NDArray[np.bool_] | None = None) -> None:
        """Initial estimate and variances for ``n`` vehicles (only the rows of ``rows`` (n,) if given)."""
        th = np.full(n, self.initial if hover_thrust is None else float(hover_thrust))
        var, acc_var = np.full(n, self.init_var), np.full(n, _ACC_VAR_INIT)
        if rows is not None and self.hover_thrust.shape == (n,):
            th, var = masked(self.hover_thrust, th, rows), masked(self.var, var, rows)
            acc_var = masked(self.acc_var, acc_var, rows)
        self.hover_thrust, self.var, self.acc_var = th, var, acc_var

    def update(self, acc_z_up: ArrayLike, thrust_z_up: ArrayLike, velocity: ArrayLike,
               dt: float | ArrayLike, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """One predict + fuse step; returns the hover thrust estimate (N,).

        ``acc_z_up`` (N,) measured vertical acceleration [m/s^2] (up positive), ``thrust_z_up`` (N,) the
        vertical normalized thrust setpoint that produced it (up positive), ``velocity`` (N, 3) NED;
        ``dt`` [s] scalar or per row (N,); ``rows`` (N,): only these rows advance.
        """
        dt = check_dt(dt)
        old = (self.hover_thrust, self.var, self.acc_var)
        acc = np.asarray(acc_z_up, dtype=float).reshape(-1)
        thr = np.asarray(thrust_z_up, dtype=float).reshape(-1)
        vel = np.asarray(velocity, dtype=float).reshape(-1, 3)
        self.var = self.var + self.process_var * dt * dt
        th = self.hover_thrust
        h = -GRAVITY * thr / (th * th)
        innov = acc - (GRAVITY * thr / th - GRAVITY)
        innov_var = h * self.var * h + self.acc_var
        passing = innov * innov / (self.gate**2 * innov_var) < 1.0
        active = (np.abs(vel[:, 2]) < self.vz_thr) & (np.hypot(vel[:, 0], vel[:, 1]) < self.vxy_thr) & \
            np.isfinite(acc) & (thr > 0.0)
        use = passing & active
        k = self.var * h / innov_var
        new_th = np.clip(th + k * innov, 0.1, 0.9)
        new_var = np.maximum((1.0 - k * h) * self.var, 1e-10)
        self.hover_thrust = np.where(use, new_th, th)
        self.var = np.where(use, new_var, self.var)
        residual = acc - (GRAVITY * thr / self.hover_thrust - GRAVITY)
        alpha = dt / (1.0 + dt)  # 1 s time constant on the residual variance
        adapted = np.maximum((1.0 - alpha) * self.acc_var + alpha * residual * residual, _ACC_VAR_MIN)
        self.acc_var = np.where(active, adapted, self.acc_var)
        if rows is not None:
            self.hover_thrust = masked(old[0], self.hover_thrust, rows)
            self.var = masked(old[1], self.var, rows)
            self.acc_var = masked(old[2], self.acc_var, rows)
        return self.hover_thrust
