"""PX4's multicopter rate controller (``rate_control`` RateControl, used by mc_rate_control), batch-first.

The law (re-derived): with rate error ``e = omega_sp - omega``,

    tau = K_P e + i - K_D omega_dot + K_FF omega_sp        (normalized torque, about [-1, 1])

where ``K_P = K * MC_*RATE_P``, ``K_I = K * MC_*RATE_I``, ``K_D = K * MC_*RATE_D`` (the "K" gain
``MC_*RATE_K`` scales the parallel gains) and the D term acts on the measured, low-passed angular
acceleration (no derivative kick).  The integrator:

* is frozen per axis in the direction in which the control allocation reports saturation;
* uses PX4's i-factor ``max(0, 1 - (e / 400 deg/s)^2)`` that reduces integration on large errors;
* is clamped to ``+-MC_*_INT_LIM``.

Observer feedforward (Wang et al. (2024) Sec. 7.2, tau = tau0 - tau_hat) is
applied by the agent after this law, in normalized units (see :mod:`fawtgym.agents.px4_allocation`).

The law is written once, as the row function :func:`rate_control_row` compiled by numba, which the PX4
cascade kernel (:mod:`fawtgym.agents.px4_cascade`) calls per vehicle and :class:`RateControl` through a
batch kernel.  A vehicle's state is one row of :attr:`RateControl.state`: integrator and saturation flags.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.rows import check_dt

from .px4_params import PX4Params
from .shared_params import InPlaceArray

_EPS = 1.1920929e-07
_I_FACTOR_RATE = math.radians(400.0)  # rad/s: PX4's i-factor error scale
#: parameter vector layout (:attr:`RateControl.params`), (3,) each
KP, KI, KD, KFF, INT_LIM = 0, 3, 6, 9, 12
N_PARAMS = 15
#: state row layout (:attr:`RateControl.state`): integrator, positive / negative saturation flags (0 or 1)
RATE_INT, SAT_POS, SAT_NEG = 0, 3, 6
N_STATE = 9


@njit(cache=True, inline="always")
def rate_control_row(rate: np.ndarray, rate_sp: np.ndarray, acc: np.ndarray, dt: float, prm: np.ndarray,
                     s: np.ndarray, advance: bool, torque: np.ndarray) -> None:
    """One vehicle's normalized torque ``torque`` (3,) = K_P e + i - K_D omega_dot + K_FF omega_sp, e = sp - rate.

    If ``advance``, the integrator (state row ``s``) integrates ``i_factor K_I e dt`` with the error frozen in a
    saturated direction, ``i_factor = max(0, 1 - (e / 400 deg/s)^2)``, clamped to ``+-INT_LIM``; a non-finite
    result leaves it unchanged.
    """
    for j in range(3):
        err = rate_sp[j] - rate[j]
        torque[j] = prm[KP + j] * err + s[RATE_INT + j] - prm[KD + j] * acc[j] + prm[KFF + j] * rate_sp[j]
        if not advance:
            continue
        e = min(err, 0.0) if s[SAT_POS + j] != 0.0 else err
        e = max(e, 0.0) if s[SAT_NEG + j] != 0.0 else e
        i_factor = e / _I_FACTOR_RATE
        i_factor = max(0.0, 1.0 - i_factor * i_factor)
        rate_i = s[RATE_INT + j] + i_factor * prm[KI + j] * e * dt
        if math.isfinite(rate_i):
            s[RATE_INT + j] = min(max(rate_i, -prm[INT_LIM + j]), prm[INT_LIM + j])


@njit(cache=True)
def _rate_kernel(rate: np.ndarray, rate_sp: np.ndarray, acc: np.ndarray, dt: np.ndarray, prm: np.ndarray,
                 state: np.ndarray, advance: np.ndarray, torque: np.ndarray) -> None:
    for i in range(rate.shape[0]):
        rate_control_row(rate[i], rate_sp[i], acc[i], dt[i], prm, state[i], advance[i], torque[i])


def _rows3(x: ArrayLike, n: int) -> NDArray[np.float64]:
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=float), (n, 3)))


class RateControl:
    """PX4 RateControl for N vehicles; ``rate_int`` (N, 3), ``sat_pos`` / ``sat_neg`` (N, 3) bool are its state."""
    params = InPlaceArray()  # the cascade reads it from a packed vector: assignment writes in place

    def __init__(self, params: PX4Params | None = None) -> None:
        p = params if params is not None else PX4Params.s500()
        k = np.array([p["MC_ROLLRATE_K"], p["MC_PITCHRATE_K"], p["MC_YAWRATE_K"]])
        self.gain_p = k * np.array([p["MC_ROLLRATE_P"], p["MC_PITCHRATE_P"], p["MC_YAWRATE_P"]])
        self.gain_i = k * np.array([p["MC_ROLLRATE_I"], p["MC_PITCHRATE_I"], p["MC_YAWRATE_I"]])
        self.gain_d = k * np.array([p["MC_ROLLRATE_D"], p["MC_PITCHRATE_D"], p["MC_YAWRATE_D"]])
        self.gain_ff = np.array([p["MC_ROLLRATE_FF"], p["MC_PITCHRATE_FF"], p["MC_YAWRATE_FF"]])
        self.lim_int = np.array([p["MC_RR_INT_LIM"], p["MC_PR_INT_LIM"], p["MC_YR_INT_LIM"]])
        self.params = np.concatenate([self.gain_p, self.gain_i, self.gain_d, self.gain_ff, self.lim_int])
        self.state: NDArray[np.float64] = np.zeros((0, N_STATE))
        self.reset(1)

    rate_int = property(lambda self: self.state[:, RATE_INT:RATE_INT + 3], doc="rate integrator (N, 3)")
    sat_pos = property(lambda self: self.state[:, SAT_POS:SAT_POS + 3] != 0.0, doc="positive saturation (N, 3)")
    sat_neg = property(lambda self: self.state[:, SAT_NEG:SAT_NEG + 3] != 0.0, doc="negative saturation (N, 3)")

    def reset(self, n: int = 1, rows: NDArray[np.bool_] | None = None) -> None:
        """Zero integrators and saturation flags for ``n`` vehicles (only the rows of ``rows`` (n,) if given)."""
        if rows is not None and self.state.shape[0] == n:
            self.state[rows] = 0.0
            return
        self.state = np.zeros((n, N_STATE))

    def set_saturation(self, positive: ArrayLike, negative: ArrayLike) -> None:
        """Saturation flags (N, 3) from the control allocation (``unallocated torque > 0`` / ``< 0``)."""
        self.state[:, SAT_POS:SAT_POS + 3] = np.asarray(positive, dtype=bool)
        self.state[:, SAT_NEG:SAT_NEG + 3] = np.asarray(negative, dtype=bool)

    def update(self, rate: ArrayLike, rate_sp: ArrayLike, angular_accel: ArrayLike, dt: float | ArrayLike,
               landed: bool = False, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Normalized torque (N, 3) from rates (N, 3) [rad/s] and angular acceleration (N, 3) [rad/s^2].

        ``dt`` [s] scalar or per row (N,); ``rows`` (N,): only these rows advance the integrator.
        """
        dt = check_dt(dt)
        rate = np.atleast_2d(np.asarray(rate, dtype=float))
        n = rate.shape[0]
        if self.state.shape[0] != n:
            self.reset(n)
        advance = np.full(n, not landed) if rows is None else np.asarray(rows, dtype=bool) & (not landed)
        torque = np.empty((n, 3))
        _rate_kernel(_rows3(rate, n), _rows3(rate_sp, n), _rows3(angular_accel, n),
                     np.ascontiguousarray(np.broadcast_to(dt, (n,)), dtype=float), self.params, self.state, advance,
                     torque)
        return torque
