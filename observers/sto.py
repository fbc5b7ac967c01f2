"""Classic super-twisting observer (Davila, Fridman, Levant, IEEE TAC 50(11) 2005), a Wang et al. (2024)-style baseline.

Davila-Fridman-Levant (DFL) observe x1' = x2, x2' = F(t, x) + xi with the super-twisting injection::

    x1_hat' = x2_hat + lambda |x1 - x1_hat|^(1/2) sign(x1 - x1_hat),   x2_hat' = F + alpha sign(x1 - x1_hat)

and recover the unknown input from the equivalent output injection.  Here the measured output is the
velocity of each channel of Wang et al. (2024) eq. (38)::

    v' = g e3 - (f/m) R e3 + d_t,          Omega' = J^-1 (J Omega x Omega + tau) + d_a

so in DFL's notation x1 := velocity and x2 := the (unknown) disturbance acceleration d, whose derivative
is the bounded unknown; the super-twisting integral state *is* the continuous disturbance estimate
(no low-pass filter of a discontinuous injection is needed)::

    s = v^m - v_hat,   v_hat' = a_known + lambda_t sig^(1/2)(s) + d_t_hat,   d_t_hat' = alpha_t sign(s)

(and the same on Omega), phi_hat = m d_t_hat, tau_hat = J d_a_hat.

Gains: Levant's rule (Levant 1998, "Robust exact differentiation via sliding mode technique",
Automatica 34) lambda = 1.5 sqrt(L), alpha = 1.1 L with L a bound on |d'|.  Defaults L_t = 5 m/s^3,
L_a = 5 rad/s^3: more than 5x the largest rate of change of the smooth parts of the Wang et al. (2024) Sec. 6
disturbances (|phi_D'|/m <= 0.19 m/s^3, |J^-1 tau_D'| <= 0.96 rad/s^3 per axis); steps are outside any
such bound by nature.  Explicit Euler at the update rate dt.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.constants import GRAVITY
from fawtgym.core.rows import write_rows
from fawtgym.observers._obs_common import (
    batch_vec,
    known_acceleration_row,
    known_angular_acceleration_row,
    positive,
    sig_row,
)
from fawtgym.observers.base import BufferStates, Observer, ObserverEstimate, register_observer

#: columns of the state (N, 12): v_hat, Omega_hat, d_t_hat [m/s^2], d_a_hat [rad/s^2]
V, W, D_T, D_A = 0, 3, 6, 9
_KEYS = ("velocity", "attitude", "angular_velocity")
#: the largest Lipschitz bound L of the disturbance [m/s^3 or rad/s^3] accepted: the estimate moves by 1.1 L dt per
#: step, 1e3 m/s^2 per millisecond step at this bound (far beyond any quadrotor's disturbance)
MAX_DISTURBANCE_RATE = 1e6


def levant_gains(bound: float) -> tuple[float, float]:
    """(lambda, alpha) = (1.5 sqrt(L), 1.1 L), Levant 1998."""
    return 1.5 * math.sqrt(bound), 1.1 * bound


@register_observer("sto")
class SuperTwistingObserver(Observer):
    """DFL super-twisting observer on the velocity and angular-velocity channels.

    ``max_dt`` = 0.05 s.  The sublinear injection has no Euler stability limit, but the discrete super-twisting
    settles in a band that grows with the step: the disturbance estimate moves by alpha dt = 1.1 L dt per step
    (Levant 1998 accuracy O(L dt) of the first derivative), 0.28 m/s^2 at the default L = 5 and dt = 50 ms;
    beyond that the estimate is mostly chatter.
    """

    required_keys = _KEYS
    max_dt = 0.05

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = GRAVITY, *, bound_t: float = 5.0,
                 bound_a: float = 5.0) -> None:
        super().__init__(mass, inertia, gravity)
        bound_t, bound_a = positive("sto", MAX_DISTURBANCE_RATE, bound_t=bound_t, bound_a=bound_a)
        self.lam_t, self.alpha_t = levant_gains(bound_t)
        self.lam_a, self.alpha_a = levant_gains(bound_a)
        self._state: NDArray[np.float64] = np.empty((0, 0))      # (N, k) after reset
        self._gains = np.array([self.mass, self.gravity, self.lam_t, self.alpha_t, self.lam_a, self.alpha_a,
                                *self.inertia.ravel(), *self.inertia_inv.ravel()])

    def _reset(self, measurement: Mapping[str, NDArray[np.float64]], force: ArrayLike | None,
               torque: ArrayLike | None, rows: NDArray[np.bool_] | None) -> int:
        """v_hat, Omega_hat := measured; d_hat := the given guesses (as accelerations).  State: ``_state`` (N, 12),
        columns v_hat, Omega_hat, d_t_hat, d_a_hat."""
        m = measurement        # checked by Observer.reset (required_keys)
        n = m["velocity"].shape[0]
        fresh = np.concatenate([m["velocity"], m["angular_velocity"], batch_vec(force, n, "force", "sto") / self.mass,
                                batch_vec(torque, n, "torque", "sto") @ self.inertia_inv.T], axis=1)
        self._state = write_rows(self._state, fresh, rows)
        return n

    def _update(self, m: dict[str, NDArray[np.float64]], f: NDArray[np.float64], tau: NDArray[np.float64],
                dt: float) -> tuple[ObserverEstimate, NDArray[np.float64]]:
        x = self._state
        x_new = np.empty(x.shape)
        est = np.empty(x.shape)
        sto_step(x, m["velocity"], m["attitude"], m["angular_velocity"], f, tau, dt, self._gains, x_new, est)
        return _estimate(est), x_new

    def estimate(self) -> ObserverEstimate:
        if self._n_rows is None:
            raise RuntimeError("sto: estimate() before reset(); call reset(measurement) first")
        est = np.empty_like(self._state)
        sto_estimate(self._state, self._gains, self.inertia, est)
        return _estimate(est)


def _estimate(est: NDArray[np.float64]) -> ObserverEstimate:
    """The estimate from the kernel's buffer (N, 12): force, torque, velocity, angular_velocity."""
    return ObserverEstimate(force=est[:, 0:3], torque=est[:, 3:6], states=BufferStates(est, _STATES))


