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
_STATE = ("v_prev", "w_prev", "dt_", "da")  # the state dict's entries, (N, 3) each, in the N = 1 path's float order


@register_observer("fxtsdo")
class FxTSDO(Observer):
    """Fixed-time DO on finite-differenced velocities (Liu et al. 2022, as in Wang et al. 2024, Sec. 6)."""

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665, *, k1: float = 5.0,
                 k2: float = 5.0, a1: float = 0.5, a2: float = 1.5) -> None:
        super().__init__(mass, inertia, gravity)
        positive("fxtsdo", k1=k1, k2=k2)
        if not (0.0 < a1 < 1.0 < a2):
            raise ValueError(f"fxtsdo: fixed-time exponents need 0 < a1 < 1 < a2, got a1={a1!r}, a2={a2!r}")
        self.k1, self.k2, self.a1, self.a2 = float(k1), float(k2), float(a1), float(a2)
        self._s: dict[str, NDArray[np.float64]] | None = None
        self._single: tuple | None = None       # (state dict, its 12 floats) after an N = 1 fast step
        self._jl, self._jil = self.inertia.tolist(), self.inertia_inv.tolist()

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None) -> int:
        """Previous velocities := measured; d_hat := the given guesses (as accelerations).  State: the dict ``_s``
        of (N, 3) arrays (:data:`_STATE`); the N = 1 cache ``_single`` is keyed by that dict's identity."""
        m = require(measurement, _KEYS, "fxtsdo")
        n = m["velocity"].shape[0]
        fresh = {"v_prev": m["velocity"].copy(), "w_prev": m["angular_velocity"].copy(),
                 "dt_": batch_vec(force, n, "force", "fxtsdo") / self.mass,
                 "da": batch_vec(torque, n, "torque", "fxtsdo") @ self.inertia_inv.T}
        self._s = write_rows(self._s, fresh, rows)
        self._single = None
        return n

    def _law(self, e: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.k1 * sig(e, self.a1) + self.k2 * sig(e, self.a2)

    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        if self._s is None:
            raise RuntimeError("fxtsdo: call reset(measurement) before update()")
        s = self._s
        if s["v_prev"].shape[0] == 1:
            est = self._update_single(measurement, thrust, torque, dt)
            if est is not None:
                return est
        m, f, tau = step_inputs(self, measurement, thrust, torque, dt, _KEYS, s["v_prev"].shape[0], "fxtsdo")
        v, w = m["velocity"], m["angular_velocity"]
        acc = (v - s["v_prev"]) / dt
        wdot = (w - s["w_prev"]) / dt
        e_t = acc - (self.gravity * _E3 - (f / self.mass)[:, None] * m["attitude"][:, :, 2]) - s["dt_"]
        j = self.inertia
        e_a = wdot - (cross(w @ j.T, w) + tau) @ self.inertia_inv.T - s["da"]
        new = {"v_prev": v.copy(), "w_prev": w.copy(), "dt_": s["dt_"] + dt * self._law(e_t),
               "da": s["da"] + dt * self._law(e_a)}
        check_finite("fxtsdo", dt_=new["dt_"], da=new["da"])
        self._s = new
        return self.estimate()

    def _law1(self, e: float) -> float:
        """:meth:`_law` for one float: k1 sig^a1(e) + k2 sig^a2(e)."""
        if e > 0:
            return self.k1 * e ** self.a1 + self.k2 * e ** self.a2
        if e < 0:
            return self.k1 * -((-e) ** self.a1) + self.k2 * -((-e) ** self.a2)
        return 0.0

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
        flat = single_state(self, _STATE)
        d0, d1, d2, q0, q1, q2 = flat[6:]
        fm = f0 / self.mass
        m0, m1, m2 = wm
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._jl
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self._jil
        h0, h1, h2 = m0 * j00 + m1 * j01 + m2 * j02, m0 * j10 + m1 * j11 + m2 * j12, m0 * j20 + m1 * j21 + m2 * j22
        c0 = h1 * m2 - h2 * m1 + tq[0]
        c1 = h2 * m0 - h0 * m2 + tq[1]
        c2 = h0 * m1 - h1 * m0 + tq[2]
        law = self._law1
        nd = [d0 + dt * law((vm[0] - flat[0]) / dt - (0.0 - fm * rm[2]) - d0),
              d1 + dt * law((vm[1] - flat[1]) / dt - (0.0 - fm * rm[5]) - d1),
              d2 + dt * law((vm[2] - flat[2]) / dt - (self.gravity - fm * rm[8]) - d2),
              q0 + dt * law((m0 - flat[3]) / dt - (c0 * i00 + c1 * i01 + c2 * i02) - q0),
              q1 + dt * law((m1 - flat[4]) / dt - (c0 * i10 + c1 * i11 + c2 * i12) - q1),
              q2 + dt * law((m2 - flat[5]) / dt - (c0 * i20 + c1 * i21 + c2 * i22) - q2)]
        store_single_state(self, "fxtsdo", _STATE, vm + wm + nd)
        mass = self.mass
        d0, d1, d2, q0, q1, q2 = nd
        out = np.array([mass * d0, mass * d1, mass * d2,
                        q0 * j00 + q1 * j01 + q2 * j02, q0 * j10 + q1 * j11 + q2 * j12, q0 * j20 + q1 * j21 + q2 * j22])
        return ObserverEstimate(force=out[None, 0:3], torque=out[None, 3:6], states={})

    def estimate(self) -> ObserverEstimate:
        if self._s is None:
            raise RuntimeError("fxtsdo: call reset(measurement) first")
        s = self._s
        return ObserverEstimate(force=self.mass * s["dt_"], torque=s["da"] @ self.inertia.T, states={})
