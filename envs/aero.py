"""Aerodynamics: wind at the vehicle -> disturbance force (world NED) and torque (body FRD).

Model (per vehicle, batch-first; every coefficient is a :class:`~fawtgym.envs.vehicles.VehiclePreset`
field, the calibration is in ``docs/wind.md`` and :func:`calibrated_rotor_drag`)::

    a_i   = R^T (w_i - v) - Omega x r_i                 air velocity relative to rotor hub i, body FRD
    a_0   = R^T (w_0 - v) - Omega x c                   ... relative to the centre of pressure c
    F_i   = k_d omega_i P a_i,  P = diag(1, 1, 0)       linear rotor (induced + profile, "H-force") drag
    M_i   = k_r omega_i (a_i x e3)                      blade-flapping moment: the disc tilts downwind
    F_b   = D |a_0| a_0,  D = body_drag                 quadratic parasitic drag of the body
    force = R (sum_i F_i + F_b)                         world NED
    tau   = sum_i (r_i x F_i + M_i) + c x F_b           body FRD

``w_0`` is the wind at the CoM and ``w_i`` at rotor hub ``i`` (so differential wind across the
vehicle, e.g. a FAWT shear layer, gives differential rotor forces and moments), ``v`` the CoM
velocity (NED), ``Omega`` the body rate (FRD), ``r_i`` the hub positions and ``c = cop_offset``.

Sources: the rotor drag ``F = -k_d omega v_inplane`` is PX4's Gazebo motor model
(``rotorDragCoefficient``; x500: 8.06428e-5) and rotorpy's (Hummingbird ``k_d = 1.19e-4``), the
linear-in-airspeed drag of Faessler et al. (RA-L 2018).  The flapping moment follows the blade-
flapping analysis of Hoffmann et al. (AIAA GNC 2007): it is about the in-plane axis normal to the
relative wind and has the same sign for both spin directions, so it pitches a vehicle nose-up in a
headwind.  Its coefficient has PX4's ``rollingMomentCoefficient`` magnitude (1e-6); PX4's own term
is spin-direction dependent and cancels between the rotor pairs of a quad in uniform wind, so it is
not modelled separately.  Not modelled: axial-inflow change of thrust, rotor-disc averaging of
small eddies, ground effect.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .vehicles import GRAVITY, VehiclePreset

#: Linear (rotor) drag per unit vehicle mass at hover [N/(m/s)/kg] used to calibrate ``rotor_drag``: rotorpy's
#: Hummingbird gives 0.31, the linear part of a fit F = a V + b V^2 to Neural-Fly's mid-values gives 0.37; rounded
#: up to 0.40 so that the s500 reaches the 2 N low end of Neural-Fly's 4.2 m/s range (docs/wind.md).
LINEAR_DRAG_PER_KG = 0.40


def calibrated_rotor_drag(preset: VehiclePreset, linear_drag_per_kg: float = LINEAR_DRAG_PER_KG) -> float:
    """``k_d`` such that ``4 k_d omega_hover = linear_drag_per_kg * mass`` (the calibration rule of docs/wind.md)."""
    return linear_drag_per_kg * preset.mass / (4.0 * preset.hover_omega)


def _hat(r: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


class AeroModel:
    """Wind + vehicle motion -> aerodynamic disturbance wrench, batch-first (module docstring)."""

    def __init__(self, preset: VehiclePreset) -> None:
        self.preset = preset
        self.rotor_positions = np.asarray(preset.rotor_positions, dtype=float)  # (4, 3) body FRD
        r = self.rotor_positions
        self.n_rotors = r.shape[0]
        k_d, k_r = float(preset.rotor_drag), float(preset.rolling_moment)
        self.cop = np.asarray(preset.cop_offset, dtype=float)
        self.body_drag = np.asarray(preset.body_drag, dtype=float)
        proj = np.diag([1.0, 1.0, 0.0])
        flap = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # a -> a x e3
        # [omega_i a_i] (N, 4*3) @ W (12, 6) = [sum F_i, sum (r_i x F_i + M_i)]
        w = np.zeros((3 * self.n_rotors, 6))
        for i in range(self.n_rotors):
            w[3 * i:3 * i + 3, :3] = (k_d * proj).T
            w[3 * i:3 * i + 3, 3:] = (k_d * _hat(r[i]) @ proj + k_r * flap).T
        self._w = w
        # Omega (N, 3) @ X (3, 15) = [Omega x c, Omega x r_1, ..., Omega x r_4]; Omega x r = -r^ Omega
        self._x = np.hstack([(-_hat(p)).T for p in (self.cop, *r)])
        self._cop_hat_t = _hat(self.cop).T
        # plain-float copies for the N = 1 path
        self._kd, self._kr = k_d, k_r
        self._rp = [tuple(row) for row in r.tolist()]
        self._c = tuple(self.cop.tolist())
        self._d = tuple(self.body_drag.tolist())

    def wrench(self, rotation: NDArray[np.float64], velocity: NDArray[np.float64],
               angular_velocity: NDArray[np.float64], rotor_speeds: NDArray[np.float64],
               wind: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Force (N, 3) world NED [N] and torque (N, 3) body FRD [N m].

        ``rotation`` (N, 3, 3) body FRD -> NED, ``velocity`` (N, 3) NED, ``angular_velocity`` (N, 3)
        FRD, ``rotor_speeds`` (N, 4) rad/s, ``wind`` (N, 5, 3) NED at [CoM, rotor 1..4].
        """
        n = velocity.shape[0]
        if n == 1 and self.n_rotors == 4 and wind.shape == (1, 5, 3) and rotation.shape == (1, 3, 3) \
                and angular_velocity.shape == (1, 3) and rotor_speeds.shape == (1, 4):
            return self._wrench_single(rotation, velocity, angular_velocity, rotor_speeds, wind)
        if wind.shape != (n, self.n_rotors + 1, 3) or rotation.shape != (n, 3, 3) \
                or angular_velocity.shape != (n, 3) or rotor_speeds.shape != (n, self.n_rotors):
            raise ValueError(f"AeroModel.wrench shapes must be rotation ({n},3,3), velocity ({n},3), angular_velocity "
                             f"({n},3), rotor_speeds ({n},{self.n_rotors}), wind ({n},{self.n_rotors + 1},3); got "
                             f"{rotation.shape}, {velocity.shape}, {angular_velocity.shape}, {rotor_speeds.shape}, "
                             f"{wind.shape}")
        # air velocity relative to each point, body FRD: R^T (w_k - v) - Omega x r_k
        rel = (wind - velocity[:, None, :]) @ rotation - (angular_velocity @ self._x).reshape(n, self.n_rotors + 1, 3)
        q = (rotor_speeds[:, :, None] * rel[:, 1:, :]).reshape(n, 3 * self.n_rotors)
        ft = q @ self._w  # (N, 6): rotor force (body) and torque
        a0 = rel[:, 0, :]
        f_body = self.body_drag * a0 * np.sqrt((a0 * a0).sum(axis=1, keepdims=True))
        force_b = ft[:, :3] + f_body
        torque = ft[:, 3:] + f_body @ self._cop_hat_t
        force_ned = (rotation @ force_b[:, :, None])[:, :, 0]
        if not math.isfinite(float(force_ned.sum()) + float(torque.sum())):
            raise ValueError("aerodynamic wrench is not finite: check rotation, velocity, angular_velocity, "
                             "rotor_speeds and wind for NaN/inf")
        return force_ned, torque

    def _wrench_single(self, rotation: NDArray[np.float64], velocity: NDArray[np.float64],
                       angular_velocity: NDArray[np.float64], rotor_speeds: NDArray[np.float64],
                       wind: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """N = 1 :meth:`wrench` through :meth:`wrench_floats`."""
        force, torque = self.wrench_floats(rotation.ravel().tolist(), velocity[0].tolist(),
                                           angular_velocity[0].tolist(), rotor_speeds[0].tolist(),
                                           wind.ravel().tolist())
        return np.array([force]), np.array([torque])

    def wrench_floats(self, r: list[float], v: list[float], w: list[float], om: list[float], wind: list[float]
                      ) -> tuple[list[float], list[float]]:
        """One vehicle in plain float arithmetic (same model as :meth:`wrench`; small numpy ops cost more than the
        math here): ``r`` = R row-major (9), ``v`` (3), ``w`` = Omega (3), ``om`` = rotor speeds (4), ``wind`` flat
        (15: CoM then hubs).  Returns (force NED, torque FRD) as lists; ValueError if not finite."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
        vx, vy, vz = v
        wp, wq, wr = w
        k_d, k_r = self._kd, self._kr
        fx = fy = tx = ty = tz = 0.0
        for i, (px, py, pz) in enumerate(self._rp):
            j = 3 * i + 3
            dx, dy, dz = wind[j] - vx, wind[j + 1] - vy, wind[j + 2] - vz
            ax = r00 * dx + r10 * dy + r20 * dz - (wq * pz - wr * py)
            ay = r01 * dx + r11 * dy + r21 * dz - (wr * px - wp * pz)
            kw, mw = k_d * om[i], k_r * om[i]
            gx, gy = kw * ax, kw * ay
            fx += gx
            fy += gy
            tx += mw * ay - pz * gy
            ty += pz * gx - mw * ax
            tz += px * gy - py * gx
        cx, cy, cz = self._c
        dx, dy, dz = wind[0] - vx, wind[1] - vy, wind[2] - vz
        ax = r00 * dx + r10 * dy + r20 * dz - (wq * cz - wr * cy)
        ay = r01 * dx + r11 * dy + r21 * dz - (wr * cx - wp * cz)
        az = r02 * dx + r12 * dy + r22 * dz - (wp * cy - wq * cx)
        nrm = math.sqrt(ax * ax + ay * ay + az * az)
        bx, by, bz = self._d[0] * ax * nrm, self._d[1] * ay * nrm, self._d[2] * az * nrm
        tx += cy * bz - cz * by
        ty += cz * bx - cx * bz
        tz += cx * by - cy * bx
        fx += bx
        fy += by
        fz = bz
        force = [r00 * fx + r01 * fy + r02 * fz, r10 * fx + r11 * fy + r12 * fz, r20 * fx + r21 * fy + r22 * fz]
        if not math.isfinite(force[0] + force[1] + force[2] + tx + ty + tz):
            raise ValueError("aerodynamic wrench is not finite: check rotation, velocity, angular_velocity, "
                             "rotor_speeds and wind for NaN/inf")
        return force, [tx, ty, tz]


def hover_drag(preset: VehiclePreset, airspeed: float | NDArray[np.float64]) -> NDArray[np.float64]:
    """Horizontal drag [N] on a level vehicle hovering (rotors at hover speed) in a uniform horizontal wind.

    The number the calibration in docs/wind.md is stated in; evaluated through :class:`AeroModel`.
    """
    v = np.atleast_1d(np.asarray(airspeed, dtype=float))
    n = v.size
    wind = np.zeros((n, 5, 3))
    wind[:, :, 0] = v[:, None]
    model = AeroModel(preset)
    force, _ = model.wrench(np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), np.zeros((n, 3)), np.zeros((n, 3)),
                            np.full((n, 4), preset.hover_omega), wind)
    return force[:, 0]


def hover_tilt_deg(preset: VehiclePreset, airspeed: float) -> float:
    """Tilt [deg] a vehicle needs to hold position against :func:`hover_drag` at ``airspeed``."""
    return math.degrees(math.atan2(float(hover_drag(preset, airspeed)[0]), preset.mass * GRAVITY))
