"""The vehicle PX4 flies in the bridge: the Iris of PX4's airframe 10016 ``none_iris``, as our preset.

PX4 v1.14 ``ROMFS/px4fmu_common/init.d-posix/airframes/10016_none_iris`` (the SITL airframe without a
simulator of its own, which starts ``simulator_mavlink``) sets the control allocation geometry
(``CA_ROTORn_PX/PY`` [m], body FRD; ``CA_ROTORn_KM`` > 0 for a counter-clockwise rotor seen from above) and
maps PWM outputs 1-4 to motors 1-4 (``PWM_MAIN_FUNCn = 100 + n``), so HIL_ACTUATOR_CONTROLS ``controls[i]``
is PX4 motor ``i + 1``:

======  ==========================  ==========  ====================
PX4     CA_ROTORn_PX, _PY (FRD, m)  spin        our rotor (index)
======  ==========================  ==========  ====================
motor1  ( 0.1515,  0.245)           CCW (+KM)   front-right, CCW (0)
motor2  (-0.1515, -0.1875)          CCW (+KM)   rear-left,   CCW (1)
motor3  ( 0.1515, -0.245)           CW  (-KM)   front-left,  CW  (2)
motor4  (-0.1515,  0.1875)          CW  (-KM)   rear-right,  CW  (3)
======  ==========================  ==========  ====================

(:data:`PX4_MOTOR_TO_ROTOR` holds the last column; a test pins it against the table.)

Mass, inertia and rotor constants are those of the Gazebo-classic Iris that PX4's ``none_iris`` tuning was
made for (PX4-SITL_gazebo-classic ``models/iris/iris.sdf.jinja``): base 1.5 kg plus four 5 g rotors, a 15 g
IMU and a 10 g GPS (1.545 kg), Ixx = Iyy = 0.029125, Izz = 0.055225 kg m^2, motorConstant 5.84e-6
N/(rad/s)^2, momentConstant 0.06 m, timeConstantUp/Down 0.0125/0.025 s, maxRotVelocity 1100 rad/s,
rotorDragCoefficient 1.75e-4, rollingMomentCoefficient 1e-6, propeller radius 0.128 m.  Gazebo's
``mavlink_interface`` turns a motor control ``u`` in [0, 1] into the rotor speed reference
``100 + 1000 u`` rad/s when armed (``input_scaling`` 1000, ``zero_position_armed`` 100), which is our motor
model ``omega_min + u (omega_max - omega_min)`` with ``omega_min = 100``, ``omega_max = 1100``.  The rotor hubs
are placed where PX4's allocation believes them (the CA table above; the Gazebo model's own hubs differ by a
few cm), so PX4's mixer and our physics agree.  Body drag: the docs/wind.md rule for a 1.5 kg quad.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.checks import shown
from fawtgym.envs.vehicles import VehiclePreset

#: PX4 airframe the preset matches (SYS_AUTOSTART) and its model name (PX4_SIM_MODEL)
PX4_AIRFRAME_ID = 10016
PX4_SIM_MODEL = "none_iris"

#: PX4 ``CA_ROTORn_PX``, ``CA_ROTORn_PY`` [m] (body FRD) and the sign of ``CA_ROTORn_KM`` (+1 = CCW), n = 0..3
PX4_ROTORS = ((0.1515, 0.245, 1.0), (-0.1515, -0.1875, 1.0), (0.1515, -0.245, -1.0), (-0.1515, 0.1875, -1.0))

#: HIL_ACTUATOR_CONTROLS index (PX4 motor number - 1) -> our rotor index
PX4_MOTOR_TO_ROTOR = (0, 1, 2, 3)


@dataclasses.dataclass(frozen=True)
class AirframePreset(VehiclePreset):
    """A :class:`VehiclePreset` whose rotor hubs are given explicitly (an airframe that is not a square X).

    ``rotor_xy`` holds the four hub positions (x, y) in body FRD [m] in our rotor order; hubs lie in the
    body's xy plane (z = 0) as in every preset.
    """

    rotor_xy: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        super().__post_init__()
        xy = np.asarray(self.rotor_xy, dtype=float)
        if xy.shape != (4, 2) or not np.all(np.isfinite(xy)):
            raise ValueError(f"vehicle field 'rotor_xy' must be 4 finite (x, y) pairs, got {shown(self.rotor_xy)}")
        object.__setattr__(self, "rotor_xy", tuple(tuple(float(v) for v in p) for p in xy))

    @property
    def rotor_positions(self) -> NDArray[np.float64]:
        """Rotor hub positions in body FRD, shape (4, 3) [m], our rotor order (= PX4's motor order)."""
        xy = np.asarray(self.rotor_xy, dtype=float)
        return np.column_stack([xy, np.zeros(4)])


def iris() -> AirframePreset:
    """The Iris of PX4 SITL airframe 10016 ``none_iris`` (see the module docstring for every number)."""
    by_rotor = {PX4_MOTOR_TO_ROTOR[motor]: (px, py) for motor, (px, py, _) in enumerate(PX4_ROTORS)}
    hubs = [by_rotor[rotor] for rotor in range(4)]
    arm = float(np.mean([math.hypot(px, py) for px, py, _ in PX4_ROTORS]))
    return AirframePreset(
        name="iris", mass=1.545, inertia=(0.029125, 0.029125, 0.055225), arm_length=arm,
        k_thrust=5.84e-6, k_moment=0.06, omega_min=100.0, omega_max=1100.0, tau_up=0.0125, tau_down=0.025,
        rotor_radius=0.128, rotor_drag=1.75e-4, rolling_moment=1e-6, body_drag=(0.022, 0.022, 0.04),
        source="PX4 v1.14 airframe 10016_none_iris (geometry, motor order); PX4-SITL_gazebo-classic iris (mass, "
               "inertia, rotors)",
        rotor_xy=tuple(hubs),
    )


def motors_from_px4(controls: NDArray[np.float64] | list[float]) -> NDArray[np.float64]:
    """Our motor commands (4,) in rotor order from PX4's HIL_ACTUATOR_CONTROLS ``controls[0..3]``."""
    out = np.zeros(4)
    for motor, rotor in enumerate(PX4_MOTOR_TO_ROTOR):
        out[rotor] = float(controls[motor])
    return out


def motors_to_px4(motors: NDArray[np.float64] | list[float]) -> NDArray[np.float64]:
    """Inverse of :func:`motors_from_px4`: PX4 ``controls[0..3]`` from our rotor-order commands."""
    return np.array([float(motors[rotor]) for rotor in PX4_MOTOR_TO_ROTOR])
