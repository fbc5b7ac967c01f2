"""The vehicle the bridge simulates: :class:`~fawtgym.envs.hover_env.HoverEnv` (physics, motors, wind, sensors)
stepped by motor commands, plus a ground to stand on before take-off.

The env has no ground contact (touching the floor ends its episodes, and MuJoCo contacts are off).  An
autopilot arms on the ground, so :class:`SitlVehicle` adds one through the env's public external wrench: a
spring-damper normal force at the lowest hull point (stiffness for a 5 Hz bounce, critically damped), viscous
friction on the horizontal velocity and a restoring/damping torque that keeps the vehicle level while it rests.
The force is computed from the state at the start of a step and held over it (the env's rule for every
external wrench), so at rest the accelerometer reads the specific force ``-g`` on body z through the env's own
sensor path.  The env's ``ground_contact`` / ``out_of_bounds`` terminations are ignored here; ``diverged``
raises :class:`~fawtgym.eval.sitl.mavio.SitlError`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.constants import GRAVITY
from fawtgym.core.frames import FAWT_HOVER_POINT_NED
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.mjcf import hull_points
from fawtgym.envs.vehicles import VehiclePreset, make_vehicle

from .airframe import iris
from .mavio import SitlError

GROUND_BOUNCE_HZ = 5.0  #: natural frequency of the ground spring with the vehicle's mass [Hz]


def ground_start(preset: VehiclePreset, xy: ArrayLike = FAWT_HOVER_POINT_NED[:2]) -> NDArray[np.float64]:
    """The NED position of the vehicle's CoM resting level on the ground at horizontal position ``xy``
    (the spring's static deflection included)."""
    hull_bottom = float(hull_points(preset)[:, 2].max())
    sag = GRAVITY / (2.0 * math.pi * GROUND_BOUNCE_HZ) ** 2
    x, y = (float(v) for v in np.ravel(xy))
    return np.array([x, y, -hull_bottom + sag])


class SitlVehicle:
    """HoverEnv + ground, stepped by motor commands at ``1 / step_seconds``.

    Args:
        vehicle: preset (default the PX4 ``none_iris`` Iris of :mod:`.airframe`).
        wind: any ``wind=`` value of the env (a name such as ``fawt-50`` or a mapping with a schedule).
        sensors: env sensor preset (a pose rate must divide the step rate; default ``seed000``).
        start: initial CoM position, NED [m] (default: on the ground below the FAWT hover point).
        step_seconds: the lockstep period (PX4's 250 Hz IMU: 0.004 s); physics runs at ``physics_rate``.
        seed: seeds the wind and the sensor noise.
    """

    def __init__(self, vehicle: VehiclePreset | str | Mapping[str, Any] | None = None,
                 wind: str | Mapping[str, Any] | None = "calm", sensors: Any = "seed000",
                 start: ArrayLike | None = None, step_seconds: float = 0.004, physics_rate: float = 1000.0,
                 seed: int = 0) -> None:
        preset = iris() if vehicle is None else make_vehicle(vehicle)
        self.env = HoverEnv(vehicle=preset, wind=wind, action_type="motors", sensors=sensors,
                            control_rate=1.0 / step_seconds, physics_rate=physics_rate, episode_seconds=1e9,
                            setpoint=ground_start(preset) if start is None else start, init_noise=0.0,
                            max_position_error=1e9)
        self.preset = self.env.preset
        self.dt = self.env.dt
        m, j = self.preset.mass, self.preset.inertia_matrix
        wn = 2.0 * math.pi * GROUND_BOUNCE_HZ
        self._k, self._c = m * wn * wn, 2.0 * m * wn
        self._kt = float(np.diag(j)[:2].max()) * wn * wn
        self._ct = 2.0 * float(np.diag(j).max()) * wn
        self._hull = hull_points(self.preset)
        self._ground = (np.zeros(3), np.zeros(3))  # the env starts with no external wrench
        _, self.info = self.env.reset(seed=seed)
        self._aero = self._aero_from_info()
        self._acc = np.zeros(3)
        self._update_ground()

    @property
    def time(self) -> float:
        return float(self.env.time)

    @property
    def measurement(self) -> dict[str, NDArray[np.float64]]:
        return self.info["measurement"]

    @property
    def truth(self) -> dict[str, NDArray[np.float64]]:
        return self.info["truth"]

    @property
    def acceleration(self) -> NDArray[np.float64]:
        """True NED acceleration over the last step [m/s^2] (difference of the true velocities)."""
        return self._acc

    @property
    def on_ground(self) -> bool:
        return self._in_contact

    @property
    def aero_wrench(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The env's aerodynamic (wind) disturbance held over the next step: force world NED [N], torque body FRD
        [N m], exactly as the env applies it (its ``info["truth"]`` force/torque minus our ground wrench)."""
        return self._aero

    @property
    def ground_wrench(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The ground contact wrench held over the next step (force NED [N], torque FRD [N m]; zero in the air)."""
        return self._ground

    def _aero_from_info(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``info["truth"]`` reports the aero wrench of the next step plus the external wrench in force when the
        info was made (our ground wrench of the step just taken); remove the latter."""
        t = self.info["truth"]
        return np.asarray(t["force"]) - self._ground[0], np.asarray(t["torque"]) - self._ground[1]

    def _update_ground(self) -> None:
        """The ground wrench for the next step from the current true state (zero in the air)."""
        t = self.info["truth"]
        r, p, v, w = t["attitude"], t["position"], t["velocity"], t["angular_velocity"]
        depth = float((p[2] + self._hull @ r[2]).max())  # lowest hull point below the floor (z_NED > 0)
        self._in_contact = depth >= 0.0
        if not self._in_contact:
            self._ground = (np.zeros(3), np.zeros(3))
            self.env.set_external_wrench(*self._ground)
            return
        normal = min(0.0, -(self._k * depth + self._c * float(v[2])))  # pushes up (NED -z), never pulls
        force = (-self._c * float(v[0]), -self._c * float(v[1]), normal)
        tilt = np.array([r[2, 1], -r[2, 0], 0.0])  # ~ (roll, pitch) for small angles, from R's last row
        torque = -self._kt * tilt - self._ct * np.asarray(w, dtype=float)
        self._ground = (np.array(force, dtype=float), torque)
        self.env.set_external_wrench(*self._ground)

    def step(self, motors: ArrayLike) -> dict[str, Any]:
        """One step with motor commands (4,) in [0, 1] (our rotor order); returns the env's info."""
        _, _, _, _, info = self.env.step(np.asarray(motors, dtype=float))
        if info["failure"] == "diverged":
            raise SitlError(f"the simulated vehicle diverged at t = {self.env.time:.3f} s")
        self._acc = (info["truth"]["velocity"] - self.info["truth"]["velocity"]) / self.dt
        self.info = info
        self._aero = self._aero_from_info()
        self._update_ground()
        return info
