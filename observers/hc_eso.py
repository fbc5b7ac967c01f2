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

Each law is one row function (numba): :func:`hc_eso_rates_row` (eq. 30's P and Q), :func:`hc_eso_step_row` (one
Lie-Euler step); :func:`hc_eso_rates`, :func:`hc_eso_step` and the observer's update loop them over the rows.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M
from fawtgym.core.checks import check_number, check_positive, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.kernel_types import NO_REFCOUNT
from fawtgym.core.rows import write_rows
from fawtgym.core.so3_kernels import exp_so3_row, known_angular_acceleration_entries, mat_copy_row, mat_mul_row

from . import vector_attitude as va
from ._obs_common import MAX_RATE_GAIN, real_vector
from .base import BufferStates, Observer, ObserverEstimate, register_observer
from .vector_attitude import _S2_FLOOR, imu_body_vectors_row

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
        is_number = isinstance(self.gamma, number) and not isinstance(self.gamma, (bool, np.bool_))
        try:
            g = float(self.gamma) if is_number else math.nan
        except OverflowError:   # an int beyond float range
            g = math.inf
        if not (math.isfinite(g) and g.is_integer() and g >= 1):
            raise ValueError(f"hc_eso: gamma must be a positive integer (Prop. 3), finite as a float, got "
                             f"{shown(self.gamma)}")
        if isinstance(self.alpha, bool) or not isinstance(self.alpha, number) or not (0.5 < self.alpha < 1.0):
            raise ValueError(f"alpha must satisfy 1/2 < alpha < 1 (Prop. 3), got {shown(self.alpha)}")
        if self.gamma - 3.0 * self.alpha + 1.0 < 0:
            raise ValueError(f"gamma - 3 alpha + 1 must be >= 0 (Prop. 3), got gamma={self.gamma}, "
                             f"alpha={self.alpha}")
        for name in ("kappa", "k_sigma", "k_psi"):
            check_positive(getattr(self, name), f"hc_eso: gain {name}", maximum=MAX_RATE_GAIN)

    @functools.cached_property
    def constants(self) -> NDArray[np.float64]:
        """The constants ``c`` of the row kernels: ((alpha-1)/gamma, 2 (1-alpha)/gamma, (alpha-1)/2, alpha-1, kappa,
        k_Psi, k_sigma)."""
        a, g = float(self.alpha), float(self.gamma)
        return np.array([(a - 1.0) / g, 2.0 * (1.0 - a) / g, (a - 1.0) / 2.0, a - 1.0, float(self.kappa),
                         float(self.k_psi), float(self.k_sigma)])