#: the estimate's states: columns of the estimate buffer and trailing shapes
_STATES = {"velocity": (6, 9, (3,)), "angular_velocity": (9, 12, (3,))}


@njit(cache=True)
def _estimate_row(x: NDArray[np.float64], mass: float, inertia: NDArray[np.float64], est: NDArray[np.float64]) -> None:
    """phi_hat = m d_t_hat, tau_hat = J d_a_hat, v_hat, Omega_hat."""
    for j in range(3):
        est[j] = mass * x[D_T + j]
        est[3 + j] = inertia[j, 0] * x[D_A] + inertia[j, 1] * x[D_A + 1] + inertia[j, 2] * x[D_A + 2]
        est[6 + j] = x[V + j]
        est[9 + j] = x[W + j]


@njit(cache=True)
def sto_estimate(x: NDArray[np.float64], gains: NDArray[np.float64], inertia: NDArray[np.float64],
                 est: NDArray[np.float64]) -> None:
    """:func:`_estimate_row` of every row of the state ``x`` (N, 12) into ``est`` (N, 12)."""
    for i in range(x.shape[0]):
        _estimate_row(x[i], gains[0], inertia, est[i])


@njit(cache=True)
def super_twisting_axis(x_hat: float, d_hat: float, y: float, known: float, lam: float, alpha: float,
                        dt: float) -> tuple[float, float]:
    """One explicit Euler step of the DFL super-twisting observer on one axis (both channels use it)::

        s = y - x_hat,   x_hat' = known + lam sig^(1/2)(s) + d_hat,   d_hat' = alpha sign(s)
    """
    s = y - x_hat
    sign = 1.0 if s > 0.0 else (-1.0 if s < 0.0 else 0.0)
    return x_hat + dt * (known + lam * sig_row(s, 0.5) + d_hat), d_hat + dt * alpha * sign


@njit(cache=True)
def sto_step(x: NDArray[np.float64], vel: NDArray[np.float64], att: NDArray[np.float64],
             omega: NDArray[np.float64], thrust: NDArray[np.float64], torque: NDArray[np.float64], dt: float,
             gains: NDArray[np.float64], x_new: NDArray[np.float64], est: NDArray[np.float64]) -> None:
    """One STO step of every row: state ``x`` (N, 12) -> ``x_new``, estimate into ``est`` (N, 12).

    Velocity channel: y = v^m, known = g e3 - (f/m) R^m e3; angular channel: y = Omega^m,
    known = J^-1 (J Omega^m x Omega^m + tau).  ``gains``: (m, g, lambda_t, alpha_t, lambda_a, alpha_a, J (9),
    J^-1 (9)).
    """
    mass, g, lam_t, alpha_t, lam_a, alpha_a = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5]
    inertia = gains[6:15].reshape((3, 3))
    inertia_inv = gains[15:24].reshape((3, 3))
    acc_known, ang_known = np.empty(3), np.empty(3)
    for i in range(x.shape[0]):
        xi, xo = x[i], x_new[i]
        known_acceleration_row(att[i], thrust[i], mass, g, acc_known)
        known_angular_acceleration_row(omega[i], torque[i], inertia, inertia_inv, ang_known)
        for j in range(3):
            xo[V + j], xo[D_T + j] = super_twisting_axis(xi[V + j], xi[D_T + j], vel[i, j], acc_known[j], lam_t,
                                                         alpha_t, dt)
            xo[W + j], xo[D_A + j] = super_twisting_axis(xi[W + j], xi[D_A + j], omega[i, j], ang_known[j], lam_a,
                                                         alpha_a, dt)
        _estimate_row(xo, mass, inertia, est[i])
