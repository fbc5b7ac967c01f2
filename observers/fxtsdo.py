"""Fixed-time disturbance observer (FxTSDO), the Wang et al. (2024) baseline of Liu et al. 2022.

Source of the comparison: Remark 2 and Sec. 6 (ref. [22], Liu et
al. 2022, Theorems 1-2).  As Remark 2 describes, the observer is driven by the velocities X_2 = v,
Y_2 = Omega and their derivatives, which -- with no accelerometer model and no angular-acceleration
sensor -- are obtained by finite differencing the measured velocities: a_fd = (v^m_k - v^m_{k-1}) / dt.
The residual of the model eq. (38) then "measures" the disturbance, and a fixed-time update with the
standard two-power form (Polyakov 2012, "Nonlinear feedback design for fixed-time stabilization";
Basin et al. fixed-time observers)::

    eps_t = a_fd - (g e3 - (f/m) R^m e3) - d_t_hat,              d_t_hat' = k1 sig^a1(eps_t) + k2 sig^a2(eps_t)
    eps_a = W'_fd - J^-1 (J W^m x W^m + tau) - d_a_hat,          d_a_hat' = k1 sig^a1(eps_a) + k2 sig^a2(eps_a)
    phi_hat = m d_t_hat,  tau_hat = J d_a_hat

(per component, sig^a(x) = |x|^a sign(x), 0 < a1 < 1 < a2).  Liu et al.'s numerical gains are not in
the seed paper; defaults a1 = 0.5, a2 = 1.5, k1 = k2 = 5 per channel, so that the update rate at
|eps| = 1 is k1 + k2 = 10 1/s, the same bandwidth as the LESO defaults.  Explicit Euler at the update
rate dt.  The first update after reset has no previous sample and uses the reset measurement.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import check_number
from fawtgym.core.constants import GRAVITY
from fawtgym.core.rows import write_rows
from fawtgym.observers._obs_common import (
    MAX_RATE_GAIN,
    batch_vec,
    known_acceleration_row,
    known_angular_acceleration_row,
    positive,
    sig_row,
)
from fawtgym.observers.base import DIVIDING_MIN_DT, Observer, ObserverEstimate, register_observer

#: columns of the state (N, 12): previous v^m, previous Omega^m, d_t_hat [m/s^2], d_a_hat [rad/s^2]
V_PREV, W_PREV, D_T, D_A = 0, 3, 6, 9
_KEYS = ("velocity", "attitude", "angular_velocity")
#: the largest disturbance-acceleration error [m/s^2 or rad/s^2] the Euler step must keep stable (10 g)
LARGE_ERROR = 10.0 * GRAVITY
#: the largest exponent a2 accepted: max_dt = 2 / (k2 a2 LARGE_ERROR^(a2 - 1)) is 1.2 us at a2 = 3.5 and k2 = 5,
#: 6e-12 s at k2 = MAX_RATE_GAIN (at a2 = 1e300 it overflows); fixed-time designs use a2 in (1, 2]
MAX_A2 = 3.5


@register_observer("fxtsdo")
class FxTSDO(Observer):
    """Fixed-time DO on finite-differenced velocities (Liu et al. 2022, as in Wang et al. 2024, Sec. 6).

    ``max_dt`` = 2 / (k2 a2 E^(a2 - 1)) with E = :data:`LARGE_ERROR` (10 g): explicit Euler of
    d' = k1 sig^a1(e) + k2 sig^a2(e), e = r - d, diverges once the law's slope times dt exceeds 2, and the
    a2 > 1 term's slope grows with |e|; the bound keeps errors up to 10 g inside the stable region
    (27 ms at the defaults).  ``min_dt`` = 1 ns (:data:`~fawtgym.observers.base.DIVIDING_MIN_DT`, or max_dt if
    smaller): the finite-differenced velocities divide by dt, and a velocity step dv moves the estimate by
    k2 dv^a2 dt^(1 - a2) (dt^-1/2 at the defaults; 1 cm/s at dt = 1 ns: 190 N on 1.2 kg).
    """

    required_keys = _KEYS
    min_dt_reason = "the finite difference of the velocities divides by dt"

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = GRAVITY, *, k1: float = 5.0,
                 k2: float = 5.0, a1: float = 0.5, a2: float = 1.5) -> None:
        super().__init__(mass, inertia, gravity)
        self.k1, self.k2 = positive("fxtsdo", MAX_RATE_GAIN, k1=k1, k2=k2)
        # fixed time needs 0 < a1 < 1 < a2; a2 is bounded so that max_dt (below) stays a representable step
        self.a1 = check_number(a1, "fxtsdo: exponent a1", minimum=0.0, maximum=1.0,
                               inclusive_maximum=False)
        self.a2 = check_number(a2, "fxtsdo: exponent a2", minimum=1.0, maximum=MAX_A2)
        self._state: NDArray[np.float64] = np.empty((0, 0))      # (N, k) after reset
        self._gains = np.array([self.mass, self.gravity, self.k1, self.k2, self.a1, self.a2,
                                *self.inertia.ravel(), *self.inertia_inv.ravel()])
        # explicit Euler of d' = law(r - d) is stable while law's slope times dt < 2; the a2 > 1 term's slope
        # k2 a2 |e|^(a2-1) grows without bound, so dt is bounded to keep errors up to LARGE_ERROR stable
        self.max_dt = 2.0 / (self.k2 * self.a2 * LARGE_ERROR ** (self.a2 - 1.0))
        # the finite difference (v_k - v_{k-1}) / dt feeds k2 sig^a2: a velocity step dv moves d_hat by
        # k2 dv^a2 dt^(1 - a2), which grows without bound as dt -> 0 (a subnormal dt gives inf); gains whose max_dt is
        # below the floor (a2 near MAX_A2 with k2 near MAX_RATE_GAIN) keep max_dt as their only step
        self.min_dt = min(DIVIDING_MIN_DT, self.max_dt)

    def _reset(self, measurement: Mapping[str, NDArray[np.float64]], force: ArrayLike | None,
               torque: ArrayLike | None, rows: NDArray[np.bool_] | None) -> int:
        """Previous velocities := measured; d_hat := the given guesses (as accelerations).  State: ``_state``
        (N, 12), columns v_prev, w_prev, d_t_hat, d_a_hat."""
        m = measurement        # checked by Observer.reset (required_keys)
        n = m["velocity"].shape[0]
        fresh = np.concatenate([m["velocity"], m["angular_velocity"],
                                batch_vec(force, n, "force", "fxtsdo") / self.mass,
                                batch_vec(torque, n, "torque", "fxtsdo") @ self.inertia_inv.T], axis=1)
        self._state = write_rows(self._state, fresh, rows)
        return n

    def _update(self, m: dict[str, NDArray[np.float64]], f: NDArray[np.float64], tau: NDArray[np.float64],
                dt: float) -> tuple[ObserverEstimate, NDArray[np.float64]]:
        x = self._state
        x_new = np.empty(x.shape)
        est = np.empty((x.shape[0], 6))
        fxtsdo_step(x, m["velocity"], m["attitude"], m["angular_velocity"], f, tau, dt, self._gains, x_new, est)
        return ObserverEstimate(force=est[:, 0:3], torque=est[:, 3:6], states={}), x_new

    def estimate(self) -> ObserverEstimate:
        if self._n_rows is None:
            raise RuntimeError("fxtsdo: estimate() before reset(); call reset(measurement) first")
        est = np.empty((self._state.shape[0], 6))
        fxtsdo_estimate(self._state, self._gains, self.inertia, est)
        return ObserverEstimate(force=est[:, 0:3], torque=est[:, 3:6], states={})


@njit(cache=True)
def _estimate_row(x: NDArray[np.float64], mass: float, inertia: NDArray[np.float64], est: NDArray[np.float64]) -> None:
    """phi_hat = m d_t_hat, tau_hat = J d_a_hat."""
    for j in range(3):
        est[j] = mass * x[D_T + j]
        est[3 + j] = inertia[j, 0] * x[D_A] + inertia[j, 1] * x[D_A + 1] + inertia[j, 2] * x[D_A + 2]


@njit(cache=True)
def fxtsdo_estimate(x: NDArray[np.float64], gains: NDArray[np.float64], inertia: NDArray[np.float64],
                    est: NDArray[np.float64]) -> None:
    """:func:`_estimate_row` of every row of the state ``x`` (N, 12) into ``est`` (N, 6)."""
    for i in range(x.shape[0]):
        _estimate_row(x[i], gains[0], inertia, est[i])


@njit(cache=True)
def fixed_time_law(e: float, k1: float, k2: float, a1: float, a2: float) -> float:
    """k1 sig^a1(e) + k2 sig^a2(e), 0 < a1 < 1 < a2 (Polyakov 2012 fixed-time form)."""
    return k1 * sig_row(e, a1) + k2 * sig_row(e, a2)


@njit(cache=True)
def fxtsdo_step(x: NDArray[np.float64], vel: NDArray[np.float64], att: NDArray[np.float64],
                omega: NDArray[np.float64], thrust: NDArray[np.float64], torque: NDArray[np.float64], dt: float,
                gains: NDArray[np.float64], x_new: NDArray[np.float64], est: NDArray[np.float64]) -> None:
    """One FxTSDO step of every row: state ``x`` (N, 12) -> ``x_new``, estimate into ``est`` (N, 6).

    eps = (velocity difference) / dt - known acceleration - d_hat; d_hat += dt (k1 sig^a1(eps) + k2 sig^a2(eps)),
    on the translational and the rotational channel (module docstring).  ``gains``: (m, g, k1, k2, a1, a2, J (9),
    J^-1 (9)).
    """
    mass, g, k1, k2, a1, a2 = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5]
    inertia = gains[6:15].reshape((3, 3))
    inertia_inv = gains[15:24].reshape((3, 3))
    acc_known, ang_known = np.empty(3), np.empty(3)
    for i in range(x.shape[0]):
        xi, xo = x[i], x_new[i]
        known_acceleration_row(att[i], thrust[i], mass, g, acc_known)
        known_angular_acceleration_row(omega[i], torque[i], inertia, inertia_inv, ang_known)
        for j in range(3):
            eps_t = (vel[i, j] - xi[V_PREV + j]) / dt - acc_known[j] - xi[D_T + j]
            eps_a = (omega[i, j] - xi[W_PREV + j]) / dt - ang_known[j] - xi[D_A + j]
            xo[V_PREV + j] = vel[i, j]
            xo[W_PREV + j] = omega[i, j]
            xo[D_T + j] = xi[D_T + j] + dt * fixed_time_law(eps_t, k1, k2, a1, a2)
            xo[D_A + j] = xi[D_A + j] + dt * fixed_time_law(eps_a, k1, k2, a1, a2)
        _estimate_row(xo, mass, inertia, est[i])