# --------------------------------------------------------------------------------------------------
# row functions
# --------------------------------------------------------------------------------------------------
@njit(cache=True, **NO_REFCOUNT)
def hc_eso_rates_row(r_hat, w, sigma_hat, l, o, tau, J, J_inv, c, p, q, psi, s):
    """P and Q of eq. 30 for one row into ``p``, ``q`` (3,), with Psi (eq. 29) and s_L (eq. 22) into ``psi``, ``s``.

    ``r_hat``, ``l`` (3, 3); ``w`` = Omega_hat, ``sigma_hat``, ``o`` = Omega^m, ``tau`` (3,); ``c`` =
    :attr:`HcEsoGains.constants`.  With A = L^T R_hat:

    * s_L = vex(A - A^T) (eq. 22), i.e. (A21 - A12, A02 - A20, A10 - A01);
    * w_L = (tr(A) I - A^T) Omega_hat - (tr(A) I - A) Omega^m (eq. 27: vex(A W + W A^T) = (tr(A) I - A^T) w for
      W = w^x);
    * z_L = (s_L^T s_L)^((alpha-1)/gamma) s_L (eq. 26), Psi = Omega^m - Omega_hat - kappa z_L (eqs. 17, 29);
    * H(s_L) w_L = w_L - 2 (1-alpha)/gamma (s_L^T w_L) / (s_L^T s_L) s_L (eq. 28).

    s^T s and Psi^T Psi are floored at :data:`vector_attitude._S2_FLOOR` (the Hölder terms are continuous at 0)."""
    e_z, c_h, e_psi, e_sig, kappa, k_psi, k_sig = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    a00 = l[0, 0] * r_hat[0, 0] + l[1, 0] * r_hat[1, 0] + l[2, 0] * r_hat[2, 0]  # A = L^T R_hat
    a01 = l[0, 0] * r_hat[0, 1] + l[1, 0] * r_hat[1, 1] + l[2, 0] * r_hat[2, 1]
    a02 = l[0, 0] * r_hat[0, 2] + l[1, 0] * r_hat[1, 2] + l[2, 0] * r_hat[2, 2]
    a10 = l[0, 1] * r_hat[0, 0] + l[1, 1] * r_hat[1, 0] + l[2, 1] * r_hat[2, 0]
    a11 = l[0, 1] * r_hat[0, 1] + l[1, 1] * r_hat[1, 1] + l[2, 1] * r_hat[2, 1]
    a12 = l[0, 1] * r_hat[0, 2] + l[1, 1] * r_hat[1, 2] + l[2, 1] * r_hat[2, 2]
    a20 = l[0, 2] * r_hat[0, 0] + l[1, 2] * r_hat[1, 0] + l[2, 2] * r_hat[2, 0]
    a21 = l[0, 2] * r_hat[0, 1] + l[1, 2] * r_hat[1, 1] + l[2, 2] * r_hat[2, 1]
    a22 = l[0, 2] * r_hat[0, 2] + l[1, 2] * r_hat[1, 2] + l[2, 2] * r_hat[2, 2]
    s0, s1, s2 = a21 - a12, a02 - a20, a10 - a01  # s_L, eq. 22
    w0, w1, w2 = w[0], w[1], w[2]
    o0, o1, o2 = o[0], o[1], o[2]
    t12, t02, t01 = a11 + a22, a00 + a22, a00 + a11
    wl0 = (t12 * w0 - a10 * w1 - a20 * w2) - (t12 * o0 - a01 * o1 - a02 * o2)  # w_L, eq. 27
    wl1 = (t02 * w1 - a01 * w0 - a21 * w2) - (t02 * o1 - a10 * o0 - a12 * o2)
    wl2 = (t01 * w2 - a02 * w0 - a12 * w1) - (t01 * o2 - a20 * o0 - a21 * o1)
    ss = max(s0 * s0 + s1 * s1 + s2 * s2, _S2_FLOOR)
    kz = kappa * ss**e_z  # kappa (s^T s)^((alpha-1)/gamma), eqs. 26, 30
    p0, p1, p2 = (o0 - w0) - kz * s0, (o1 - w1) - kz * s1, (o2 - w2) - kz * s2  # Psi, eq. 29
    pp = max(p0 * p0 + p1 * p1 + p2 * p2, _S2_FLOOR)
    hc = c_h * (s0 * wl0 + s1 * wl1 + s2 * wl2) / ss  # H(s_L) w_L, eq. 28
    hw0, hw1, hw2 = wl0 - hc * s0, wl1 - hc * s1, wl2 - hc * s2
    # J^-1 (J Omega^m x Omega^m + tau), the known part of Omega' (Wang et al. 2024 eq. 38)
    k0, k1, k2 = known_angular_acceleration_entries(J, J_inv, o0, o1, o2, tau[0], tau[1], tau[2])
    kp = k_psi * pp**e_psi
    p[0] = k0 + sigma_hat[0] + kp * p0 - kz * hw0  # P, eq. 30
    p[1] = k1 + sigma_hat[1] + kp * p1 - kz * hw1
    p[2] = k2 + sigma_hat[2] + kp * p2 - kz * hw2
    ks = k_sig * pp**e_sig  # Q of eq. 30 is ks Psi
    q[0], q[1], q[2] = ks * p0, ks * p1, ks * p2
    psi[0], psi[1], psi[2] = p0, p1, p2
    s[0], s[1], s[2] = s0, s1, s2


