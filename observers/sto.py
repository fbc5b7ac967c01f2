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

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.rows import write_rows
from fawtgym.observers._obs_common import (
    batch_vec,
    check_finite,
    cross,
    positive,
    require,
    sig,
    single_inputs,
    single_state,
    step_inputs,
    store_single_state,
)
from fawtgym.observers.base import Observer, ObserverEstimate, register_observer

_E3 = np.array([0.0, 0.0, 1.0])
_KEYS = ("velocity", "attitude", "angular_velocity")
_STATE = ("v", "w", "dt_", "da")  # the state dict's entries, (N, 3) each, in the N = 1 path's float order


def _sig_half(x: float) -> float:
    """sig^(1/2)(x) = |x|^(1/2) sign(x) for one float (0 at 0), as :func:`~fawtgym.observers._obs_common.sig`."""
    return abs(x) ** 0.5 if x > 0 else (-(abs(x) ** 0.5) if x < 0 else 0.0)


def levant_gains(bound: float) -> tuple[float, float]:
    """(lambda, alpha) = (1.5 sqrt(L), 1.1 L), Levant 1998."""
    return 1.5 * np.sqrt(bound), 1.1 * bound


@register_observer("sto")
class SuperTwistingObserver(Observer):
    """DFL super-twisting observer on the velocity and angular-velocity channels."""

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665, *, bound_t: float = 5.0,
                 bound_a: float = 5.0) -> None:
        super().__init__(mass, inertia, gravity)
        positive("sto", bound_t=bound_t, bound_a=bound_a)
        self.lam_t, self.alpha_t = levant_gains(float(bound_t))
        self.lam_a, self.alpha_a = levant_gains(float(bound_a))
        self._s: dict[str, NDArray[np.float64]] | None = None
        self._single: tuple | None = None       # (state dict, its 12 floats) after an N = 1 fast step
        self._jl, self._jil = self.inertia.tolist(), self.inertia_inv.tolist()

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None) -> int:
        """v_hat, Omega_hat := measured; d_hat := the given guesses (as accelerations).  State: the dict ``_s``
        of (N, 3) arrays (:data:`_STATE`); the N = 1 cache ``_single`` is keyed by that dict's identity."""
        m = require(measurement, _KEYS, "sto")
        n = m["velocity"].shape[0]
        fresh = {"v": m["velocity"].copy(), "w": m["angular_velocity"].copy(),
                 "dt_": batch_vec(force, n, "force", "sto") / self.mass,
                 "da": batch_vec(torque, n, "torque", "sto") @ self.inertia_inv.T}
        self._s = write_rows(self._s, fresh, rows)
        self._single = None
        return n

    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        if self._s is None:
            raise RuntimeError("sto: call reset(measurement) before update()")
        s = self._s
        if s["v"].shape[0] == 1:
            est = self._update_single(measurement, thrust, torque, dt)
            if est is not None:
                return est
        m, f, tau = step_inputs(self, measurement, thrust, torque, dt, _KEYS, s["v"].shape[0], "sto")
        wm = m["angular_velocity"]
        j = self.inertia
        s_t = m["velocity"] - s["v"]
        s_a = wm - s["w"]
        a_t = self.gravity * _E3 - (f / self.mass)[:, None] * m["attitude"][:, :, 2]
        a_a = (cross(wm @ j.T, wm) + tau) @ self.inertia_inv.T
        new = {"v": s["v"] + dt * (a_t + self.lam_t * sig(s_t, 0.5) + s["dt_"]),
               "w": s["w"] + dt * (a_a + self.lam_a * sig(s_a, 0.5) + s["da"]),
               "dt_": s["dt_"] + dt * self.alpha_t * np.sign(s_t),
               "da": s["da"] + dt * self.alpha_a * np.sign(s_a)}
        check_finite("sto", **new)
        self._s = new
        return self.estimate()

    def _update_single(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
                       dt: float) -> ObserverEstimate | None:
        """N = 1 fast path: :meth:`update`'s equations in Python floats (numpy's per-call cost dominates 3-vectors).

        Returns None, touching nothing, unless the step is a well-formed, finite N = 1 step; the general
        path then runs and raises its usual errors.
        """
        inputs = single_inputs(measurement, _KEYS, thrust, torque, dt)
        if inputs is None:
            return None
        (vm, rm, wm), f0, tq = inputs
        v0, v1, v2, w0, w1, w2, d0, d1, d2, q0, q1, q2 = single_state(self, _STATE)
        st0, st1, st2 = vm[0] - v0, vm[1] - v1, vm[2] - v2
        m0, m1, m2 = wm
        sa0, sa1, sa2 = m0 - w0, m1 - w1, m2 - w2
        fm = f0 / self.mass
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._jl
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self._jil
        h0, h1, h2 = m0 * j00 + m1 * j01 + m2 * j02, m0 * j10 + m1 * j11 + m2 * j12, m0 * j20 + m1 * j21 + m2 * j22
        c0 = h1 * m2 - h2 * m1 + tq[0]
        c1 = h2 * m0 - h0 * m2 + tq[1]
        c2 = h0 * m1 - h1 * m0 + tq[2]
        lt, la = float(self.lam_t), float(self.lam_a)
        gt, ga = dt * float(self.alpha_t), dt * float(self.alpha_a)
        flat = [v0 + dt * (0.0 - fm * rm[2] + lt * _sig_half(st0) + d0),
                v1 + dt * (0.0 - fm * rm[5] + lt * _sig_half(st1) + d1),
                v2 + dt * (self.gravity - fm * rm[8] + lt * _sig_half(st2) + d2),
                w0 + dt * (c0 * i00 + c1 * i01 + c2 * i02 + la * _sig_half(sa0) + q0),
                w1 + dt * (c0 * i10 + c1 * i11 + c2 * i12 + la * _sig_half(sa1) + q1),
                w2 + dt * (c0 * i20 + c1 * i21 + c2 * i22 + la * _sig_half(sa2) + q2),
                d0 + gt * ((st0 > 0) - (st0 < 0)), d1 + gt * ((st1 > 0) - (st1 < 0)),
                d2 + gt * ((st2 > 0) - (st2 < 0)),
                q0 + ga * ((sa0 > 0) - (sa0 < 0)), q1 + ga * ((sa1 > 0) - (sa1 < 0)),
                q2 + ga * ((sa2 > 0) - (sa2 < 0))]
        store_single_state(self, "sto", _STATE, flat)
        mass = self.mass
        d0, d1, d2, q0, q1, q2 = flat[6:]
        out = np.array([mass * d0, mass * d1, mass * d2,
                        q0 * j00 + q1 * j01 + q2 * j02, q0 * j10 + q1 * j11 + q2 * j12, q0 * j20 + q1 * j21 + q2 * j22]
                       + flat[0:6])
        return ObserverEstimate(force=out[None, 0:3], torque=out[None, 3:6], states={
            "velocity": out[None, 6:9], "angular_velocity": out[None, 9:12]})

    def estimate(self) -> ObserverEstimate:
        if self._s is None:
            raise RuntimeError("sto: call reset(measurement) first")
        s = self._s
        return ObserverEstimate(force=self.mass * s["dt_"], torque=s["da"] @ self.inertia.T, states={
            "velocity": s["v"].copy(), "angular_velocity": s["w"].copy()})
