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
    """Body-rate PID + allocation for one vehicle (physics-rate, plain numpy)."""

    def __init__(self, preset: VehiclePreset, dt: float, kp: tuple[float, float, float] = (18.0, 18.0, 8.0),
                 ki: tuple[float, float, float] = (15.0, 15.0, 4.0), kd: tuple[float, float, float] = (0.3, 0.3, 0.0),
                 integrator_limit: float = 30.0) -> None:
        self.preset = preset
        self.dt = dt
        self.j = preset.inertia_matrix
        self.kp, self.ki, self.kd = (np.asarray(g, dtype=float) for g in (kp, ki, kd))
        self.i_lim = integrator_limit
        self.b_inv = np.linalg.inv(allocation_matrix(preset))
        self.t_min = preset.k_thrust * preset.omega_min**2
        self.t_max = preset.max_thrust_per_rotor
        self.reset()

    def reset(self) -> None:
        self.integral = np.zeros(3)
        self.prev_rate: NDArray[np.float64] | None = None

    def rotor_thrusts(self, collective: float, rate_sp: NDArray[np.float64],
                      rate: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rotor thrusts [N] (4,) for a collective thrust [N] and a body-rate setpoint [rad/s]."""
        err = rate_sp - rate
        rate_dot = np.zeros(3) if self.prev_rate is None else (rate - self.prev_rate) / self.dt
        self.prev_rate = rate.copy()
        ang_acc = self.kp * err + self.integral - self.kd * rate_dot
        torque = self.j @ ang_acc + np.cross(rate, self.j @ rate)
        thrust_part = self.b_inv[:, 0] * collective
        torque_part = self.b_inv[:, 1:] @ torque
        # keep collective thrust; shrink the torque until every rotor is within limits
        scale = 1.0
        lo, hi = self.t_min - thrust_part, self.t_max - thrust_part
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(torque_part > 0, hi / torque_part, np.where(torque_part < 0, lo / torque_part, np.inf))
        scale = float(np.clip(np.min(s), 0.0, 1.0))
        saturated = scale < 1.0
        if not saturated:  # PX4: freeze the integrator while the actuators saturate
            self.integral = np.clip(self.integral + self.ki * err * self.dt, -self.i_lim, self.i_lim)
        return np.clip(thrust_part + scale * torque_part, self.t_min, self.t_max)