@njit(cache=True, **NO_REFCOUNT)
def hc_eso_step_row(r_hat, w, sigma_hat, l, o, tau, J, J_inv, c, h, scratch):
    """One Lie-Euler step of eq. 30 of size h of one row, in place: R_hat <- R_hat exp(h Omega_hat^x),
    Omega_hat <- Omega_hat + h P, sigma_hat <- sigma_hat + h Q (P, Q at the start of the step).
    ``scratch``: (6, 3, 3) work space (rows 0-3)."""
    p, q, psi, s = scratch[0, 0], scratch[0, 1], scratch[0, 2], scratch[1, 0]
    hc_eso_rates_row(r_hat, w, sigma_hat, l, o, tau, J, J_inv, c, p, q, psi, s)
    h_w = scratch[1, 1]
    for k in range(3):
        h_w[k] = h * w[k]
    exp_so3_row(h_w, scratch[2])
    mat_copy_row(r_hat, scratch[3])
    mat_mul_row(scratch[3], scratch[2], r_hat)
    for k in range(3):
        w[k] += h * p[k]
        sigma_hat[k] += h * q[k]


@njit(cache=True, **NO_REFCOUNT)
def gain_matrix_row(use_attitude, sf, mag, att, E, EW, U, L):
    """L = (E W) (U^m)^T (Lemma 2) of one row into ``L``, U^m into ``U`` (3, 3): from the measured attitude
    (U^m = (R^m)^T E) or from the IMU (:func:`vector_attitude.imu_body_vectors_row`).  Returns that function's
    status (0: usable)."""
    if use_attitude:
        for i in range(3):
            for j in range(3):
                U[i, j] = att[0, i] * E[0, j] + att[1, i] * E[1, j] + att[2, i] * E[2, j]
        code = 0
    else:
        code = imu_body_vectors_row(sf, mag, U)
        if code:
            return code
    for i in range(3):
        for j in range(3):
            L[i, j] = EW[i, 0] * U[j, 0] + EW[i, 1] * U[j, 1] + EW[i, 2] * U[j, 2]
    return code


@njit(cache=True)
def _rates_rows(r_hat, w, sigma_hat, l, o, tau, J, J_inv, c, p, q, psi, s):
    for i in range(r_hat.shape[0]):
        hc_eso_rates_row(r_hat[i], w[i], sigma_hat[i], l[i], o[i], tau[i], J, J_inv, c, p[i], q[i], psi[i], s[i])


@njit(cache=True)
def _step_rows(r_hat, w, sigma_hat, l, o, tau, J, J_inv, c, h):
    scratch = np.empty((6, 3, 3))
    for i in range(r_hat.shape[0]):
        hc_eso_step_row(r_hat[i], w[i], sigma_hat[i], l[i], o[i], tau[i], J, J_inv, c, h, scratch)


