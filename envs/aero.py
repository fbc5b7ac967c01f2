"""Aerodynamics: wind at the vehicle -> disturbance force (world NED) and torque (body FRD).

Model (per vehicle; one compiled kernel, :func:`aero_wrench_rows`, loops over the vehicles, N = 1 is a batch of
one; every coefficient is a :class:`~fawtgym.envs.vehicles.VehiclePreset` field, the calibration is in
``docs/wind.md`` and :func:`calibrated_rotor_drag`)::

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
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.arrays import as_f64
from fawtgym.core.checks import shown
from fawtgym.core.so3_kernels import cross_entries

from .vehicles import GRAVITY, VehiclePreset

#: Linear (rotor) drag per unit vehicle mass at hover [N/(m/s)/kg] used to calibrate ``rotor_drag``: rotorpy's
#: Hummingbird gives 0.31, the linear part of a fit F = a V + b V^2 to Neural-Fly's mid-values gives 0.37; rounded
#: up to 0.40 so that the s500 reaches the 2 N low end of Neural-Fly's 4.2 m/s range (docs/wind.md).
LINEAR_DRAG_PER_KG = 0.40


def calibrated_rotor_drag(preset: VehiclePreset, linear_drag_per_kg: float = LINEAR_DRAG_PER_KG) -> float:
    """``k_d`` such that ``4 k_d omega_hover = linear_drag_per_kg * mass`` (the calibration rule of docs/wind.md)."""
    return linear_drag_per_kg * preset.mass / (4.0 * preset.hover_omega)


@njit(cache=True)
def _air_velocity(rotation: NDArray[np.float64], i: int, w0: float, w1: float, w2: float, v0: float, v1: float,
                  v2: float, o0: float, o1: float, o2: float, p0: float, p1: float, p2: float
                  ) -> tuple[float, float, float]:  # pragma: no cover - jitted
    """``a = R^T (w - v) - Omega x p``: the air velocity relative to body point ``p`` (body FRD), with R
    ``rotation[i]``, wind ``w`` and velocity ``v`` (NED), body rate ``Omega`` (FRD).  Scalars in and out (no row
    views or scratch arrays: the compiled loop keeps them in registers)."""
    d0, d1, d2 = w0 - v0, w1 - v1, w2 - v2  # w - v, NED
    a0 = rotation[i, 0, 0] * d0 + rotation[i, 1, 0] * d1 + rotation[i, 2, 0] * d2  # R^T (w - v)
    a1 = rotation[i, 0, 1] * d0 + rotation[i, 1, 1] * d1 + rotation[i, 2, 1] * d2
    a2 = rotation[i, 0, 2] * d0 + rotation[i, 1, 2] * d1 + rotation[i, 2, 2] * d2
    x0, x1, x2 = cross_entries(o0, o1, o2, p0, p1, p2)  # Omega x p
    return a0 - x0, a1 - x1, a2 - x2


@njit(cache=True)
def aero_wrench_rows(rotation: NDArray[np.float64], velocity: NDArray[np.float64], rate: NDArray[np.float64],
                     rotor_speeds: NDArray[np.float64], wind: NDArray[np.float64], hubs: NDArray[np.float64],
                     cop: NDArray[np.float64], body_drag: NDArray[np.float64], k_d: float, k_r: float,
                     force: NDArray[np.float64], torque: NDArray[np.float64]) -> int:  # pragma: no cover - jitted
    """The wrench of the module docstring for every row into ``force`` (N, 3) NED and ``torque`` (N, 3) FRD.

    Returns -1, or the first row whose wrench is not finite (NaN/inf in its inputs).
    """
    c0, c1, c2 = cop[0], cop[1], cop[2]
    for i in range(rotation.shape[0]):
        v0, v1, v2 = velocity[i, 0], velocity[i, 1], velocity[i, 2]
        o0, o1, o2 = rate[i, 0], rate[i, 1], rate[i, 2]
        fb0, fb1, fb2 = 0.0, 0.0, 0.0  # sum_j F_j + F_b, body FRD
        t0, t1, t2 = 0.0, 0.0, 0.0  # tau, body FRD
        for j in range(hubs.shape[0]):
            h0, h1, h2 = hubs[j, 0], hubs[j, 1], hubs[j, 2]
            a0, a1, _ = _air_velocity(rotation, i, wind[i, j + 1, 0], wind[i, j + 1, 1], wind[i, j + 1, 2], v0, v1, v2,
                                      o0, o1, o2, h0, h1, h2)  # a_j
            drag = k_d * rotor_speeds[i, j]  # F_j = k_d omega_j P a_j,  P = diag(1, 1, 0)
            flap = k_r * rotor_speeds[i, j]  # M_j = k_r omega_j (a_j x e3) = k_r omega_j (a_y, -a_x, 0)
            f0, f1 = drag * a0, drag * a1  # F_j (its z component is 0)
            x0, x1, x2 = cross_entries(h0, h1, h2, f0, f1, 0.0)  # r_j x F_j
            t0 += x0 + flap * a1  # r_j x F_j + M_j
            t1 += x1 - flap * a0
            t2 += x2
            fb0 += f0
            fb1 += f1
        a0, a1, a2 = _air_velocity(rotation, i, wind[i, 0, 0], wind[i, 0, 1], wind[i, 0, 2], v0, v1, v2, o0, o1, o2,
                                   c0, c1, c2)  # a_0, at the centre of pressure
        speed = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        # F_b = D |a_0| a_0
        d0, d1, d2 = body_drag[0] * a0 * speed, body_drag[1] * a1 * speed, body_drag[2] * a2 * speed
        x0, x1, x2 = cross_entries(c0, c1, c2, d0, d1, d2)  # c x F_b
        t0 += x0
        t1 += x1
        t2 += x2
        fb0, fb1, fb2 = fb0 + d0, fb1 + d1, fb2 + d2
        for c in range(3):  # force = R (sum_j F_j + F_b), world NED
            force[i, c] = rotation[i, c, 0] * fb0 + rotation[i, c, 1] * fb1 + rotation[i, c, 2] * fb2
        torque[i, 0], torque[i, 1], torque[i, 2] = t0, t1, t2
        if not (math.isfinite(force[i, 0] + force[i, 1] + force[i, 2]) and math.isfinite(t0 + t1 + t2)):
            return i
    return -1


class AeroModel:
    """Wind + vehicle motion -> aerodynamic disturbance wrench, batch-first (module docstring).

    The coefficients ``k_d``, ``k_r``, ``cop`` (3,) and ``body_drag`` (3,) may be assigned (checked) or edited in
    place (``model.body_drag[2] = 0.05``) any time: they live in one array, :attr:`coefficients` (cop 0-2,
    body_drag 3-5, k_d 6, k_r 7), which an env shares with its step kernels (``HoverBatchEnv`` makes it a view of its
    parameter array), so a change acts from the env's next step on.  ``rotor_positions`` is the vehicle's geometry
    (also in the MuJoCo model and the allocation): read-only; build the env with a vehicle preset instead.
    """

    def __init__(self, preset: VehiclePreset) -> None:
        self.preset = preset
        hubs = np.array(preset.rotor_positions, dtype=float)  # (R, 3) body FRD
        hubs.flags.writeable = False
        self._rotor_positions = hubs
        self.n_rotors = hubs.shape[0]
        #: cop 0-2, body_drag 3-5, k_d 6, k_r 7 (class docstring; the properties are views of it)
        self._coefficients = np.concatenate([np.asarray(preset.cop_offset, dtype=float),
                                            np.asarray(preset.body_drag, dtype=float),
                                            [float(preset.rotor_drag), float(preset.rolling_moment)]])

    @property
    def coefficients(self) -> NDArray[np.float64]:
        """cop 0-2, body_drag 3-5, k_d 6, k_r 7 (8,): the one array the env's step kernels read (class docstring);
        edit it in place or assign ``k_d``, ``k_r``, ``cop``, ``body_drag`` (assigning the array itself would
        unlink it from the env: refused)."""
        return self._coefficients

    @coefficients.setter
    def coefficients(self, value: object) -> None:
        raise AttributeError("AeroModel.coefficients is the array the env's step kernels read: edit it in place or "
                             "assign k_d, k_r, cop, body_drag (checked) instead")

    def _share(self, array: NDArray[np.float64]) -> None:
        """Make ``array`` (8,) float64 (an env's step parameters, already holding these values) the coefficients."""
        self._coefficients = array

    @property
    def rotor_positions(self) -> NDArray[np.float64]:
        """Rotor hub positions (R, 3) body FRD [m], read-only (the vehicle's geometry)."""
        view = self._rotor_positions.view()
        view.flags.writeable = False  # (a copy of the model, e.g. deepcopy, would hold a writeable one)
        return view

    @rotor_positions.setter
    def rotor_positions(self, value: object) -> None:
        raise AttributeError("AeroModel.rotor_positions is the vehicle's geometry (also its MuJoCo model and "
                             "allocation) and cannot change after construction: build the env with a vehicle preset "
                             "(vehicle=VehiclePreset(...) or a mapping) instead")

    @property
    def k_d(self) -> float:
        """Linear rotor drag coefficient (``F_i = k_d omega_i P a_i``); assign a finite number >= 0."""
        return float(self._coefficients[6])

    @k_d.setter
    def k_d(self, value: object) -> None:
        self._coefficients[6] = _coefficient("k_d", value, (), nonnegative=True)

    @property
    def k_r(self) -> float:
        """Blade-flapping moment coefficient (``M_i = k_r omega_i (a_i x e3)``); assign a finite number."""
        return float(self._coefficients[7])

    @k_r.setter
    def k_r(self, value: object) -> None:
        self._coefficients[7] = _coefficient("k_r", value, (), nonnegative=False)

    @property
    def cop(self) -> NDArray[np.float64]:
        """Centre of pressure (3,) body FRD [m] (a view of :attr:`coefficients`); assign 3 finite numbers."""
        return self._coefficients[0:3]

    @cop.setter
    def cop(self, value: object) -> None:
        self._coefficients[0:3] = _coefficient("cop", value, (3,), nonnegative=False)

    @property
    def body_drag(self) -> NDArray[np.float64]:
        """Quadratic body drag per body axis (3,) [N/(m/s)^2] (a view of :attr:`coefficients`); assign 3 finite
        numbers >= 0."""
        return self._coefficients[3:6]

    @body_drag.setter
    def body_drag(self, value: object) -> None:
        self._coefficients[3:6] = _coefficient("body_drag", value, (3,), nonnegative=True)

    def wrench(self, rotation: NDArray[np.float64], velocity: NDArray[np.float64],
               angular_velocity: NDArray[np.float64], rotor_speeds: NDArray[np.float64],
               wind: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Force (N, 3) world NED [N] and torque (N, 3) body FRD [N m].

        ``rotation`` (N, 3, 3) body FRD -> NED, ``velocity`` (N, 3) NED, ``angular_velocity`` (N, 3)
        FRD, ``rotor_speeds`` (N, R) rad/s, ``wind`` (N, R + 1, 3) NED at [CoM, rotor 1..R].
        """
        rotation, velocity = as_f64(rotation, "rotation"), as_f64(velocity, "velocity")
        angular_velocity, rotor_speeds = as_f64(angular_velocity, "angular_velocity"), as_f64(rotor_speeds,
                                                                                             "rotor_speeds")
        wind = as_f64(wind, "wind")
        n, m = velocity.shape[0] if velocity.ndim else -1, self.n_rotors
        if velocity.shape != (n, 3) or wind.shape != (n, m + 1, 3) or rotation.shape != (n, 3, 3) \
                or angular_velocity.shape != (n, 3) or rotor_speeds.shape != (n, m):
            raise ValueError(f"AeroModel.wrench shapes must be rotation (N,3,3), velocity (N,3), angular_velocity "
                             f"(N,3), rotor_speeds (N,{m}), wind (N,{m + 1},3); got {rotation.shape}, "
                             f"{velocity.shape}, {angular_velocity.shape}, {rotor_speeds.shape}, {wind.shape}")
        force, torque = np.empty((n, 3)), np.empty((n, 3))
        if aero_wrench_rows(rotation, velocity, angular_velocity, rotor_speeds, wind, self.rotor_positions,
                            self.cop, self.body_drag, self.k_d, self.k_r, force, torque) >= 0:
            raise ValueError("aerodynamic wrench is not finite: check rotation, velocity, angular_velocity, "
                             "rotor_speeds and wind for NaN/inf")
        return force, torque


def _coefficient(name: str, value: object, shape: tuple[int, ...], nonnegative: bool) -> NDArray[np.float64]:
    """An aero coefficient assigned to :class:`AeroModel`, checked: ``shape``, finite (and >= 0)."""
    try:
        raw = np.asarray(value)
    except ValueError:  # ragged nested sequences
        raw = np.asarray(None)
    v = raw.astype(np.float64) if raw.dtype.kind in "iuf" else np.array(np.nan)  # bool/complex/str refused
    if v.shape != shape or not np.all(np.isfinite(v)) or (nonnegative and np.any(v < 0)):
        what = "a finite number" if not shape else f"{shape[0]} finite numbers"
        raise ValueError(f"AeroModel.{name} must be {what}{' >= 0' if nonnegative else ''}, got {shown(value)}")
    return v


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
