"""The env's inner body-rate loop for ``action_type="ctbr"`` (collective thrust + body rates).

PX4's rate controller (``RateControl``: PID on the rate error with the D term on the measured
angular acceleration) written in physical units, ``tau = J (K_P e + K_I int e - K_D Omega_dot) +
Omega x J Omega``, run at the physics rate on the true body rates (an idealized onboard loop; the
agent's own measurements carry the sensor noise).  The default gains are PX4's S500 rate gains
(MC_ROLLRATE_P 0.18, I 0.15, D 0.003; MC_YAWRATE_P 0.2, I 0.1) converted from normalized torque
to physical units with the s500's maximum torques (~3 N m roll/pitch) and inertia, rounded.
The integrator (in angular acceleration, rad/s^2) is limited to ``integrator_limit`` (PX4's
MC_*RATE_INT_LIM 0.3 of the s500's ~3 N m / 0.03 kg m^2).  Rotor thrusts come from the exact inverse
of the allocation matrix, clipped to the rotor limits
with the collective thrust kept first (the torque is scaled down until it fits).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.so3_kernels import cross_entries, mat_vec_entries

from .motors import allocation_matrix
from .vehicles import VehiclePreset

#: max commanded body rates (PX4 MC_ROLLRATE_MAX / PITCHRATE_MAX 220 deg/s, MC_YAWRATE_MAX 200 deg/s)
MAX_RATES = np.radians([220.0, 220.0, 200.0])


class RateLoop:
    """Body-rate PID + allocation for N vehicles (batch-first: state rows (N, 3), physics rate)."""

    def __init__(self, preset: VehiclePreset, dt: float, n: int = 1,
                 kp: tuple[float, float, float] = (18.0, 18.0, 8.0),
                 ki: tuple[float, float, float] = (15.0, 15.0, 4.0), kd: tuple[float, float, float] = (0.3, 0.3, 0.0),
                 integrator_limit: float = 30.0) -> None:
        self.preset = preset
        self.dt = dt
        self.n = n
        self.j = preset.inertia_matrix
        self.kp: NDArray[np.float64] = np.asarray(kp, dtype=np.float64)
        self.ki: NDArray[np.float64] = np.asarray(ki, dtype=np.float64)
        self.kd: NDArray[np.float64] = np.asarray(kd, dtype=np.float64)
        self.i_lim = integrator_limit
        self.b_inv: NDArray[np.float64] = np.linalg.inv(allocation_matrix(preset)).astype(np.float64)
        self.t_min = float(preset.k_thrust * preset.omega_min**2)
        self.t_max = float(preset.max_thrust_per_rotor)
        self.integral = np.zeros((n, 3))  #: the rate integrator (angular acceleration, rad/s^2), (N, 3)
        self.prev_rate = np.zeros((n, 3))
        self.has_prev = np.zeros(n, dtype=bool)

    def reset(self, rows: NDArray[np.intp] | None = None) -> None:
        """Zero the integrator and forget the previous rate of ``rows`` (all rows if None)."""
        sel = slice(None) if rows is None else rows
        self.integral[sel] = 0.0
        self.prev_rate[sel] = 0.0
        self.has_prev[sel] = False

    def rotor_thrusts(self, collective: NDArray[np.float64], rate_sp: NDArray[np.float64],
                      rate: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rotor thrusts (N, 4) [N] for collective thrusts (N,) [N], body-rate set points and rates (N, 3) [rad/s]
        (the law: :func:`rate_loop_rows`)."""
        out = np.empty((collective.shape[0], 4))
        rate_loop_rows(np.ascontiguousarray(collective, dtype=np.float64),
                       np.ascontiguousarray(rate_sp, dtype=np.float64), np.ascontiguousarray(rate, dtype=np.float64),
                       self.kp, self.ki, self.kd, self.j, self.b_inv, self.t_min, self.t_max, self.i_lim, self.dt,
                       self.integral, self.prev_rate, self.has_prev, out)
        return out


@njit(cache=True)
def rate_loop_rows(collective: NDArray[np.float64], rate_sp: NDArray[np.float64], rate: NDArray[np.float64],
                   kp: NDArray[np.float64], ki: NDArray[np.float64], kd: NDArray[np.float64], j: NDArray[np.float64],
                   b_inv: NDArray[np.float64], t_min: float, t_max: float, i_lim: float, dt: float,
                   integral: NDArray[np.float64], prev_rate: NDArray[np.float64], has_prev: NDArray[np.bool_],
                   out: NDArray[np.float64]) -> None:  # pragma: no cover - jitted
    """The rate loop of every row (module docstring), its state (``integral``, ``prev_rate``, ``has_prev``) updated.

    ``tau = J (K_P e + I - K_D Omega_dot) + Omega x J Omega`` with ``e = Omega_sp - Omega`` and ``Omega_dot`` the
    rate's backward difference (0 on a row's first call); rotor thrusts ``B^-1 [c, tau]`` with the torque part
    scaled by the largest s in [0, 1] that keeps every rotor in [t_min, t_max] (the collective thrust first); the
    integrator ``I += K_I e dt`` (clipped to +- i_lim) only while s = 1 (PX4 freezes it when the rotors saturate).
    """
    err = np.empty(3)
    ang_acc = np.empty(3)
    torque = np.empty(3)
    base = np.empty(4)
    part = np.empty(4)
    for i in range(collective.shape[0]):
        for c in range(3):
            err[c] = rate_sp[i, c] - rate[i, c]
            rate_dot = (rate[i, c] - prev_rate[i, c]) / dt if has_prev[i] else 0.0
            prev_rate[i, c] = rate[i, c]
            ang_acc[c] = kp[c] * err[c] + integral[i, c] - kd[c] * rate_dot
        has_prev[i] = True
        w0, w1, w2 = rate[i, 0], rate[i, 1], rate[i, 2]
        h0, h1, h2 = mat_vec_entries(j, w0, w1, w2)  # J Omega
        g0, g1, g2 = cross_entries(w0, w1, w2, h0, h1, h2)  # Omega x J Omega = -(J Omega x Omega)
        ja0, ja1, ja2 = mat_vec_entries(j, ang_acc[0], ang_acc[1], ang_acc[2])  # J (K_P e + I - K_D Omega_dot)
        torque[0], torque[1], torque[2] = ja0 + g0, ja1 + g1, ja2 + g2
        scale = 1.0
        for r in range(4):  # keep the collective thrust; shrink the torque until every rotor fits
            base[r] = b_inv[r, 0] * collective[i]
            part[r] = b_inv[r, 1] * torque[0] + b_inv[r, 2] * torque[1] + b_inv[r, 3] * torque[2]
            if part[r] > 0.0:
                room = (t_max - base[r]) / part[r]
            elif part[r] < 0.0:
                room = (t_min - base[r]) / part[r]
            else:
                room = math.inf
            scale = min(scale, room)
        scale = max(scale, 0.0)
        if scale >= 1.0:
            for c in range(3):
                integral[i, c] = min(max(integral[i, c] + ki[c] * err[c] * dt, -i_lim), i_lim)
        for r in range(4):
            out[i, r] = min(max(base[r] + scale * part[r], t_min), t_max)