@njit(cache=True, **NO_REFCOUNT)
def _update_rows(r_hat, w, sigma_hat, l, o, tau, use_attitude, sf, mag, att, rate, J, J_inv, E, EW, c, h, steps,
                 out, l_new, o_new, scratch):
    """One observer update of every row from the state (``r_hat``, ``w``, ``sigma_hat``) and the held L, Omega^m
    (``l``, ``o``), none of them written: ``steps`` Lie-Euler substeps of size h, the held L propagated by
    exp(h (Omega^m)^x) between them, into ``out`` (N, 21): force (0) | torque J sigma_hat | R_hat (9) | Omega_hat |
    sigma_hat; then the new measurement's L and rate into ``l_new``, ``o_new`` (the held sample of the next
    update).

    Returns (status, row): (0, -1) done, or (k, i): the IMU vectors of row i are unusable
    (:func:`vector_attitude.imu_body_vectors_row` code k).  The inputs are checked finite by
    :meth:`Observer.update`; a non-finite new state is caught there from the estimate.

    ``scratch`` (7, 3, 3) is work space: the kernel allocates nothing (it and its row laws are
    :data:`~fawtgym.core.kernel_types.NO_REFCOUNT`)."""
    n = r_hat.shape[0]
    li, o_i, h_o = scratch[4], scratch[6, 0], scratch[6, 1]
    for i in range(n):
        row = out[i]
        r_new, w_new, sigma_new, tau_hat = row[6:15].reshape(3, 3), row[15:18], row[18:21], row[3:6]
        for j in range(3):
            w_new[j] = w[i, j]
            sigma_new[j] = sigma_hat[i, j]
            o_i[j] = o[i, j]
            for k in range(3):
                r_new[j, k] = r_hat[i, j, k]
                li[j, k] = l[i, j, k]
        if steps > 1:
            for j in range(3):
                h_o[j] = h * o_i[j]
            exp_so3_row(h_o, scratch[5])
        for k in range(steps):  # time substeps
            hc_eso_step_row(r_new, w_new, sigma_new, li, o_i, tau[i], J, J_inv, c, h, scratch)
            if k + 1 < steps:  # the held vectors for the next substep (after the last one, new ones come)
                mat_copy_row(li, scratch[3])
                mat_mul_row(scratch[3], scratch[5], li)
        code = gain_matrix_row(use_attitude, sf[i], mag[i], att[i], E, EW, scratch[3], l_new[i])
        if code:
            return code, i
        for j in range(3):
            o_new[i, j] = rate[i, j]
        _wrench_row(sigma_new, J, row[0:3], tau_hat)
    return 0, -1


@njit(cache=True, **NO_REFCOUNT)
def _wrench_row(sigma_hat, J, force, torque):
    """The estimated wrench of one row: force 0 (HC-ESO estimates the torque only), torque J sigma_hat."""
    for k in range(3):
        force[k] = 0.0
        torque[k] = J[k, 0] * sigma_hat[0] + J[k, 1] * sigma_hat[1] + J[k, 2] * sigma_hat[2]


@njit(cache=True)
def _estimate_rows(r_hat, w, sigma_hat, J, out):
    """The estimate of the state of every row into ``out`` (N, 21), the layout of :func:`_update_rows`."""
    for i in range(r_hat.shape[0]):
        row = out[i]
        row[6:15].reshape(3, 3)[:, :] = r_hat[i]
        row[15:18] = w[i]
        row[18:21] = sigma_hat[i]
        _wrench_row(sigma_hat[i], J, row[0:3], row[3:6])


def _rows3(x: ArrayLike, n: int, trailing: tuple[int, ...]) -> NDArray[np.float64]:
    """x as C-contiguous float rows (n, *trailing) (broadcast from one row)."""
    a = np.asarray(x, dtype=float)
    if a.shape != (n,) + trailing:
        a = np.broadcast_to(a, (n,) + trailing)
    return np.ascontiguousarray(a)


def hc_eso_rates(r_hat: ArrayLike, omega_hat: ArrayLike, sigma_hat: ArrayLike, l: ArrayLike, omega_m: ArrayLike,
                 tau: ArrayLike, inertia: ArrayLike, gains: HcEsoGains,
                 inertia_inv: ArrayLike | None = None) -> tuple[NDArray[np.float64], ...]:
    """Right-hand sides ``(P, Q)`` of the Omega_hat and sigma_hat equations of eq. 30, plus ``(Psi, s_L)``
    (:func:`hc_eso_rates_row` over the rows).  Shapes: r_hat, l (N, 3, 3); omega_hat, sigma_hat, omega_m, tau
    (N, 3)."""
    r = np.asarray(r_hat, dtype=float)
    n = r.shape[0]
    J = np.ascontiguousarray(inertia, dtype=float)
    J_inv = np.linalg.inv(J) if inertia_inv is None else np.ascontiguousarray(inertia_inv, dtype=float)
    out = np.empty((4, n, 3))
    _rates_rows(_rows3(r, n, (3, 3)), _rows3(omega_hat, n, (3,)), _rows3(sigma_hat, n, (3,)), _rows3(l, n, (3, 3)),
                _rows3(omega_m, n, (3,)), _rows3(tau, n, (3,)), J, J_inv, gains.constants, out[0], out[1], out[2],
                out[3])
    return out[0], out[1], out[2], out[3]


