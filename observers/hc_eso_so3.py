"""Hölder-continuous extended state observer (HC-ESO) on SO(3) from vector measurements.

Source: (Wang and Sanyal, IFAC PapersOnLine 55-22, 2022), Prop. 3.

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

A single vehicle runs the same step in Python floats (:func:`hc_eso_step_single`, numpy's per-call
overhead dominating 3-vectors); the batched numpy functions are the reference it is tested against
(tests/test_obs2_hceso_fastpath.py).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M
from fawtgym.core.measurement import TRAILING_SHAPES as _MEAS_TRAILING
from fawtgym.core.rows import write_rows
from fawtgym.core.so3 import _SMALL as _LIE_SMALL
from fawtgym.core.so3 import exp_so3, exp_so3_floats, matmul33_floats

from . import vector_attitude as va
from ._obs_common import single_inputs
from .base import Observer, ObserverEstimate, register_observer

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

    @functools.cached_property
    def single_constants(self) -> tuple[float, ...]:
        """Constants of :func:`hc_eso_step_single`: ``((alpha-1)/gamma, 2 (1-alpha)/gamma, (alpha-1)/2, alpha-1,
        kappa, k_Psi, k_sigma)`` as Python floats."""
        a, g = float(self.alpha), float(self.gamma)
        return ((a - 1.0) / g, 2.0 * (1.0 - a) / g, (a - 1.0) / 2.0, a - 1.0, float(self.kappa), float(self.k_psi),
                float(self.k_sigma))


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
    """:func:`fawtgym.core.so3.exp_so3` (same formulas and threshold, same numbers) evaluating only
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


