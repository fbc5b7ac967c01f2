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

import numpy as np
from numpy.typing import NDArray

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
        self.kp, self.ki, self.kd = (np.asarray(g, dtype=float) for g in (kp, ki, kd))
        self.i_lim = integrator_limit
        self.b_inv = np.linalg.inv(allocation_matrix(preset))
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
        """Rotor thrusts (N, 4) [N] for collective thrusts (N,) [N], body-rate set points and rates (N, 3) [rad/s].

        ``tau = J (K_P e + I - K_D Omega_dot) + Omega x J Omega`` (module docstring), then
        ``T = B^-1 [c, tau]`` with the torque part scaled by the largest s in [0, 1] that keeps every rotor in
        [t_min, t_max] (the collective thrust first).
        """
        err = rate_sp - rate
        rate_dot = np.where(self.has_prev[:, None], (rate - self.prev_rate) / self.dt, 0.0)
        self.prev_rate = rate.copy()
        self.has_prev[:] = True
        ang_acc = self.kp * err + self.integral - self.kd * rate_dot
        torque = ang_acc @ self.j.T + np.cross(rate, rate @ self.j.T)
        thrust_part = self.b_inv[:, 0] * collective[:, None]
        torque_part = torque @ self.b_inv[:, 1:].T
        lo, hi = self.t_min - thrust_part, self.t_max - thrust_part
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(torque_part > 0, hi / torque_part, np.where(torque_part < 0, lo / torque_part, np.inf))
        scale = np.clip(room.min(axis=1), 0.0, 1.0)
        free = scale >= 1.0  # PX4: freeze the integrator while the actuators saturate
        self.integral = np.where(free[:, None], np.clip(self.integral + self.ki * err * self.dt, -self.i_lim,
                                                        self.i_lim), self.integral)
        return np.clip(thrust_part + scale[:, None] * torque_part, self.t_min, self.t_max)