def hc_eso_step(r_hat: ArrayLike, omega_hat: ArrayLike, sigma_hat: ArrayLike, l: ArrayLike, omega_m: ArrayLike,
                tau: ArrayLike, inertia: ArrayLike, gains: HcEsoGains, h: float,
                inertia_inv: ArrayLike | None = None) -> tuple[NDArray[np.float64], ...]:
    """One geometric (Lie-Euler) step of eq. 30 of size h (:func:`hc_eso_step_row` over the rows); returns new
    (R_hat, Omega_hat, sigma_hat)."""
    r = np.array(r_hat, dtype=float)
    n = r.shape[0]
    r = _rows3(r, n, (3, 3)).copy()
    w, s = _rows3(omega_hat, n, (3,)).copy(), _rows3(sigma_hat, n, (3,)).copy()
    J = np.ascontiguousarray(inertia, dtype=float)
    J_inv = np.linalg.inv(J) if inertia_inv is None else np.ascontiguousarray(inertia_inv, dtype=float)
    _step_rows(r, w, s, _rows3(l, n, (3, 3)), _rows3(omega_m, n, (3,)), _rows3(tau, n, (3,)), J, J_inv,
               gains.constants, float(h))
    return r, w, s


VECTOR_SOURCES = ("imu", "attitude")
#: an update integrates ceil(dt / max_step) substeps; more than this is refused
MAX_SUBSTEPS = 100


#: the estimate's states: columns of the estimate buffer (N, 21) and trailing shapes
_STATES = {"attitude": (6, 15, (3, 3)), "angular_velocity": (15, 18, (3,)), "sigma": (18, 21, (3,))}


