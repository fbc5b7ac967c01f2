"""Frames of ``fawtgym/Hover-v0``: the vehicle hovering in front of the fan array, with a height cue and the wind.

Everything but the vehicle and the floor is drawn at render time as scene decoration (MuJoCo
``mjvScene`` geoms), so the physics model carries no geometry it does not need:

* the fan array of Wang et al. (2024), Sec. 7.1: a 1.44 m x 0.72 m wall of 18 x 9 = 162 fans of
  80 mm pitch, its face centred 1.5 m above the floor, the jet blowing north (+x) towards the hover
  point 1.5 m downstream (:data:`fawtgym.core.frames.FAWT_ORIGIN_NED`);
* the wind: a bold orange arrow at the vehicle is the wind vector at its centre of mass (the
  ``info["truth"]["wind"]`` of the last step), 0.1 m per m/s; the blue streaks across the jet carry
  the same vector at 0.14 m per m/s (the wind at the vehicle drawn across the jet, not a flow-field
  solution); in still air no arrow is drawn;
* the height: a red-and-white surveyor's pole beside the hover point in 0.5 m bands (2.5 m), a drop
  line from the vehicle to the floor and a dark disc (a shadow) where it meets the floor; the set
  point is a small green sphere.

Speed: MuJoCo's offscreen renderer runs on the CPU where there is no GPU (EGL or OSMesa on llvmpipe).
Multisampling and shadow maps dominate its cost there (480 x 480: 3.8 frames/s with MuJoCo's
defaults, about 25 with this scene without them, on the project's 2-core machine), so the model asks
for neither (``<quality offsamples="0" shadowsize="0" numslices="12"/>``, reflections off); the
decoration costs about 3 ms a frame.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from numpy.typing import NDArray

from fawtgym.core.frames import FAWT_ORIGIN_NED, vec_ned_to_mj

#: fan array (Wang et al. 2024, Sec. 7.1): columns x rows of fans, fan pitch [m], face centre (MuJoCo frame)
FAN_COLUMNS, FAN_ROWS, FAN_PITCH = 18, 9, 0.08
FAN_FACE_MJ = vec_ned_to_mj(FAWT_ORIGIN_NED)
#: arrow length per wind speed [m per m/s]
WIND_SCALE = 0.1
#: surveyor's pole: band length [m] and number of bands
POLE_BAND, POLE_BANDS = 0.5, 5

_X_TO_Z = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # maps local z onto world +x
_EYE = np.eye(3)


class HoverRenderer:
    """Offscreen RGB frames of one hover env (see the module docstring for what is drawn)."""

    def __init__(self, model: mujoco.MjModel, width: int, height: int, body_id: int) -> None:
        self._renderer = mujoco.Renderer(model, height, width, max_geom=1000)
        self._body = body_id
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance = 3.6
        self.camera.azimuth = 140.0
        self.camera.elevation = -30.0
        self._static = self._fan_array()
        #: MuJoCo's shadows and floor reflections (off: they dominate the cost of CPU rendering)
        self.shadows = False
        self.reflections = False

    def _fan_array(self) -> list[tuple[int, NDArray, NDArray, NDArray, NDArray]]:
        """(type, size, pos, mat, rgba) of the frame and the 162 fans, built once."""
        geoms = []
        half_w, half_h = FAN_COLUMNS * FAN_PITCH / 2, FAN_ROWS * FAN_PITCH / 2
        c = FAN_FACE_MJ
        geoms.append((int(mujoco.mjtGeom.mjGEOM_BOX), np.array([0.06, half_w + 0.03, half_h + 0.03]),
                      c + np.array([-0.065, 0.0, 0.0]), _EYE, np.array([0.22, 0.23, 0.26, 1.0])))
        for leg in (-1.0, 1.0):  # the stand
            geoms.append((int(mujoco.mjtGeom.mjGEOM_BOX), np.array([0.04, 0.04, (c[2] - half_h) / 2]),
                          np.array([c[0] - 0.065, leg * (half_w - 0.1), (c[2] - half_h) / 2]), _EYE,
                          np.array([0.3, 0.3, 0.32, 1.0])))
        for i in range(FAN_COLUMNS):
            for j in range(FAN_ROWS):
                pos = c + np.array([0.0, (i + 0.5) * FAN_PITCH - half_w, (j + 0.5) * FAN_PITCH - half_h])
                geoms.append((int(mujoco.mjtGeom.mjGEOM_CYLINDER), np.array([0.036, 0.006, 0.0]), pos, _X_TO_Z,
                              np.array([0.55, 0.58, 0.62, 1.0])))
                geoms.append((int(mujoco.mjtGeom.mjGEOM_CYLINDER), np.array([0.009, 0.008, 0.0]),
                              pos + np.array([0.003, 0.0, 0.0]), _X_TO_Z, np.array([0.1, 0.1, 0.1, 1.0])))
        return geoms

    def _add(self, scene: mujoco.MjvScene, gtype: int, size: NDArray, pos: NDArray, mat: NDArray,
             rgba: NDArray) -> None:
        if scene.ngeom >= scene.maxgeom:
            return
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], gtype, size, pos, mat.ravel(), rgba)
        scene.ngeom += 1

    def _connector(self, scene: mujoco.MjvScene, gtype: int, width: float, a: NDArray, b: NDArray,
                   rgba: NDArray) -> None:
        if scene.ngeom >= scene.maxgeom or float(np.linalg.norm(b - a)) < 1e-6:
            return
        g = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(g, gtype, np.zeros(3), np.zeros(3), _EYE.ravel(), rgba.astype(np.float32))
        mujoco.mjv_connector(g, gtype, width, a, b)
        scene.ngeom += 1

    def render(self, data: mujoco.MjData, setpoint_ned: NDArray, wind_ned: NDArray) -> NDArray[np.uint8]:
        """One frame, (height, width, 3) uint8."""
        r = self._renderer
        vehicle = np.array(data.xpos[self._body])
        self.camera.lookat[:] = 0.5 * (vehicle + FAN_FACE_MJ) + np.array([0.1, 0.0, -0.35])
        r.update_scene(data, camera=self.camera)
        scene = r.scene
        scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = int(self.shadows)
        scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = int(self.reflections)
        for geom in self._static:
            self._add(scene, *geom)
        # height: surveyor's pole beside the hover point, drop line and floor ring under the vehicle
        sp = vec_ned_to_mj(setpoint_ned)
        pole = np.array([sp[0] - 0.2, sp[1] + 1.0, 0.0])
        for k in range(POLE_BANDS):
            rgba = np.array([0.85, 0.15, 0.12, 1.0]) if k % 2 == 0 else np.array([0.95, 0.95, 0.95, 1.0])
            self._connector(scene, int(mujoco.mjtGeom.mjGEOM_CAPSULE), 0.018, pole + [0, 0, k * POLE_BAND],
                            pole + [0, 0, (k + 1) * POLE_BAND], rgba)
        ground = np.array([vehicle[0], vehicle[1], 0.002])
        self._connector(scene, int(mujoco.mjtGeom.mjGEOM_LINE), 2.0, vehicle, ground,
                        np.array([0.9, 0.9, 0.9, 0.8]))
        self._add(scene, int(mujoco.mjtGeom.mjGEOM_CYLINDER), np.array([0.15, 0.004, 0.0]), ground, _EYE,
                  np.array([0.1, 0.1, 0.12, 0.75]))
        self._add(scene, int(mujoco.mjtGeom.mjGEOM_SPHERE), np.array([0.025, 0.0, 0.0]), sp, _EYE,
                  np.array([0.1, 0.85, 0.2, 0.6]))
        # wind: the vector at the vehicle, and the same vector drawn as streaks across the jet
        w = vec_ned_to_mj(wind_ned)
        speed = float(np.linalg.norm(w))
        if math.isfinite(speed) and speed > 0.05:
            arrow = w * WIND_SCALE
            self._connector(scene, int(mujoco.mjtGeom.mjGEOM_ARROW), 0.018, vehicle - arrow, vehicle,
                            np.array([1.0, 0.55, 0.05, 1.0]))
            for dy in (-0.5, -0.25, 0.0, 0.25, 0.5):
                for dz in (-0.22, 0.0, 0.22):
                    if dy == 0.0 and dz == 0.0:
                        continue  # the vehicle's own arrow is on the axis
                    start = FAN_FACE_MJ + np.array([0.1, dy, dz])
                    self._connector(scene, int(mujoco.mjtGeom.mjGEOM_ARROW), 0.009, start, start + 1.4 * arrow,
                                    np.array([0.2, 0.6, 1.0, 0.8]))
        return r.render()

    def close(self) -> None:
        self._renderer.close()
