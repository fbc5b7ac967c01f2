"""PX4's multicopter rate controller (``rate_control`` RateControl, used by mc_rate_control), batch-first.

The law (re-derived): with rate error ``e = omega_sp - omega``,

    tau = K_P e + i - K_D omega_dot + K_FF omega_sp        (normalized torque, about [-1, 1])

where ``K_P = K * MC_*RATE_P``, ``K_I = K * MC_*RATE_I``, ``K_D = K * MC_*RATE_D`` (the "K" gain
``MC_*RATE_K`` scales the parallel gains) and the D term acts on the measured, low-passed angular
acceleration (no derivative kick).  The integrator:

* is frozen per axis in the direction in which the control allocation reports saturation;
* uses PX4's i-factor ``max(0, 1 - (e / 400 deg/s)^2)`` that reduces integration on large errors;
* is clamped to ``+-MC_*_INT_LIM``.

Observer feedforward (Wang et al. (2024) Sec. 7.2, tau = tau0 - tau_hat) is
applied by the agent after this law, in normalized units (see :mod:`fawtgym.agents.px4_allocation`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.rows import check_dt, masked, per_row

from .px4_params import PX4Params

_EPS = 1.1920929e-07


class RateControl:
    """PX4 RateControl for N vehicles."""

    def __init__(self, params: PX4Params | None = None) -> None:
        p = params if params is not None else PX4Params.s500()
        k = np.array([p["MC_ROLLRATE_K"], p["MC_PITCHRATE_K"], p["MC_YAWRATE_K"]])
        self.gain_p = k * np.array([p["MC_ROLLRATE_P"], p["MC_PITCHRATE_P"], p["MC_YAWRATE_P"]])
        self.gain_i = k * np.array([p["MC_ROLLRATE_I"], p["MC_PITCHRATE_I"], p["MC_YAWRATE_I"]])
        self.gain_d = k * np.array([p["MC_ROLLRATE_D"], p["MC_PITCHRATE_D"], p["MC_YAWRATE_D"]])
        self.gain_ff = np.array([p["MC_ROLLRATE_FF"], p["MC_PITCHRATE_FF"], p["MC_YAWRATE_FF"]])
        self.lim_int = np.array([p["MC_RR_INT_LIM"], p["MC_PR_INT_LIM"], p["MC_YR_INT_LIM"]])
        self.rate_int = np.zeros((1, 3))
        self.sat_pos = np.zeros((1, 3), dtype=bool)
        self.sat_neg = np.zeros((1, 3), dtype=bool)

    def reset(self, n: int = 1, rows: NDArray[np.bool_] | None = None) -> None:
        """Zero integrators and saturation flags for ``n`` vehicles (only the rows of ``rows`` (n,) if given)."""
        if rows is not None and self.rate_int.shape[0] == n:
            self.rate_int = masked(self.rate_int, 0.0 * self.rate_int, rows)
            self.sat_pos = self.sat_pos & ~rows[:, None]
            self.sat_neg = self.sat_neg & ~rows[:, None]
            return
        self.rate_int = np.zeros((n, 3))
        self.sat_pos = np.zeros((n, 3), dtype=bool)
        self.sat_neg = np.zeros((n, 3), dtype=bool)

    def set_saturation(self, positive: ArrayLike, negative: ArrayLike) -> None:
        """Saturation flags (N, 3) from the control allocation (``unallocated torque > 0`` / ``< 0``)."""
        self.sat_pos = np.asarray(positive, dtype=bool)
        self.sat_neg = np.asarray(negative, dtype=bool)

    def update(self, rate: ArrayLike, rate_sp: ArrayLike, angular_accel: ArrayLike, dt: float | ArrayLike,
               landed: bool = False, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Normalized torque (N, 3) from rates (N, 3) [rad/s] and angular acceleration (N, 3) [rad/s^2].

        ``dt`` [s] scalar or per row (N,); ``rows`` (N,): only these rows advance the integrator.
        """
        dt = check_dt(dt)
        rate = np.atleast_2d(np.asarray(rate, dtype=float))
        n = rate.shape[0]
        if self.rate_int.shape[0] != n:
            self.reset(n)
        rate_sp = np.asarray(rate_sp, dtype=float)
        acc = np.asarray(angular_accel, dtype=float)
        err = rate_sp - rate
        torque = self.gain_p * err + self.rate_int - self.gain_d * acc + self.gain_ff * rate_sp
        if not landed:
            old = self.rate_int
            self._update_integral(err, per_row(dt, 2))
            self.rate_int = masked(old, self.rate_int, rows)
        return torque

    def _update_integral(self, err: NDArray[np.float64], dt: float | NDArray[np.float64]) -> None:
        e = np.where(self.sat_pos, np.minimum(err, 0.0), err)
        e = np.where(self.sat_neg, np.maximum(e, 0.0), e)
        i_factor = e / math.radians(400.0)
        i_factor = np.maximum(0.0, 1.0 - i_factor * i_factor)
        rate_i = self.rate_int + i_factor * self.gain_i * e * dt
        self.rate_int = np.where(np.isfinite(rate_i), np.clip(rate_i, -self.lim_int, self.lim_int), self.rate_int)
