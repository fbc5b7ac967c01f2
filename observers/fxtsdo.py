"""Fixed-time disturbance observer (FxTSDO), the seed-000 baseline of Liu et al. 2022.

Source of the comparison: ``ffts_eso_tse3_fawt_wang2024.txt`` Remark 2 and Sec. 6 (ref. [22], Liu et
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

from fawtgym.observers._obs_common import (
    batch_vec,
    check_finite,
    cross,
    positive,
    require,
    sig,
    step_inputs,
)
from fawtgym.observers.base import Observer, ObserverEstimate, register_observer

_E3 = np.array([0.0, 0.0, 1.0])
_KEYS = ("velocity", "attitude", "angular_velocity")


@register_observer("fxtsdo")
class FxTSDO(Observer):
    """Fixed-time DO on finite-differenced velocities (Liu et al. 2022 as used in seed-000 Sec. 6, Remark 2)."""

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665, *, k1: float = 5.0,
                 k2: float = 5.0, a1: float = 0.5, a2: float = 1.5) -> None:
        super().__init__(mass, inertia, gravity)
        positive("fxtsdo", k1=k1, k2=k2)
        if not (0.0 < a1 < 1.0 < a2):
            raise ValueError(f"fxtsdo: fixed-time exponents need 0 < a1 < 1 < a2, got a1={a1!r}, a2={a2!r}")
        self.k1, self.k2, self.a1, self.a2 = float(k1), float(k2), float(a1), float(a2)
        self._s: dict[str, NDArray[np.float64]] | None = None

    def reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None = None,
              torque: ArrayLike | None = None) -> None:
        m = require(measurement, _KEYS, "fxtsdo")
        n = m["velocity"].shape[0]
        self._s = {"v_prev": m["velocity"].copy(), "w_prev": m["angular_velocity"].copy(),
                   "dt_": batch_vec(force, n, "force", "fxtsdo") / self.mass,
                   "da": batch_vec(torque, n, "torque", "fxtsdo") @ self.inertia_inv.T}

    def _law(self, e: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.k1 * sig(e, self.a1) + self.k2 * sig(e, self.a2)

    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        if self._s is None:
            raise RuntimeError("fxtsdo: call reset(measurement) before update()")
        s = self._s
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

    def estimate(self) -> ObserverEstimate:
        if self._s is None:
            raise RuntimeError("fxtsdo: call reset(measurement) first")
        s = self._s
        return ObserverEstimate(force=self.mass * s["dt_"], torque=s["da"] @ self.inertia.T, states={})
