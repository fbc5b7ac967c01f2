"""Hölder-continuous extended state observer (HC-ESO) on SO(3) from vector measurements.

Source: ``hc_eso_so3_wang2022.txt`` (Wang and Sanyal, IFAC PapersOnLine 55-22, 2022), Prop. 3.

Model (eq. 6): ``R' = R Omega^x``, ``Omega' = J^-1 (J Omega x Omega + tau) + sigma``, ``sigma' = delta``
with ``sigma = J^-1 tau_d``.  From the inertial vectors E, their body measurements U^m (through
``L = E W (U^m)^T``, :mod:`.vector_attitude`) and the measured rate ``Omega^m`` (eq. 16), the ESO
(eq. 30) is::

    R_hat'     = R_hat Omega_hat^x
    Omega_hat' = J^-1 (J Omega^m x Omega^m + tau) + sigma_hat + k_Psi (Psi^T Psi)^((alpha-1)/2) Psi
                 - kappa (s_L^T s_L)^((alpha-1)/gamma) H(s_L) w_L(R_hat, Omega_hat, Omega^m)
    sigma_hat' = k_sigma (Psi^T Psi)^(alpha-1) Psi

with ``Omega_tilde = Omega^m - Omega_hat`` (eq. 17), ``Psi = Omega_tilde - kappa z_L(R_hat)``
(eq. 29), ``z_L``, ``w_L``, ``H`` of eqs. 26-28.  Parameters (Prop. 3): gamma a positive
integer, 1/2 < alpha < 1, gamma - 3 alpha + 1 >= 0, kappa > 0, k_Psi, k_sigma > 0.

Integration is geometric (Sec. 6): one Lie-Euler step of size h is
``R_hat <- R_hat exp(h Omega_hat^x)``, ``Omega_hat <- Omega_hat + h P``, ``sigma_hat <- sigma_hat + h Q``
with P, Q the right-hand sides at the start of the step, so R_hat stays on SO(3) without
projection.  Between two measurements the measured vectors are propagated with the measured rate
(``L <- L exp(h (Omega^m)^x)``, the same L' = L Omega^x that eq. 27 assumes).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.envs import measurement as M

from . import vector_attitude as va
from .base import Observer, ObserverEstimate, register_observer
from .lie import _SMALL as _LIE_SMALL
from .lie import exp_so3

#: the Morse-function gains K (Lemma 1) used when none are given; the paper's simulation does not state
#: its K, any k1 > k2 > k3 >= 1 is admissible.
DEFAULT_MORSE_GAINS = (3.0, 2.0, 1.0)


@dataclasses.dataclass(frozen=True)
class HcEsoGains:
    """ESO parameters of Prop. 3; defaults are the paper's Sec. 6 values."""

    alpha: float = 0.85
    gamma: int = 2
    kappa: float = 0.15
    k_sigma: float = 5.0
    k_psi: float = 5.0

    def __post_init__(self) -> None:
        number = (int, float, np.integer, np.floating)
        if (isinstance(self.gamma, bool) or not isinstance(self.gamma, number) or not float(self.gamma).is_integer()
                or self.gamma < 1):
            raise ValueError(f"gamma must be a positive integer (Prop. 3), got {self.gamma!r}")
        if isinstance(self.alpha, bool) or not isinstance(self.alpha, number) or not (0.5 < self.alpha < 1.0):
            raise ValueError(f"alpha must satisfy 1/2 < alpha < 1 (Prop. 3), got {self.alpha!r}")
        if self.gamma - 3.0 * self.alpha + 1.0 < 0:
            raise ValueError(f"gamma - 3 alpha + 1 must be >= 0 (Prop. 3), got gamma={self.gamma}, "
                             f"alpha={self.alpha}")
        for name in ("kappa", "k_sigma", "k_psi"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, number) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite positive number, got {v!r}")


