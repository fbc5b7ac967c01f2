"""MJCF generated from a vehicle preset: one free body, four rotor sites, a floor.

Actuators (all ``ctrl`` in physical units, unlimited):

* ``rotor1..4``: site transmission at each rotor hub, gear (0, 0, 1, 0, 0, -d_i k_M) in the FLU
  site frame: ``ctrl`` is the rotor thrust [N] pushing along body up (= -z FRD), and the rotor's
  reaction torque ``d_i k_M T`` about FRD z (= -z FLU).

Contacts are disabled: the only thing the vehicle could touch is the floor, and touching it ends the
episode, which the env detects analytically from the hull and rotor points (:func:`hull_points`);
MuJoCo's collision pipeline would cost a quarter of every physics step for nothing.

The disturbance wrench goes straight into the free joint's generalized force ``data.qfrc_applied``
(the free joint's six dofs): the body frame is at the CoM, so ``qfrc_applied[0:3]`` is a world-frame force
at the CoM and ``qfrc_applied[3:6]`` a torque in body axes (MuJoCo's free-joint rotational dofs are
body-local), i.e. a body-fixed torque over a control step.  No Jacobian is needed (an ``xfrc_applied``
force and three torque actuators cost MuJoCo ~15 % of a step for the same wrench).  Gravity is
``GRAVITY`` along -z.  The fan array and the other scene cues are drawn at render time only
(:mod:`fawtgym.envs.render`); offscreen rendering asks for no multisampling and no shadow map (the
two dominate the cost of CPU rendering).  The body frame is the CoM frame (``inertial pos = 0``),
principal or full inertia from the preset.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from fawtgym.core.checks import shown
from fawtgym.core.frames import vec_ned_to_mj

from .vehicles import GRAVITY, VehiclePreset

#: MuJoCo integrators allowed by the env; the default is justified in :class:`HoverEnv`.
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")


def hull_half_size(preset: VehiclePreset) -> tuple[float, float]:
    """Half sizes (horizontal, vertical) [m] of the hull box drawn and used for ground contact."""
    return 0.25 * preset.arm_length, 0.04


def hull_points(preset: VehiclePreset) -> np.ndarray:
    """Body-FRD points whose height decides ground contact: the 8 hull corners and the 4 rotor hubs, (12, 3)."""
    h, hz = hull_half_size(preset)
    corners = np.array([[sx * h, sy * h, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return np.vstack([corners, preset.rotor_positions])


def vehicle_mjcf(preset: VehiclePreset, physics_dt: float = 0.001, integrator: str = "Euler",
                 render_width: int = 640, render_height: int = 480) -> str:
    """Return the MJCF text for ``preset``."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"unknown integrator {shown(integrator)}; valid: {list(INTEGRATORS)}")
    j = preset.inertia_matrix
    full = " ".join(f"{x:.9g}" for x in (j[0, 0], j[1, 1], j[2, 2], j[0, 1], j[0, 2], j[1, 2]))
    r = preset.rotor_radius
    body_half, body_half_z = hull_half_size(preset)
    rotors = []
    actuators = []
    for i, (pos, d) in enumerate(zip(preset.rotor_positions, preset.rotor_directions, strict=True), start=1):
        p = vec_ned_to_mj(pos)
        color = "0.85 0.2 0.2 0.6" if i in (1, 3) else "0.2 0.2 0.85 0.6"  # front red, back blue
        rotors.append(
            f'<site name="rotor{i}" pos="{p[0]:.6g} {p[1]:.6g} {p[2] + 0.02:.6g}" size="0.005"/>\n'
            f'      <geom name="arm{i}" type="capsule" fromto="0 0 0 {p[0]:.6g} {p[1]:.6g} 0" size="0.008" '
            f'contype="0" conaffinity="0" mass="0" rgba="0.3 0.3 0.3 1"/>\n'
            f'      <geom name="prop{i}" type="cylinder" pos="{p[0]:.6g} {p[1]:.6g} {p[2] + 0.02:.6g}" '
            f'size="{r:.6g} 0.003" contype="0" conaffinity="0" mass="0" rgba="{color}"/>')
        actuators.append(f'<general name="rotor{i}" site="rotor{i}" gear="0 0 1 0 0 {-d * preset.k_moment:.9g}"/>')
    rotor_xml = "\n      ".join(rotors)
    act_xml = "\n    ".join(actuators)
    return f"""<mujoco model={quoteattr("fawtgym_" + preset.name)}>
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{physics_dt:.9g}" integrator="{integrator}" gravity="0 0 {-GRAVITY:.9g}" density="0" viscosity="0">
    <flag contact="disable" constraint="disable"/>
  </option>
  <visual>
    <global offwidth="{render_width}" offheight="{render_height}"/>
    <quality offsamples="0" shadowsize="0" numslices="12" numstacks="2"/>
    <headlight ambient="0.35 0.35 0.35" diffuse="0.5 0.5 0.5"/>
  </visual>
  <asset>
    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.72 0.8 0.9" rgb2="0.95 0.96 0.98"
             width="64" height="64"/>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.62 0.64 0.66" rgb2="0.68 0.7 0.72"
             width="256" height="256"/>
    <material name="grid" texture="grid" texrepeat="10 10"/>
  </asset>
  <worldbody>
    <light pos="0 0 6" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" size="5 5 0.1" material="grid"/>
    <body name="vehicle" pos="0 0 1.5">
      <freejoint name="root"/>
      <inertial pos="0 0 0" mass="{preset.mass:.9g}" fullinertia="{full}"/>
      <site name="com" pos="0 0 0" size="0.01"/>
      <geom name="hull" type="box" size="{body_half:.6g} {body_half:.6g} {body_half_z:.6g}" mass="0"
            rgba="0.15 0.15 0.15 1"/>
      {rotor_xml}
    </body>
  </worldbody>
  <actuator>
    {act_xml}
  </actuator>
</mujoco>
"""