def hc_eso_step_single(r_hat: Sequence[float], omega_hat: Sequence[float], sigma_hat: Sequence[float],
                       l: Sequence[float], omega_m: Sequence[float], tau: Sequence[float],
                       inertia: Sequence[float], inertia_inv: Sequence[float], gains: HcEsoGains,
                       h: float) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """:func:`hc_eso_step` for one vehicle in Python floats (the observer's N = 1 fast path).

    Matrices (R_hat, L, J, J^-1) row-major as 9 floats, vectors as 3 floats.  The same equations as
    :func:`hc_eso_rates` and :func:`hc_eso_step`, written out per component with ``A = L^T R_hat``:

    * ``s_L = vex(A - A^T)`` (eq. 22), i.e. (A21 - A12, A02 - A20, A10 - A01);
    * ``w_L = (tr(A) I - A^T) Omega_hat - (tr(A) I - A) Omega^m`` (eq. 27: vex(A W + W A^T) = (tr(A) I - A^T) w
      for W = w^x, the closed form of :func:`vector_attitude.s_l_w_l`);
    * ``z_L = (s_L^T s_L)^((alpha-1)/gamma) s_L`` (eq. 26), ``Psi = Omega^m - Omega_hat - kappa z_L`` (eqs. 17, 29);
    * ``H(s_L) w_L = w_L - 2 (1-alpha)/gamma (s_L^T w_L) / (s_L^T s_L) s_L`` (eq. 28);
    * P, Q of eq. 30 and one Lie-Euler step ``R_hat exp(h Omega_hat^x)``, ``Omega_hat + h P``, ``sigma_hat + h Q``.

    The floor on s^T s and Psi^T Psi is :data:`vector_attitude._S2_FLOOR`, as in the batched functions.
    Returns (R_hat, Omega_hat, sigma_hat) as tuples of floats.
    """
    e_z, c_h, e_psi, e_sig, kap, k_psi, k_sig = gains.single_constants
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r_hat
    l00, l01, l02, l10, l11, l12, l20, l21, l22 = l
    w0, w1, w2 = omega_hat
    o0, o1, o2 = omega_m
    # A = L^T R_hat
    a00 = l00 * r00 + l10 * r10 + l20 * r20
    a01 = l00 * r01 + l10 * r11 + l20 * r21
    a02 = l00 * r02 + l10 * r12 + l20 * r22
    a10 = l01 * r00 + l11 * r10 + l21 * r20
    a11 = l01 * r01 + l11 * r11 + l21 * r21
    a12 = l01 * r02 + l11 * r12 + l21 * r22
    a20 = l02 * r00 + l12 * r10 + l22 * r20
    a21 = l02 * r01 + l12 * r11 + l22 * r21
    a22 = l02 * r02 + l12 * r12 + l22 * r22
    s0, s1, s2 = a21 - a12, a02 - a20, a10 - a01  # s_L, eq. 22
    t12, t02, t01 = a11 + a22, a00 + a22, a00 + a11
    wl0 = (t12 * w0 - a10 * w1 - a20 * w2) - (t12 * o0 - a01 * o1 - a02 * o2)  # w_L, eq. 27
    wl1 = (t02 * w1 - a01 * w0 - a21 * w2) - (t02 * o1 - a10 * o0 - a12 * o2)
    wl2 = (t01 * w2 - a02 * w0 - a12 * w1) - (t01 * o2 - a20 * o0 - a21 * o1)
    ss = s0 * s0 + s1 * s1 + s2 * s2
    ss = ss if ss > va._S2_FLOOR else va._S2_FLOOR
    zf = ss**e_z  # (s^T s)^((alpha-1)/gamma), eqs. 26, 30
    kz = kap * zf
    p0, p1, p2 = (o0 - w0) - kz * s0, (o1 - w1) - kz * s1, (o2 - w2) - kz * s2  # Psi, eq. 29
    pp = p0 * p0 + p1 * p1 + p2 * p2
    pp = pp if pp > va._S2_FLOOR else va._S2_FLOOR
    hc = c_h * (s0 * wl0 + s1 * wl1 + s2 * wl2) / ss  # H(s_L) w_L, eq. 28
    hw0, hw1, hw2 = wl0 - hc * s0, wl1 - hc * s1, wl2 - hc * s2
    j00, j01, j02, j10, j11, j12, j20, j21, j22 = inertia
    i00, i01, i02, i10, i11, i12, i20, i21, i22 = inertia_inv
    jw0, jw1, jw2 = j00 * o0 + j01 * o1 + j02 * o2, j10 * o0 + j11 * o1 + j12 * o2, j20 * o0 + j21 * o1 + j22 * o2
    u0 = jw1 * o2 - jw2 * o1 + tau[0]  # J Omega^m x Omega^m + tau
    u1 = jw2 * o0 - jw0 * o2 + tau[1]
    u2 = jw0 * o1 - jw1 * o0 + tau[2]
    kp = k_psi * pp**e_psi
    sg0, sg1, sg2 = sigma_hat
    pd0 = i00 * u0 + i01 * u1 + i02 * u2 + sg0 + kp * p0 - kz * hw0  # P of eq. 30
    pd1 = i10 * u0 + i11 * u1 + i12 * u2 + sg1 + kp * p1 - kz * hw1
    pd2 = i20 * u0 + i21 * u1 + i22 * u2 + sg2 + kp * p2 - kz * hw2
    ks = k_sig * pp**e_sig  # Q of eq. 30 is ks Psi
    rot = matmul33_floats(r_hat, exp_so3_floats(h * w0, h * w1, h * w2))
    return (rot, (w0 + h * pd0, w1 + h * pd1, w2 + h * pd2),
            (sg0 + h * (ks * p0), sg1 + h * (ks * p1), sg2 + h * (ks * p2)))


#: allowed shapes of every known measurement key in an N = 1 step: (trailing) or (1, *trailing)
_SINGLE_SHAPES = {k: (t, (1,) + t) for k, t in _MEAS_TRAILING.items()}


