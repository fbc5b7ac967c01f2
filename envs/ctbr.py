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
    """Body-rate PID + allocation for one vehicle (physics-rate, float arithmetic)."""

    def __init__(self, preset: VehiclePreset, dt: float, kp: tuple[float, float, float] = (18.0, 18.0, 8.0),
                 ki: tuple[float, float, float] = (15.0, 15.0, 4.0), kd: tuple[float, float, float] = (0.3, 0.3, 0.0),
                 integrator_limit: float = 30.0) -> None:
        self.preset = preset
        self.dt = dt
        self.j = preset.inertia_matrix
        self.kp, self.ki, self.kd = (np.asarray(g, dtype=float) for g in (kp, ki, kd))
        self.i_lim = integrator_limit
        self.b_inv = np.linalg.inv(allocation_matrix(preset))
        self.t_min = float(preset.k_thrust * preset.omega_min**2)
        self.t_max = float(preset.max_thrust_per_rotor)
        # plain-float copies for rotor_thrusts_floats
        self._kp, self._ki, self._kd = (tuple(g.tolist()) for g in (self.kp, self.ki, self.kd))
        self._j = tuple(self.j.ravel().tolist())
        self._b_rows = [tuple(row) for row in self.b_inv.tolist()]
        self._inv_dt = 1.0 / dt
        self.reset()

    def reset(self) -> None:
        self._integral = [0.0, 0.0, 0.0]
        self._prev: tuple[float, float, float] | None = None

    @property
    def integral(self) -> NDArray[np.float64]:
        """The rate integrator (angular acceleration, rad/s^2), (3,)."""
        return np.array(self._integral)

    def rotor_thrusts(self, collective: float, rate_sp: NDArray[np.float64],
                      rate: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rotor thrusts [N] (4,) for a collective thrust [N] and a body-rate setpoint [rad/s]."""
        return np.array(self.rotor_thrusts_floats(float(collective), np.ravel(rate_sp).tolist(),
                                                  np.ravel(rate).tolist()))

    def rotor_thrusts_floats(self, collective: float, rate_sp: list[float], rate: list[float]) -> list[float]:
        """:meth:`rotor_thrusts` in float arithmetic (the env runs it every physics step)."""
        r0, r1, r2 = rate
        e0, e1, e2 = rate_sp[0] - r0, rate_sp[1] - r1, rate_sp[2] - r2
        prev = self._prev
        if prev is None:
            d0 = d1 = d2 = 0.0
        else:
            inv_dt = self._inv_dt
            d0, d1, d2 = (r0 - prev[0]) * inv_dt, (r1 - prev[1]) * inv_dt, (r2 - prev[2]) * inv_dt
        self._prev = (r0, r1, r2)
        (p0, p1, p2), (k0, k1, k2), (i0, i1, i2) = self._kp, self._kd, self._integral
        a0, a1, a2 = p0 * e0 + i0 - k0 * d0, p1 * e1 + i1 - k1 * d1, p2 * e2 + i2 - k2 * d2
        j00, j01, j02, j10, j11, j12, j20, j21, j22 = self._j
        h0, h1, h2 = j00 * r0 + j01 * r1 + j02 * r2, j10 * r0 + j11 * r1 + j12 * r2, j20 * r0 + j21 * r1 + j22 * r2
        tau = (j00 * a0 + j01 * a1 + j02 * a2 + (r1 * h2 - r2 * h1),
               j10 * a0 + j11 * a1 + j12 * a2 + (r2 * h0 - r0 * h2),
               j20 * a0 + j21 * a1 + j22 * a2 + (r0 * h1 - r1 * h0))
        # keep collective thrust; shrink the torque until every rotor is within limits
        t_min, t_max = self.t_min, self.t_max
        base, part, scale = [], [], 1.0
        for b0, b1, b2, b3 in self._b_rows:
            tp = b0 * collective
            q = b1 * tau[0] + b2 * tau[1] + b3 * tau[2]
            if q > 0.0:
                room = (t_max - tp) / q
            elif q < 0.0:
                room = (t_min - tp) / q
            else:
                room = 1.0
            if room < scale:
                scale = room
            base.append(tp)
            part.append(q)
        if scale < 0.0:
            scale = 0.0
        if scale >= 1.0:  # PX4: freeze the integrator while the actuators saturate
            lim, ki, dt = self.i_lim, self._ki, self.dt
            self._integral = [min(max(i + k * e * dt, -lim), lim) for i, k, e in zip(self._integral, ki, (e0, e1, e2),
                                                                                      strict=True)]
        return [min(max(tp + scale * q, t_min), t_max) for tp, q in zip(base, part, strict=True)]
