"""Rotor model: command mapping, exact first-order speed lag, thrust/torque and the quad X mixer.

The normalized motor command ``u`` in [0, 1] (like a PX4 actuator output) sets the rotor speed
reference linearly, as an ESC in speed mode and PX4's Gazebo motor model do::

    omega_ref = omega_min + u (omega_max - omega_min)

The rotor speed follows ``d omega/dt = (omega_ref - omega) / tau`` with ``tau = tau_up`` while
``omega < omega_ref`` and ``tau_down`` otherwise.  With ``omega_ref`` held over a control period
the speed approaches the reference monotonically, so the time constant cannot switch inside the
period and the exact solution ``omega(t) = omega_ref + (omega_0 - omega_ref) exp(-t / tau)`` is used
(no integration error, any step size).  Thrust ``T = k_T omega^2`` along body -z (FRD) and reaction
torque ``d_i k_M T`` about body z.

The lag over a step of K physics substeps is one compiled kernel over rows (:func:`lag_thrusts`): the thrust of
substep k is ``k_T omega(t_k)^2`` at its midpoint ``t_k``, the speed carried on is ``omega`` at the step's end.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from .vehicles import VehiclePreset


def command_to_omega(preset: VehiclePreset, u: ArrayLike) -> NDArray[np.float64]:
    """Normalized command (..., 4) in [0, 1] to rotor speed reference [rad/s]."""
    return preset.omega_min + np.asarray(u, dtype=float) * (preset.omega_max - preset.omega_min)


def omega_to_command(preset: VehiclePreset, omega: ArrayLike) -> NDArray[np.float64]:
    """Inverse of :func:`command_to_omega` (not clipped)."""
    return (np.asarray(omega, dtype=float) - preset.omega_min) / (preset.omega_max - preset.omega_min)


def thrust_to_command(preset: VehiclePreset, thrust: ArrayLike) -> NDArray[np.float64]:
    """Steady-state command that makes each rotor produce ``thrust`` [N] (clipped to [0, 1])."""
    omega = np.sqrt(np.maximum(np.asarray(thrust, dtype=float), 0.0) / preset.k_thrust)
    return np.clip(omega_to_command(preset, omega), 0.0, 1.0)


def command_to_thrust(preset: VehiclePreset, u: ArrayLike) -> NDArray[np.float64]:
    """Steady-state rotor thrust [N] for a normalized command."""
    return preset.k_thrust * command_to_omega(preset, u) ** 2


def hover_command(preset: VehiclePreset) -> float:
    """The command that holds the vehicle's weight with four equal rotors."""
    return float(omega_to_command(preset, preset.hover_omega))


def decay_factors(preset: VehiclePreset, times: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(exp(-t / tau_up), exp(-t / tau_down))`` at ``times`` (K,): the factors of :func:`lag_thrusts`."""
    t = np.ascontiguousarray(times, dtype=float)
    return np.exp(-t / preset.tau_up), np.exp(-t / preset.tau_down)


def substep_times(step_dt: float, substeps: int) -> NDArray[np.float64]:
    """The K substep midpoints and the step's end [s]: ``(k + 1/2) step_dt / K`` for k < K, then ``step_dt``."""
    return np.append((np.arange(substeps) + 0.5) * (step_dt / substeps), step_dt)


@njit(cache=True)
def lag_thrusts(omega_ref: NDArray[np.float64], omega0: NDArray[np.float64], decay_up: NDArray[np.float64],
                decay_down: NDArray[np.float64], k_thrust: float, thrust_out: NDArray[np.float64],
                speeds_out: NDArray[np.float64], mean_thrust: NDArray[np.float64]) -> None:
    """Exact lag of every row's rotors (N, R) from ``omega0`` toward the held ``omega_ref`` over K substeps.

    ``decay_*`` (K + 1,) are ``exp(-t / tau)`` at the substep midpoints and the step's end (:func:`substep_times`):
    ``thrust_out[i, k, j] = k_T omega_ij(t_k)^2`` (columns 0..R-1 of a wider array are written), ``mean_thrust`` their
    mean over the K substeps, ``speeds_out`` the speeds at the end.
    """
    n_sub = decay_up.shape[0] - 1
    for i in range(omega_ref.shape[0]):
        for j in range(omega_ref.shape[1]):
            ref, w0 = omega_ref[i, j], omega0[i, j]
            decay = decay_up if ref > w0 else decay_down  # monotone approach: one time constant per step
            gap = w0 - ref
            total = 0.0
            for k in range(n_sub):
                w = ref + gap * decay[k]  # omega(t_k) = omega_ref + (omega_0 - omega_ref) exp(-t_k / tau)
                thrust = k_thrust * (w * w)
                thrust_out[i, k, j] = thrust
                total += thrust
            mean_thrust[i, j] = total / n_sub
            speeds_out[i, j] = ref + gap * decay[n_sub]


def lag_speeds(preset: VehiclePreset, omega0: ArrayLike, omega_ref: ArrayLike, times: ArrayLike) -> NDArray[np.float64]:
    """Exact rotor speeds at ``times`` (K,) after ``omega0`` with a held reference; returns (K, ..., 4).

    The closed form :func:`lag_thrusts` evaluates, written out with numpy (a reference for tests and plots).
    """
    omega0 = np.asarray(omega0, dtype=float)
    omega_ref = np.asarray(omega_ref, dtype=float)
    tau = np.where(omega_ref > omega0, preset.tau_up, preset.tau_down)
    t = np.asarray(times, dtype=float).reshape((-1,) + (1,) * omega0.ndim)
    return omega_ref + (omega0 - omega_ref) * np.exp(-t / tau)


def allocation_matrix(preset: VehiclePreset) -> NDArray[np.float64]:
    """Effectiveness B (4x4): [f, tau_x, tau_y, tau_z] = B @ rotor thrusts (f along -z body FRD).

    Rotor i at r_i = (x_i, y_i, 0) pushing -T_i e3 gives tau = r_i x (-T_i e3) = T_i (-y_i, x_i, 0),
    plus the reaction torque d_i k_M T_i about z.
    """
    r = preset.rotor_positions
    return np.vstack([np.ones(4), -r[:, 1], r[:, 0], preset.rotor_directions * preset.k_moment])


def rotor_wrench(preset: VehiclePreset, thrusts: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Collective thrust f (...,) [N] and body torque (..., 3) [N m] from rotor thrusts (..., 4)."""
    w = np.asarray(thrusts, dtype=float) @ allocation_matrix(preset).T
    return w[..., 0], w[..., 1:]


def mix(preset: VehiclePreset, thrust: ArrayLike, torque: ArrayLike) -> NDArray[np.float64]:
    """Rotor thrusts (..., 4) realizing collective thrust f and body torque exactly (unsaturated)."""
    wrench = np.concatenate([np.asarray(thrust, dtype=float)[..., None], np.asarray(torque, dtype=float)], axis=-1)
    return wrench @ np.linalg.inv(allocation_matrix(preset)).T