def _single_shapes_ok(measurement: Mapping[str, object], torque: object) -> bool:
    """True iff :func:`fawtgym.core.measurement.batch_measurement` accepts ``measurement`` as an N = 1 batch
    (every value a numeric numpy array/scalar, or a Python number under ``"time"`` or an unknown key; every
    known key shaped (trailing) or (1, *trailing)) and ``torque`` is (3,) or (1, 3).

    Anything else goes to the batched path, which raises (or, for a shape it does accept, computes) as before.
    """
    ts = torque.shape if type(torque) is np.ndarray else np.shape(torque)
    if ts != (3,) and ts != (1, 3):
        return False
    get = _SINGLE_SHAPES.get
    for key, value in measurement.items():
        try:
            allowed = get(key)
            if allowed is not None and value.shape not in allowed or value.dtype.kind not in "fiub":
                return False
        except AttributeError:  # not a numpy array or scalar
            if not isinstance(value, (int, float)) or key != M.TIME and key in _SINGLE_SHAPES:
                return False
    return True


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

    A single vehicle (N = 1 at reset) takes a fast path (:meth:`_update_single`: the same equations in
    Python floats, :func:`hc_eso_step_single`) whenever the step is well formed and finite (numpy
    arrays or numbers as measurement values); anything else takes the batched path, the reference,
    which raises the usual errors.
    """

    channels = frozenset({"torque"})
    #: False sends every update through the batched path (tests compare the two paths)
    _fast_path: bool = True

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
        # N = 1 fast path: (R_hat, Omega_hat, sigma_hat, L, Omega^m) as tuples/lists of floats, newer than
        # self._state / self._held when not None (written back by _sync_single)
        self._single: tuple[Sequence[float], ...] | None = None
        self._jl = tuple(self.inertia.ravel().tolist())
        self._jil = tuple(self.inertia_inv.ravel().tolist())
        self._ewl = tuple(self._ew.ravel().tolist())
        self._el = tuple(self._e.ravel().tolist())
        self._keys = (((M.ATTITUDE,) if vectors == "attitude" else (M.SPECIFIC_FORCE, M.MAGNETOMETER))
                      + (rate_key,))

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

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None) -> int:
        """R_hat from the static Wahba solution of the vectors, Omega_hat = Omega^m, sigma_hat = J^-1 torque guess.

        State: the tuples ``_state`` (R_hat (N, 3, 3), Omega_hat (N, 3), sigma_hat (N, 3)) and ``_held``
        (L (N, 3, 3), Omega^m (N, 3)), behind the N = 1 float state ``_single`` when it is set (synced before a
        masked write)."""
        meas = M.batch_measurement(measurement)
        l, omega_m = self._measured(meas)
        sigma = np.zeros_like(omega_m)
        if torque is not None:
            t = np.asarray(torque, dtype=float)
            if t.shape[-1:] != (3,) or not np.all(np.isfinite(t)):
                raise ValueError(f"initial torque guess must be finite with shape (3,) or (N, 3), got {t.shape}")
            sigma = np.broadcast_to(t @ self.inertia_inv.T, omega_m.shape).copy()
        fresh_state = (va.solve_wahba(l), omega_m.copy(), sigma)
        fresh_held = (l, omega_m.copy())  # a copy: omega_m may be the caller's array
        self._sync_single()
        self._state = write_rows(self._state, fresh_state, rows)
        self._held = write_rows(self._held, fresh_held, rows)
        self._single = None
        return omega_m.shape[0]

    def _gain_matrix_single(self, values: list[list[float]]) -> list[float] | None:
        """L = (E W) (U^m)^T for one vehicle (as :meth:`_measured`), row-major 9 floats; None where
        :meth:`_measured` raises (degenerate IMU vectors)."""
        if self.vectors == "attitude":
            rm = values[0]
            u = matmul33_floats(rm[0::3] + rm[1::3] + rm[2::3], self._el)  # U^m = (R^m)^T E
        else:
            u = va.imu_body_vectors_single(values[0], values[1])
            if u is None:
                return None
        e00, e01, e02, e10, e11, e12, e20, e21, e22 = self._ewl
        u00, u01, u02, u10, u11, u12, u20, u21, u22 = u
        return [e00 * u00 + e01 * u01 + e02 * u02, e00 * u10 + e01 * u11 + e02 * u12, e00 * u20 + e01 * u21 + e02 * u22,
                e10 * u00 + e11 * u01 + e12 * u02, e10 * u10 + e11 * u11 + e12 * u12, e10 * u20 + e11 * u21 + e12 * u22,
                e20 * u00 + e21 * u01 + e22 * u02, e20 * u10 + e21 * u11 + e22 * u12, e20 * u20 + e21 * u21 + e22 * u22]

    def _update_single(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
                       dt: float) -> ObserverEstimate | None:
        """N = 1 fast path: :meth:`update`'s batched step in Python floats (:func:`hc_eso_step_single`).

        Same scheme as the batched path: ``ceil(dt / max_step)`` Lie-Euler substeps of eq. 30 with the
        held L (propagated by ``exp(h (Omega^m)^x)`` between substeps) and Omega^m, then the new
        measurement becomes the held one.  Returns None, touching nothing, unless the step is a
        well-formed, finite N = 1 step (:func:`_obs_common.single_inputs`, :func:`_single_shapes_ok`)
        with usable vectors; :meth:`update`'s batched path then runs and raises its usual errors.
        """
        got = single_inputs(measurement, self._keys, thrust, torque, dt)
        if got is None or not _single_shapes_ok(measurement, torque):
            return None
        values, _, tau = got
        new_l = self._gain_matrix_single(values)
        if new_l is None:
            return None
        cache = self._single
        if cache is None:  # after reset / a batched step: read the numpy state
            st, held = self._state, self._held
            r_hat, omega_hat, sigma_hat = (x[0].ravel().tolist() for x in st)
            l, omega_m = held[0][0].ravel().tolist(), held[1][0].tolist()
        else:
            r_hat, omega_hat, sigma_hat, l, omega_m = cache
        steps = max(1, math.ceil(dt / self.max_step - 1e-9))
        h = dt / steps
        rot = exp_so3_floats(h * omega_m[0], h * omega_m[1], h * omega_m[2]) if steps > 1 else None
        jl, jil, gains = self._jl, self._jil, self.gains
        for k in range(steps):  # time substeps, as update()
            r_hat, omega_hat, sigma_hat = hc_eso_step_single(r_hat, omega_hat, sigma_hat, l, omega_m, tau, jl, jil,
                                                             gains, h)
            if k + 1 < steps:
                l = matmul33_floats(l, rot)
        if not math.isfinite(sum(omega_hat) + sum(sigma_hat)) and not all(map(math.isfinite, omega_hat + sigma_hat)):
            raise ValueError(f"HC-ESO state became non-finite (dt={dt}, max_step={self.max_step}); "
                             "reduce max_step or the gains")
        self._single = (r_hat, omega_hat, sigma_hat, new_l, values[-1])
        s0, s1, s2 = sigma_hat
        j00, j01, j02, j10, j11, j12, j20, j21, j22 = jl
        out = np.fromiter((0.0, 0.0, 0.0, j00 * s0 + j01 * s1 + j02 * s2, j10 * s0 + j11 * s1 + j12 * s2,
                           j20 * s0 + j21 * s1 + j22 * s2, *r_hat, *omega_hat, *sigma_hat), float, 21).reshape(7, 3)
        return ObserverEstimate(force=out[0:1], torque=out[1:2],  # fresh arrays, not views of the float state
                                states={"attitude": out[None, 2:5], "angular_velocity": out[5:6], "sigma": out[6:7]})

    def _sync_single(self) -> None:
        """Write the float state of the last N = 1 fast step back into self._state / self._held."""
        if self._single is not None:
            r_hat, omega_hat, sigma_hat, l, omega_m = self._single
            self._state = (np.array(r_hat).reshape(1, 3, 3), np.array([omega_hat]), np.array([sigma_hat]))
            self._held = (np.array(l).reshape(1, 3, 3), np.array([omega_m]))
            self._single = None

    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        if self._state is None or self._held is None:
            raise ValueError("HcEsoSO3.update called before reset(measurement)")
        if self._fast_path and self._state[0].shape[0] == 1:
            est = self._update_single(measurement, thrust, torque, dt)
            if est is not None:
                return est
        self._sync_single()
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
        if new_omega.shape[0] != n:
            raise ValueError(f"measurement[{self.rate_key!r}] batch size {new_omega.shape[0]} != {n} set at reset")
        self._state = (r_hat, omega_hat, sigma_hat)
        self._held = (new_l, new_omega)
        return ObserverEstimate(force=np.zeros((n, 3)), torque=sigma_hat @ self.inertia.T,
                                states={"attitude": r_hat.copy(), "angular_velocity": omega_hat.copy(),
                                        "sigma": sigma_hat.copy()})