@register_observer("hc_eso")
class HcEsoSO3(Observer):
    """HC-ESO on SO(3) (Wang and Sanyal 2022, eq. 30) estimating the body disturbance torque ``J sigma_hat``.

    Options (defaults in brackets): ``alpha`` [0.85], ``gamma`` [2], ``kappa`` [0.15],
    ``k_sigma`` [5], ``k_psi`` [5] (all Sec. 6); ``morse_gains`` K [(3, 2, 1), not stated in the
    paper]; ``vectors``: ``"imu"`` [default: gravity from the accelerometer, Earth field from the
    magnetometer, their cross product, :func:`vector_attitude.imu_vector_set`] or ``"attitude"``
    (the body images of the NED axes from the measured attitude, ``U^m = (R^m)^T I``);
    ``rate_key`` ["angular_velocity" or "gyro"]; ``max_step`` [0.005 s]: each update integrates
    ``ceil(dt / max_step)`` Lie-Euler steps (at most :data:`MAX_SUBSTEPS`).  Measurements are held over the update
    interval (the previous update's vectors, propagated with the previous rate).

    ``states``: ``"attitude"`` R_hat (N, 3, 3), ``"angular_velocity"`` Omega_hat (N, 3),
    ``"sigma"`` sigma_hat = J^-1 tau_hat (N, 3).
    """

    channels = frozenset({"torque"})
    #: the update holds the measured vectors and rate over dt (the vectors propagated with the held rate), so the
    #: estimate lags the sample by up to dt: the paper's simulation samples at 100 Hz (Sec. 6, h = 0.01 s); 0.1 s
    #: is 10 of its samples and 20 substeps, at which a constant torque is still recovered to 2e-8 N m (the
    #: synthetic run of tests/test_hc_eso_observer.py, 6 s)
    max_dt = 0.1

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = GRAVITY, *, alpha: float = 0.85,
                 gamma: int = 2, kappa: float = 0.15, k_sigma: float = 5.0, k_psi: float = 5.0,
                 morse_gains: ArrayLike = DEFAULT_MORSE_GAINS, vectors: str = "imu",
                 rate_key: str = M.ANGULAR_VELOCITY, max_step: float = 0.005,
                 field_ned: ArrayLike = M.EARTH_FIELD_NED) -> None:
        super().__init__(mass, inertia, gravity)
        self.gains = HcEsoGains(alpha, gamma, kappa, k_sigma, k_psi)
        self.morse_gains = va.check_morse_gains(morse_gains)
        if vectors not in VECTOR_SOURCES:
            raise ValueError(f"vectors must be one of {VECTOR_SOURCES}, got {shown(vectors)}")
        if rate_key not in (M.ANGULAR_VELOCITY, M.GYRO):
            raise ValueError(f"rate_key must be {shown(M.ANGULAR_VELOCITY)} or {shown(M.GYRO)}, got {shown(rate_key)}")
        max_step = check_number(max_step, "hc_eso: max_step", minimum=self.max_dt / MAX_SUBSTEPS,
                                inclusive_minimum=True, note=f"s (>= max_dt / {MAX_SUBSTEPS})")
        self.vectors, self.rate_key, self.max_step = vectors, rate_key, max_step
        field = real_vector(field_ned, 3)
        if field is None:
            raise ValueError(f"hc_eso: field_ned must be 3 finite real numbers (the Earth field, NED), got "
                             f"{shown(field_ned)}")
        self.field_ned = field
        self._e = np.eye(3) if vectors == "attitude" else va.imu_inertial_vectors(self.field_ned)
        self._w = va.wahba_weight(self._e, self.morse_gains)
        self._ew = np.ascontiguousarray(self._e @ self._w)
        self._c = self.gains.constants
        self._J = np.ascontiguousarray(self.inertia)
        self._J_inv = np.ascontiguousarray(self.inertia_inv)
        self.required_keys = (((M.ATTITUDE,) if vectors == "attitude" else (M.SPECIFIC_FORCE, M.MAGNETOMETER))
                              + (rate_key,))
        #: state: R_hat (N, 3, 3), Omega_hat (N, 3), sigma_hat (N, 3); held: L (N, 3, 3), Omega^m (N, 3)
        self._r_hat: NDArray[np.float64] = np.empty((0, 3, 3))
        self._w_hat: NDArray[np.float64] = np.empty((0, 3))
        self._sigma: NDArray[np.float64] = np.empty((0, 3))
        self._l: NDArray[np.float64] = np.empty((0, 3, 3))
        self._o: NDArray[np.float64] = np.empty((0, 3))
        self._blank = (np.zeros((0, 3)), np.zeros((0, 3, 3)))

    def _measured(self, meas: Mapping[str, NDArray[np.float64]]) -> tuple[NDArray[np.float64], ...]:
        """(specific force, magnetometer, attitude, rate): the measurement rows the kernels read, C-contiguous (the
        unused ones as zero placeholders); :meth:`Observer.update` / :meth:`Observer.reset` checked them (present, N
        rows, finite, the attitude a rotation)."""
        rate = np.ascontiguousarray(meas[self.rate_key])
        n = rate.shape[0]
        if self._blank[0].shape[0] != n:  # placeholders of the keys this observer does not read (never written)
            self._blank = (np.zeros((n, 3)), np.zeros((n, 3, 3)))
        if self.vectors == "attitude":
            return self._blank[0], self._blank[0], np.ascontiguousarray(meas[M.ATTITUDE]), rate
        return (np.ascontiguousarray(meas[M.SPECIFIC_FORCE]), np.ascontiguousarray(meas[M.MAGNETOMETER]),
                self._blank[1], rate)

    def _gain_matrices(self, sf: NDArray[np.float64], mag: NDArray[np.float64], att: NDArray[np.float64],
                       rate: NDArray[np.float64]) -> NDArray[np.float64]:
        """L (N, 3, 3) of the measurement, through the observer's update kernel with no substep; raises the update's
        errors."""
        n = rate.shape[0]
        l_new, z3, z33 = np.empty((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3))
        code, row = _update_rows(z33, z3, z3, z33, z3, z3, self.vectors == "attitude", sf, mag, att, rate, self._J,
                                 self._J_inv, self._e, self._ew, self._c, 0.0, 0, np.empty((n, 21)), l_new,
                                 np.empty((n, 3)), np.empty((7, 3, 3)))
        self._raise(code, row)
        return l_new

    def _raise(self, code: int, row: int) -> None:
        if code:
            raise ValueError(f"hc_eso: row {row}: {va.IMU_VECTOR_ERRORS[code - 1]}")

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None, **options: Any) -> int:
        """R_hat from the static Wahba solution of the vectors, Omega_hat = Omega^m, sigma_hat = J^-1 torque guess.

        State: R_hat (N, 3, 3), Omega_hat (N, 3), sigma_hat (N, 3) and the held L (N, 3, 3), Omega^m (N, 3)."""
        sf, mag, att, rate = self._measured(M.batch_measurement(measurement))
        l = self._gain_matrices(sf, mag, att, rate)
        n = rate.shape[0]
        sigma = np.zeros((n, 3))
        if torque is not None:
            t = np.asarray(torque, dtype=float)
            if t.shape[-1:] != (3,) or not np.all(np.isfinite(t)):
                raise ValueError(f"initial torque guess must be finite with shape (3,) or (N, 3), got {t.shape}")
            sigma = np.ascontiguousarray(np.broadcast_to(t @ self.inertia_inv.T, (n, 3)))
        fresh = (np.ascontiguousarray(va.solve_wahba(l)), rate.copy(), sigma, l, rate.copy())
        (self._r_hat, self._w_hat, self._sigma, self._l, self._o) = write_rows(
            (self._r_hat, self._w_hat, self._sigma, self._l, self._o), fresh, rows)
        return n

    def _update(self, meas: dict[str, NDArray[np.float64]], thrust: NDArray[np.float64],
                torque: NDArray[np.float64], dt: float) -> tuple[ObserverEstimate, Any]:
        """``ceil(dt / max_step)`` Lie-Euler substeps of eq. 30 with the held L and Omega^m, then the new measurement
        becomes the held one (:func:`_update_rows`); the new state is stored by :meth:`_commit`."""
        n = self._r_hat.shape[0]
        sf, mag, att, rate = self._measured(meas)
        steps = max(1, math.ceil(dt / self.max_step - 1e-9))
        out, l_new, o_new = np.empty((n, 21)), np.empty((n, 3, 3)), np.empty((n, 3))
        code, row = _update_rows(self._r_hat, self._w_hat, self._sigma, self._l, self._o,
                                 np.ascontiguousarray(torque), self.vectors == "attitude", sf, mag, att, rate, self._J,
                                 self._J_inv, self._e, self._ew, self._c, dt / steps, steps, out, l_new, o_new,
                                 np.empty((7, 3, 3)))
        self._raise(code, row)
        # the estimate: views of one buffer, which are also the new state (no update writes into a stored state)
        r_hat, w_hat, sigma = out[:, 6:15].reshape(n, 3, 3), out[:, 15:18], out[:, 18:21]
        states = BufferStates(out, _STATES, {"attitude": r_hat, "angular_velocity": w_hat, "sigma": sigma})
        est = ObserverEstimate(force=out[:, 0:3], torque=out[:, 3:6], states=states)
        return est, (r_hat, w_hat, sigma, l_new, o_new)

    def _commit(self, state: Any) -> None:
        self._r_hat, self._w_hat, self._sigma, self._l, self._o = state

    def snapshot(self) -> Any:
        return self._r_hat, self._w_hat, self._sigma, self._l, self._o

    def estimate(self) -> ObserverEstimate:
        """The current estimate (after reset/update): the one the last update returned, from the stored state."""
        if self._n_rows is None:
            raise RuntimeError("hc_eso: estimate() before reset(); call reset(measurement) first")
        out = np.empty((self._r_hat.shape[0], 21))
        _estimate_rows(self._r_hat, self._w_hat, self._sigma, self._J, out)
        return ObserverEstimate(force=out[:, 0:3], torque=out[:, 3:6], states=BufferStates(out, _STATES))
