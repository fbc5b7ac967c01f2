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
thrust curve (PX4's ``THR_MDL_FAC`` tuned to the rotor): the controller's own thrust curve,
:func:`rotor_command_row`, which ``tests/test_px4_allocation.py`` pins to the env's rotor map.

The mixing with desaturation is written once, as the row function :func:`allocate_row` compiled by numba,
which the PX4 cascade kernel (:mod:`fawtgym.agents.px4_cascade`) calls per vehicle and
:meth:`QuadXAllocation.allocate` through a batch kernel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.envs.motors import allocation_matrix
from fawtgym.envs.vehicles import VehiclePreset

from .shared_params import InPlaceArray

_FLT_EPS = 1.1920929e-07
ROLL, PITCH, YAW, THRUST_Z = 0, 1, 2, 3
#: the rotor-map vector layout (:attr:`QuadXAllocation.rotor_map`)
T_MAX, K_THRUST, OMEGA_MIN, OMEGA_MAX = 0, 1, 2, 3
_YAW_HEADROOM = 1.15  # mixYaw: yaw may use 15 % above full thrust before thrust is reduced


@njit(cache=True, inline="always")
def _desaturation_gain(mix_t: np.ndarray, axis: int, act: np.ndarray, upper: float) -> float:
    """computeDesaturationGain: k_min + k_max over the actuators outside [0, upper] along the mix column of ``axis``
    (row ``axis`` of ``mix_t``; indexed, not a row view: a view per call costs an atomic reference count)."""
    k_min, k_max = 0.0, 0.0
    for j in range(4):
        if abs(mix_t[axis, j]) < _FLT_EPS:
            continue
        if act[j] < 0.0:
            k = (0.0 - act[j]) / mix_t[axis, j]
            k_min, k_max = min(k_min, k), max(k_max, k)
        if act[j] > upper:
            k = (upper - act[j]) / mix_t[axis, j]
            k_min, k_max = min(k_min, k), max(k_max, k)
    return k_min + k_max


@njit(cache=True, inline="always")
def _desaturate(act: np.ndarray, mix_t: np.ndarray, axis: int, increase_only: bool, upper: float) -> None:
    """desaturateActuators in place along the mix column of ``axis``: ``act += k vec`` then ``+= 0.5 k' vec``;
    ``increase_only`` skips k < 0."""
    saturated = False
    for j in range(4):
        if act[j] < 0.0 or act[j] > upper:
            saturated = True
    if not saturated:
        return  # every desaturation gain is exactly 0
    gain = _desaturation_gain(mix_t, axis, act, upper)
    # increase_only: along the negative F_z column a positive gain only lowers thrust ("thrust is never raised
    # to unsaturate a motor"), so a negative gain leaves the actuators as they are
    if increase_only and gain < 0.0:
        return
    for j in range(4):
        act[j] += gain * mix_t[axis, j]
    gain = 0.5 * _desaturation_gain(mix_t, axis, act, upper)
    for j in range(4):
        act[j] += gain * mix_t[axis, j]


@njit(cache=True, inline="always")
def allocate_row(torque: np.ndarray, thrust: float, mix_t: np.ndarray, effectiveness: np.ndarray,
                 scale: np.ndarray, act: np.ndarray, unallocated: np.ndarray) -> None:
    """PX4 sequential desaturation (airmode off) for one vehicle: normalized torque (3,) and collective thrust
    -> rotor normalized thrusts ``act`` (4,) in [0, 1] and the unallocated control ``unallocated`` (4,) on
    [roll, pitch, yaw, F_z].  ``mix_t`` (4 axes, 4 rotors) is the transposed normalized mix (one row per axis)."""
    c_z = -thrust
    for j in range(4):  # mix roll, pitch and thrust
        act[j] = torque[ROLL] * mix_t[ROLL, j] + torque[PITCH] * mix_t[PITCH, j] + c_z * mix_t[THRUST_Z, j]
    _desaturate(act, mix_t, THRUST_Z, True, 1.0)
    _desaturate(act, mix_t, ROLL, False, 1.0)
    _desaturate(act, mix_t, PITCH, False, 1.0)
    for j in range(4):  # mixYaw: add yaw with head-room above full thrust, then reduce thrust only
        act[j] += torque[YAW] * mix_t[YAW, j]
    _desaturate(act, mix_t, YAW, False, _YAW_HEADROOM)
    _desaturate(act, mix_t, THRUST_Z, True, 1.0)
    for j in range(4):
        act[j] = min(max(act[j], 0.0), 1.0)
    for a in range(4):  # c_sp - c_achieved, c_achieved = scale * (B act)
        achieved = (effectiveness[a, 0] * act[0] + effectiveness[a, 1] * act[1] + effectiveness[a, 2] * act[2]
                    + effectiveness[a, 3] * act[3]) * scale[a]
        unallocated[a] = (torque[a] if a < 3 else c_z) - achieved


@njit(cache=True, inline="always")
def rotor_command_row(act: np.ndarray, rotor_map: np.ndarray, command: np.ndarray) -> None:
    """Rotor normalized thrusts (4,) -> motor commands (4,) in [0, 1] through the controller's thrust curve:
    ``T = T_max t``, ``omega = sqrt(T / k_T)``, ``u = (omega - omega_min) / (omega_max - omega_min)``."""
    for j in range(4):
        omega = math.sqrt(max(act[j] * rotor_map[T_MAX], 0.0) / rotor_map[K_THRUST])
        u = (omega - rotor_map[OMEGA_MIN]) / (rotor_map[OMEGA_MAX] - rotor_map[OMEGA_MIN])
        command[j] = min(max(u, 0.0), 1.0)


@njit(cache=True)
def _allocate_kernel(torque: np.ndarray, thrust: np.ndarray, mix_t: np.ndarray, effectiveness: np.ndarray,
                     scale: np.ndarray, act: np.ndarray, unallocated: np.ndarray) -> None:
    for i in range(torque.shape[0]):
        allocate_row(torque[i], thrust[i], mix_t, effectiveness, scale, act[i], unallocated[i])


@njit(cache=True)
def _command_kernel(act: np.ndarray, rotor_map: np.ndarray, command: np.ndarray) -> None:
    for i in range(act.shape[0]):
        rotor_command_row(act[i], rotor_map, command[i])


class QuadXAllocation:
    """Normalized torque (N, 3) + collective thrust (N,) -> rotor thrusts in [0, 1] (N, 4) and motor commands."""
    mix_t = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place
    effectiveness = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place
    scale = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place
    rotor_map = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place

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
        #: the mix transposed, one row per axis (roll, pitch, yaw, F_z), for :func:`allocate_row`
        self.mix_t = np.ascontiguousarray(mix_n.T)
        #: N m per unit normalized torque, per axis (roll, pitch, yaw)
        self.torque_scale = 1.0 / self.scale[:3]
        #: N per unit normalized collective thrust
        self.thrust_scale = float(1.0 / self.scale[3])
        #: the controller's thrust curve (T_max, k_T, omega_min, omega_max) for :func:`rotor_command_row`
        self.rotor_map = np.array([self.max_rotor_thrust, preset.k_thrust, preset.omega_min, preset.omega_max])

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
        tau = np.ascontiguousarray(np.atleast_2d(np.asarray(torque_norm, dtype=float)))
        thr = np.ascontiguousarray(np.atleast_1d(np.asarray(thrust_norm, dtype=float)).reshape(-1))
        act, unallocated = np.empty((tau.shape[0], 4)), np.empty((tau.shape[0], 4))
        _allocate_kernel(tau, thr, self.mix_t, self.effectiveness, self.scale, act, unallocated)
        return act, unallocated

    def motor_commands(self, rotor_thrust_norm: ArrayLike) -> NDArray[np.float64]:
        """Rotor normalized thrusts (..., 4) -> env ``"motors"`` commands in [0, 1] (:func:`rotor_command_row`)."""
        a = np.asarray(rotor_thrust_norm, dtype=float)
        act = np.ascontiguousarray(a.reshape(-1, 4))
        out = np.empty_like(act)
        _command_kernel(act, self.rotor_map, out)
        return out.reshape(a.shape)

    def wrench(self, rotor_thrust_norm: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Physical collective thrust (N,) [N] and torque (N, 3) [N m] of rotor normalized thrusts (N, 4)."""
        w = (np.asarray(rotor_thrust_norm, dtype=float) * self.max_rotor_thrust) @ allocation_matrix(self.preset).T
        return w[..., 0], w[..., 1:]
