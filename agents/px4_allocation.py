"""PX4-style control allocation for a quad X, and the physical <-> normalized wrench mapping.

Effectiveness.  PX4's control allocator (``control_allocator`` module, ``ActuatorEffectivenessRotors``)
builds, per rotor with normalized thrust ``t_i`` in [0, 1], the moment and force it produces.  Here
the rotor's physical thrust is ``T_i = T_max t_i`` with ``T_max = k_T omega_max^2`` of the vehicle
preset, so the effectiveness on the control axes ``[M_x, M_y, M_z, F_z]`` (body FRD, ``F_z = -f``) is
``T_max`` times the rows of :func:`fawtgym.envs.motors.allocation_matrix`.

Mixing.  ``mix = pinv(B)``, normalized per column as PX4's ``ControlAllocationPseudoInverse``:
roll and pitch share ``s_rp = max_j sqrt(|mix_j|^2 / (nnz_j / 2))``, yaw uses ``s_y = max(mix_yaw)``,
thrust uses the mean rotor-row norm ``s_t``; entries below 1e-3 are zeroed.  Desaturation is PX4's
``ControlAllocationSequentialDesaturation`` with airmode disabled: mix roll/pitch/thrust, reduce thrust
only, then roll, then pitch; add yaw, desaturate yaw with 15 % head-room above full thrust, then reduce
thrust only again; finally clip to [0, 1].

Physical mapping (derived, not tuned).  For unsaturated commands the normalized control ``c`` gives
the physical wrench ``W_phys = c / s`` per axis, so

* collective thrust ``f = thrust_scale * c_T`` with ``thrust_scale = 1 / s_t = 4 T_max`` [N],
* torque ``tau = torque_scale * c_tau`` with ``torque_scale = (1/s_rp, 1/s_rp, 1/s_y)``; for a quad X of
  arm ``l`` this is ``(2 l T_max, 2 l T_max, 4 k_M T_max)`` [N m].

These are the units in which the observer feedforward ``tau = tau0 - tau_hat`` is subtracted.
Rotor thrusts become the env's ``"motors"`` commands through the exact inverse of the preset's
steady-state rotor map (:func:`fawtgym.envs.motors.thrust_to_command`), i.e. a perfectly calibrated
thrust curve (PX4's ``THR_MDL_FAC`` tuned to the rotor).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.envs.motors import allocation_matrix, thrust_to_command
from fawtgym.envs.vehicles import VehiclePreset

_FLT_EPS = 1.1920929e-07
ROLL, PITCH, YAW, THRUST_Z = 0, 1, 2, 3


class QuadXAllocation:
    """Normalized torque (N, 3) + collective thrust (N,) -> rotor thrusts in [0, 1] (N, 4) and motor commands."""

    def __init__(self, preset: VehiclePreset) -> None:
        self.preset = preset
        self.max_rotor_thrust = preset.max_thrust_per_rotor
        b_phys = allocation_matrix(preset)  # rows: f, tau_x, tau_y, tau_z per unit rotor thrust [N]
        #: effectiveness on [M_x, M_y, M_z, F_z] per unit normalized rotor thrust
        self.effectiveness = self.max_rotor_thrust * np.vstack([b_phys[1], b_phys[2], b_phys[3], -b_phys[0]])
        mix = np.linalg.pinv(self.effectiveness)  # (4 rotors, 4 axes)
        nnz_r = np.count_nonzero(np.abs(mix[:, ROLL]) > 1e-3)
        nnz_p = np.count_nonzero(np.abs(mix[:, PITCH]) > 1e-3)
        s_r = np.sqrt(mix[:, ROLL] @ mix[:, ROLL] / (nnz_r / 2.0)) if nnz_r else 1.0
        s_p = np.sqrt(mix[:, PITCH] @ mix[:, PITCH] / (nnz_p / 2.0)) if nnz_p else 1.0
        s_rp = max(s_r, s_p)
        s_y = float(mix[:, YAW].max())
        s_t = float(np.mean(np.abs(mix[:, THRUST_Z])))
        self.scale = np.array([s_rp, s_rp, s_y, s_t])
        mix_n = mix / self.scale
        mix_n[np.abs(mix_n) < 1e-3] = 0.0
        self.mix = mix_n
        #: N m per unit normalized torque, per axis (roll, pitch, yaw)
        self.torque_scale = 1.0 / self.scale[:3]
        #: N per unit normalized collective thrust
        self.thrust_scale = float(1.0 / self.scale[3])

    # ---- unit conversions ---------------------------------------------------------------------
    def torque_to_normalized(self, torque: ArrayLike) -> NDArray[np.float64]:
        """Body torque (..., 3) [N m] -> normalized torque."""
        return np.asarray(torque, dtype=float) / self.torque_scale

    def normalized_to_torque(self, torque_norm: ArrayLike) -> NDArray[np.float64]:
        return np.asarray(torque_norm, dtype=float) * self.torque_scale

    def thrust_to_normalized(self, thrust: ArrayLike) -> NDArray[np.float64]:
        """Collective thrust [N] -> normalized collective thrust."""
        return np.asarray(thrust, dtype=float) / self.thrust_scale

    # ---- allocation ---------------------------------------------------------------------------
    def allocate(self, torque_norm: ArrayLike,
                 thrust_norm: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Rotor normalized thrusts (N, 4) in [0, 1] and the unallocated normalized control (N, 4).

        ``torque_norm`` (N, 3), ``thrust_norm`` (N,) collective in [0, 1] (upward).  The unallocated
        part ``c_sp - c_achieved`` on [roll, pitch, yaw, F_z] feeds the rate loop's saturation flags.
        """
        tau = np.atleast_2d(np.asarray(torque_norm, dtype=float))
        thr = np.atleast_1d(np.asarray(thrust_norm, dtype=float)).reshape(-1)
        c = np.concatenate([tau, -thr[:, None]], axis=1)  # (N, 4): roll, pitch, yaw, F_z
        m = self.mix
        act = c[:, [ROLL, PITCH, THRUST_Z]] @ m[:, [ROLL, PITCH, THRUST_Z]].T
        act = self._desaturate(act, m[:, THRUST_Z], increase_only=True)
        act = self._desaturate(act, m[:, ROLL])
        act = self._desaturate(act, m[:, PITCH])
        # mixYaw: add yaw, allow 15 % head-room for yaw above full thrust, then reduce thrust only
        act = act + c[:, YAW:YAW + 1] * m[:, YAW]
        act = self._desaturate(act, m[:, YAW], upper=1.15)
        act = self._desaturate(act, m[:, THRUST_Z], increase_only=True)
        act = np.clip(act, 0.0, 1.0)
        achieved = (act @ self.effectiveness.T) * self.scale
        return act, c - achieved

    @staticmethod
    def _gain(vec: NDArray[np.float64], act: NDArray[np.float64], upper: float) -> NDArray[np.float64]:
        """computeDesaturationGain: k_min + k_max over the saturated actuators (N,)."""
        use = np.abs(vec) >= _FLT_EPS
        safe = np.where(use, vec, 1.0)
        k_lo = np.where(use & (act < 0.0), (0.0 - act) / safe, 0.0)
        k_hi = np.where(use & (act > upper), (upper - act) / safe, 0.0)
        ks = np.concatenate([k_lo, k_hi], axis=1)
        return np.minimum(ks.min(axis=1), 0.0) + np.maximum(ks.max(axis=1), 0.0)

    def _desaturate(self, act: NDArray[np.float64], vec: NDArray[np.float64], increase_only: bool = False,
                    upper: float = 1.0) -> NDArray[np.float64]:
        if act.min() >= 0.0 and act.max() <= upper:
            return act  # nothing saturated: every desaturation gain is exactly 0
        g = self._gain(vec, act, upper)
        # increase_only: a negative gain skips this axis (along the negative F_z column a positive gain
        # only lowers thrust, so "thrust is never raised to unsaturate a motor")
        apply = (g >= 0.0) if increase_only else np.ones_like(g, dtype=bool)
        out = act + g[:, None] * vec
        out = out + 0.5 * self._gain(vec, out, upper)[:, None] * vec
        return np.where(apply[:, None], out, act)

    def motor_commands(self, rotor_thrust_norm: ArrayLike) -> NDArray[np.float64]:
        """Rotor normalized thrusts (..., 4) -> env ``"motors"`` commands in [0, 1] (exact inverse rotor map)."""
        return thrust_to_command(self.preset, np.asarray(rotor_thrust_norm, dtype=float) * self.max_rotor_thrust)

    def wrench(self, rotor_thrust_norm: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Physical collective thrust (N,) [N] and torque (N, 3) [N m] of rotor normalized thrusts (N, 4)."""
        w = (np.asarray(rotor_thrust_norm, dtype=float) * self.max_rotor_thrust) @ allocation_matrix(self.preset).T
        return w[..., 0], w[..., 1:]
