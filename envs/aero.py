"""Aerodynamics: wind at the vehicle -> disturbance force (world NED) and torque (body FRD).

First version (issue 2): linear rotor drag per rotor and quadratic body drag at the CoM.  The
wind issue extends this model (rolling moments, centre-of-pressure lever arm, differential wind
across the rotor discs) and calibrates it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .vehicles import VehiclePreset


class AeroModel:
    """Wind + vehicle motion -> aerodynamic disturbance wrench, batch-first."""

    def __init__(self, preset: VehiclePreset) -> None:
        self.preset = preset
        self.rotor_positions = preset.rotor_positions  # (4, 3) body FRD

    def wrench(self, rotation: NDArray[np.float64], velocity: NDArray[np.float64],
               angular_velocity: NDArray[np.float64], rotor_speeds: NDArray[np.float64],
               wind: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Force (N, 3) world NED [N] and torque (N, 3) body FRD [N m].

        ``rotation`` (N, 3, 3) body FRD -> NED, ``velocity`` (N, 3) NED, ``angular_velocity`` (N, 3)
        FRD, ``rotor_speeds`` (N, 4) rad/s, ``wind`` (N, 5, 3) NED at [CoM, rotor 1..4].
        """
        p = self.preset
        # air velocity relative to the CoM, in body FRD
        rel_ned = wind[:, 0, :] - velocity
        rel_body = np.einsum("nji,nj->ni", rotation, rel_ned)
        inplane = rel_body.copy()
        inplane[:, 2] = 0.0
        f_rotor = p.rotor_drag * rotor_speeds.sum(axis=1)[:, None] * inplane
        f_body = np.asarray(p.body_drag) * np.abs(rel_body) * rel_body
        force_body = f_rotor + f_body
        force_ned = np.einsum("nij,nj->ni", rotation, force_body)
        return force_ned, np.zeros_like(force_ned)