def hc_eso_rates(r_hat: NDArray[np.float64], omega_hat: NDArray[np.float64], sigma_hat: NDArray[np.float64],
                 l: NDArray[np.float64], omega_m: NDArray[np.float64], tau: NDArray[np.float64],
                 inertia: NDArray[np.float64], gains: HcEsoGains,
                 inertia_inv: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64], ...]:
    """Right-hand sides ``(P, Q)`` of the Omega_hat and sigma_hat equations of eq. 30, plus ``(Psi, s_L)``.

    Shapes: r_hat, l (N, 3, 3); omega_hat, sigma_hat, omega_m, tau (N, 3).
    """
    a, g = gains.alpha, float(gains.gamma)
    j_inv = np.linalg.inv(inertia) if inertia_inv is None else inertia_inv
    s, wl = va.s_l_w_l(l, r_hat, omega_hat, omega_m)  # eqs. 22, 27
    s2 = np.maximum((s * s).sum(axis=-1), va._S2_FLOOR)[..., None]
    psi = (omega_m - omega_hat) - gains.kappa * (s2[..., 0] ** ((a - 1.0) / g))[..., None] * s  # eq. 29 (26), 17
    psi2 = np.maximum((psi * psi).sum(axis=-1), va._S2_FLOOR)[..., None]
    hw = (va.h_matrix(s, a, g) @ wl[..., None])[..., 0]
    jw = omega_m @ inertia.T
    jwxw = jw.take(va._I1, -1) * omega_m.take(va._I2, -1) - jw.take(va._I2, -1) * omega_m.take(va._I1, -1)
    p = ((jwxw + tau) @ j_inv.T + sigma_hat + gains.k_psi * psi2 ** ((a - 1.0) / 2.0) * psi
         - gains.kappa * s2 ** ((a - 1.0) / g) * hw)
    q = gains.k_sigma * psi2 ** (a - 1.0) * psi
    return p, q, psi, s


def hc_eso_step(r_hat: NDArray[np.float64], omega_hat: NDArray[np.float64], sigma_hat: NDArray[np.float64],
                l: NDArray[np.float64], omega_m: NDArray[np.float64], tau: NDArray[np.float64],
                inertia: NDArray[np.float64], gains: HcEsoGains, h: float,
                inertia_inv: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64], ...]:
    """One geometric (Lie-Euler) step of eq. 30 of size h; returns (R_hat, Omega_hat, sigma_hat)."""
    p, q, _, _ = hc_eso_rates(r_hat, omega_hat, sigma_hat, l, omega_m, tau, inertia, gains, inertia_inv)
    return r_hat @ _exp_so3(h * omega_hat), omega_hat + h * p, sigma_hat + h * q


_EYE = np.eye(3)


