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
    cross,
    positive,
    require,
    sig,
)
from fawtgym.observers.base import Observer, ObserverEstimate, register_observer

_E3 = np.array([0.0, 0.0, 1.0])
_KEYS = ("velocity", "attitude", "angular_velocity")
#: the largest disturbance-acceleration error [m/s^2 or rad/s^2] the Euler step must keep stable (10 g)
LARGE_ERROR = 10.0 * 9.80665


@register_observer("fxtsdo")
class FxTSDO(Observer):
    """Fixed-time DO on finite-differenced velocities (Liu et al. 2022, as in Wang et al. 2024, Sec. 6).

    ``max_dt`` = 2 / (k2 a2 E^(a2 - 1)) with E = :data:`LARGE_ERROR` (10 g): explicit Euler of
    d' = k1 sig^a1(e) + k2 sig^a2(e), e = r - d, diverges once the law's slope times dt exceeds 2, and the
    a2 > 1 term's slope grows with |e|; the bound keeps errors up to 10 g inside the stable region
    (27 ms at the defaults).
    """

    required_keys = _KEYS

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665, *, k1: float = 5.0,
                 k2: float = 5.0, a1: float = 0.5, a2: float = 1.5) -> None:
        super().__init__(mass, inertia, gravity)
        positive("fxtsdo", k1=k1, k2=k2)
        if not (0.0 < a1 < 1.0 < a2):
            raise ValueError(f"fxtsdo: fixed-time exponents need 0 < a1 < 1 < a2, got a1={a1!r}, a2={a2!r}")
        self.k1, self.k2, self.a1, self.a2 = float(k1), float(k2), float(a1), float(a2)
        self._state: dict[str, NDArray[np.float64]] | None = None
        # explicit Euler of d' = law(r - d) is stable while law's slope times dt < 2; the a2 > 1 term's slope
        # k2 a2 |e|^(a2-1) grows without bound, so dt is bounded to keep errors up to LARGE_ERROR stable
        self.max_dt = 2.0 / (self.k2 * self.a2 * LARGE_ERROR ** (self.a2 - 1.0))

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None) -> int:
        """Previous velocities := measured; d_hat := the given guesses (as accelerations).  State: the dict ``_state``
        of (N, 3) arrays."""
        m = require(measurement, _KEYS, "fxtsdo")
        n = m["velocity"].shape[0]
        fresh = {"v_prev": m["velocity"].copy(), "w_prev": m["angular_velocity"].copy(),
                 "dt_": batch_vec(force, n, "force", "fxtsdo") / self.mass,
                 "da": batch_vec(torque, n, "torque", "fxtsdo") @ self.inertia_inv.T}
        self._state = write_rows(self._state, fresh, rows)
        return n

    def _law(self, e: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.k1 * sig(e, self.a1) + self.k2 * sig(e, self.a2)

    def _update(self, m: dict[str, NDArray[np.float64]], f: NDArray[np.float64], tau: NDArray[np.float64],
                dt: float) -> tuple[ObserverEstimate, dict[str, NDArray[np.float64]]]:
        s = self._state
        v, w = m["velocity"], m["angular_velocity"]
        acc = (v - s["v_prev"]) / dt
        wdot = (w - s["w_prev"]) / dt
        e_t = acc - (self.gravity * _E3 - (f / self.mass)[:, None] * m["attitude"][:, :, 2]) - s["dt_"]
        j = self.inertia
        e_a = wdot - (cross(w @ j.T, w) + tau) @ self.inertia_inv.T - s["da"]
        new = {"v_prev": v.copy(), "w_prev": w.copy(), "dt_": s["dt_"] + dt * self._law(e_t),
               "da": s["da"] + dt * self._law(e_a)}
        return self._estimate_of(new), new

    def estimate(self) -> ObserverEstimate:
        if self._state is None:
            raise RuntimeError("fxtsdo: call reset(measurement) first")
        return self._estimate_of(self._state)

    def _estimate_of(self, s: dict[str, NDArray[np.float64]]) -> ObserverEstimate:
        return ObserverEstimate(force=self.mass * s["dt_"], torque=s["da"] @ self.inertia.T, states={})