def _exp_so3(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`fawtgym.observers.lie.exp_so3` (same formulas and threshold, same numbers) evaluating only
    the branch (Taylor series or Rodrigues) that the whole batch needs; a mixed batch goes to lie."""
    th2 = (w * w).sum(axis=-1)[..., None, None]
    small = th2 < _LIE_SMALL
    if small.all():
        a = 1.0 - th2 / 6.0 + th2 * th2 / 120.0
        b = 0.5 - th2 / 24.0 + th2 * th2 / 720.0
    elif not small.any():
        th = np.sqrt(th2)
        a = np.sin(th) / th
        b = (1.0 - np.cos(th)) / (th * th)
    else:
        return exp_so3(w)
    k = va._hat(w)
    return _EYE + a * k + b * (k @ k)


VECTOR_SOURCES = ("imu", "attitude")


@register_observer("hc_eso")
class HcEsoSO3(Observer):
    """HC-ESO on SO(3) (Wang and Sanyal 2022, eq. 30) estimating the body disturbance torque ``J sigma_hat``.

    Options (defaults in brackets): ``alpha`` [0.85], ``gamma`` [2], ``kappa`` [0.15],
    ``k_sigma`` [5], ``k_psi`` [5] (all Sec. 6); ``morse_gains`` K [(3, 2, 1), not stated in the
    paper]; ``vectors``: ``"imu"`` [default: gravity from the accelerometer, Earth field from the
    magnetometer, their cross product, :func:`vector_attitude.imu_vector_set`] or ``"attitude"``
    (the body images of the NED axes from the measured attitude, ``U^m = (R^m)^T I``);
    ``rate_key`` ["angular_velocity" or "gyro"]; ``max_step`` [0.005 s]: each update integrates
    ``ceil(dt / max_step)`` Lie-Euler steps.  Measurements are held over the update interval (the
    previous update's vectors, propagated with the previous rate).

    ``states``: ``"attitude"`` R_hat (N, 3, 3), ``"angular_velocity"`` Omega_hat (N, 3),
    ``"sigma"`` sigma_hat = J^-1 tau_hat (N, 3).
    """

    channels = frozenset({"torque"})

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665, *, alpha: float = 0.85,
                 gamma: int = 2, kappa: float = 0.15, k_sigma: float = 5.0, k_psi: float = 5.0,
                 morse_gains: ArrayLike = DEFAULT_MORSE_GAINS, vectors: str = "imu",
                 rate_key: str = M.ANGULAR_VELOCITY, max_step: float = 0.005,
                 field_ned: ArrayLike = M.EARTH_FIELD_NED) -> None:
        super().__init__(mass, inertia, gravity)
        self.gains = HcEsoGains(alpha, gamma, kappa, k_sigma, k_psi)
        self.morse_gains = va.check_morse_gains(morse_gains)
        if vectors not in VECTOR_SOURCES:
            raise ValueError(f"vectors must be one of {VECTOR_SOURCES}, got {vectors!r}")
        if rate_key not in (M.ANGULAR_VELOCITY, M.GYRO):
            raise ValueError(f"rate_key must be {M.ANGULAR_VELOCITY!r} or {M.GYRO!r}, got {rate_key!r}")
        if not (isinstance(max_step, (int, float)) and math.isfinite(max_step) and max_step > 0):
            raise ValueError(f"max_step must be a finite positive number of seconds, got {max_step!r}")
        self.vectors, self.rate_key, self.max_step = vectors, rate_key, float(max_step)
        self.field_ned = np.asarray(field_ned, float)
        if vectors == "attitude":
            self._e = np.eye(3)
        else:
            self._e = va.imu_inertial_vectors(self.field_ned)
        self._w = va.wahba_weight(self._e, self.morse_gains)
        self._ew = self._e @ self._w
        self._state: tuple[NDArray[np.float64], ...] | None = None
        self._held: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def _measured(self, meas: Mapping[str, NDArray[np.float64]]) -> tuple[NDArray[np.float64], ...]:
        keys = (M.ATTITUDE,) if self.vectors == "attitude" else (M.SPECIFIC_FORCE, M.MAGNETOMETER)
        for key in keys + (self.rate_key,):
            if key not in meas:
                raise ValueError(f"HC-ESO (vectors={self.vectors!r}) needs measurement[{key!r}]; "
                                 f"got keys {sorted(meas)}")
            if not np.isfinite(meas[key]).all():
                raise ValueError(f"measurement[{key!r}] contains non-finite values")
        if self.vectors == "attitude":
            u_m = np.swapaxes(meas[M.ATTITUDE], -1, -2) @ self._e
        else:
            u_m = va.imu_body_vectors(meas[M.SPECIFIC_FORCE], meas[M.MAGNETOMETER])
        return self._ew @ np.swapaxes(u_m, -1, -2), meas[self.rate_key]  # L = (E W) (U^m)^T (va.gain_matrix)

    def reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None = None,
              torque: ArrayLike | None = None) -> None:
        """R_hat from the static Wahba solution of the vectors, Omega_hat = Omega^m, sigma_hat = J^-1 torque guess."""
        meas = M.batch_measurement(measurement)
        l, omega_m = self._measured(meas)
        sigma = np.zeros_like(omega_m)
        if torque is not None:
            t = np.asarray(torque, dtype=float)
            if t.shape[-1:] != (3,) or not np.all(np.isfinite(t)):
                raise ValueError(f"initial torque guess must be finite with shape (3,) or (N, 3), got {t.shape}")
            sigma = np.broadcast_to(t @ self.inertia_inv.T, omega_m.shape).copy()
        self._state = (va.solve_wahba(l), omega_m.copy(), sigma)
        self._held = (l, omega_m)

    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        if self._state is None or self._held is None:
            raise ValueError("HcEsoSO3.update called before reset(measurement)")
        meas, _, tau = self._inputs(measurement, thrust, torque, dt)
        r_hat, omega_hat, sigma_hat = self._state
        n = r_hat.shape[0]
        try:
            tau = tau if tau.shape == (n, 3) else np.broadcast_to(tau, (n, 3))
        except ValueError:
            raise ValueError(f"torque {tau.shape} does not match the batch size {n} set at reset") from None
        l, omega_m = self._held
        steps = max(1, math.ceil(dt / self.max_step - 1e-9))
        h = dt / steps
        rot = _exp_so3(h * omega_m) if steps > 1 else None
        for k in range(steps):  # loop over time substeps, not over the batch
            r_hat, omega_hat, sigma_hat = hc_eso_step(r_hat, omega_hat, sigma_hat, l, omega_m, tau, self.inertia,
                                                      self.gains, h, self.inertia_inv)
            if k + 1 < steps:  # the held vectors for the next substep (after the last one, new ones come)
                l = l @ rot
        if not (np.isfinite(omega_hat).all() and np.isfinite(sigma_hat).all()):
            raise ValueError(f"HC-ESO state became non-finite (dt={dt}, max_step={self.max_step}); "
                             "reduce max_step or the gains")
        new_l, new_omega = self._measured(meas)
        if new_l.shape[0] != n:
            raise ValueError(f"measurement batch size {new_l.shape[0]} != {n} set at reset")
        self._state = (r_hat, omega_hat, sigma_hat)
        self._held = (new_l, new_omega)
        return ObserverEstimate(force=np.zeros((n, 3)), torque=sigma_hat @ self.inertia.T,
                                states={"attitude": r_hat.copy(), "angular_velocity": omega_hat.copy(),
                                        "sigma": sigma_hat.copy()})
