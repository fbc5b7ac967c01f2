"""Generalized extended state observer (GESO) of order n, exact sampled-data form.

Source: (Shi, Wu, Chou, IEEE Access 2018), Sec. IV.

Per channel and per axis the disturbance ``d`` is modelled as a time polynomial of degree n - 1
(eq. 18), its derivatives ``xi = [d, d', ..., d^(n-1)]`` (eq. 19) are appended to the measured
momentum ``x0``, and with ``x0' = u* + d`` (eq. 20) the augmented system is the integrator chain
(eq. 21)::

    x = [x0, d, d', ..., d^(n-1)],   x' = A x + B u* + B_d d^(n),   y = C x = x0.

The observer (eq. 22) is ``x_hat' = A x_hat + B u* + L (y - C x_hat)`` with
``L = [l_0, ..., l_n]`` chosen by the bandwidth rule (eqs. 34-35)::

    s^(n+1) + l_0 s^n + ... + l_n = (s + w_b)^(n+1)   =>   l_i = C(n+1, i+1) w_b^(i+1)

The disturbance-estimation error obeys ``d_tilde(s) = G(s) d(s)`` (eqs. 33, 36) with
``G(s) = s^n (s + (n+1) w_b) / (s + w_b)^(n+1)``, magnitude eq. 37 and low-frequency asymptote
eq. 38 (functions :func:`error_transfer`, :func:`error_magnitude`, :func:`error_magnitude_lowfreq`).

Two channels of the rigid-body model of :mod:`fawtgym.observers.base` use the same filter:

* rotational (the paper's use): ``x0 = J Omega`` (body FRD), ``u* = tau + J Omega x Omega``
  (the feedback-linearized input of Sec. IV-A), ``d = tau_D`` [N m];
* translational: ``x0 = m v`` (world NED), ``u* = m g e3 - f R e3``, ``d = phi_D`` [N].

Discretization: the observer is a linear time-invariant filter of its two inputs (u*, y).  It is
discretized exactly with the matrix exponential of the augmented system (:func:`scipy.linalg.expm`,
the same matrices as :func:`scipy.signal.cont2discrete`): zero-order hold (``hold="zoh"``: u* and y
held at their values at the start of the step, u* being the applied input averaged over the step) or
first-order hold on y (``hold="foh"``, default: y interpolated linearly between the previous and the
new measurement, u* held).  The
discrete transition matrix is ``expm((A - L C) dt)`` whose eigenvalues are ``exp(-w_b dt)``, so the
filter is stable for every step size, including the env's 50-1000 Hz control rates.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import scipy.linalg
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M
from fawtgym.core.arrays import REAL_KINDS, as_array
from fawtgym.core.checks import check_positive, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.kernel_types import NO_REFCOUNT
from fawtgym.core.rows import write_rows
from fawtgym.core.so3_kernels import cross_row

from ._obs_common import MAX_RATE_GAIN
from .base import BufferStates, Observer, ObserverEstimate, register_observer

#: orders the module supports (eqs. 18-23 for n = 1..4)
ORDERS = (1, 2, 3, 4)
HOLDS = ("zoh", "foh")
CHANNELS = ("force", "torque")
_E3 = np.array([0.0, 0.0, 1.0])
_RATE_NAME = {"force": "velocity", "torque": "angular_velocity"}
_EYE3 = np.eye(3)[None]      # the attitude argument of the torque channel (not read)
_DER_NAME = {"force": "force_derivatives", "torque": "torque_derivatives"}


def _check_order(order: object) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or int(order) not in ORDERS:
        raise ValueError(f"GESO order must be one of {ORDERS}, got {shown(order)}")
    return int(order)


def _check_bandwidth(bandwidth: object) -> float:
    """A real, finite bandwidth in (0, :data:`~fawtgym.observers._obs_common.MAX_RATE_GAIN`] rad/s (bool, complex,
    str refused): the gains l_i = C(n+1, i+1) w_b^(i+1) stay far inside float64 and max_dt = 1 / w_b above 1 us."""
    return check_positive(bandwidth, "GESO bandwidth", maximum=MAX_RATE_GAIN, note="rad/s")


def geso_gains(order: int, bandwidth: float) -> NDArray[np.float64]:
    """Observer gains ``[l_0, ..., l_n]`` of the bandwidth rule, eqs. 34-35: ``l_i = C(n+1, i+1) w_b^(i+1)``.

    ``geso_gains(3, 20)`` is Table 2's GESO-3 row, ``[80, 2400, 32000, 160000]``.
    """
    n = _check_order(order)
    wb = _check_bandwidth(bandwidth)
    return np.array([math.comb(n + 1, i + 1) * wb ** (i + 1) for i in range(n + 1)], dtype=float)


def _check_gains(gains: ArrayLike) -> NDArray[np.float64]:
    l = as_array(gains)
    if l.dtype.kind not in REAL_KINDS:
        raise ValueError(f"GESO gains must be a vector [l_0..l_n] of real numbers, got {shown(gains)} (dtype "
                         f"{l.dtype})")
    l = l.astype(np.float64)
    if l.ndim != 1 or l.size - 1 not in ORDERS:
        raise ValueError(f"GESO gains must be a vector [l_0..l_n] with n in {ORDERS}, got shape {l.shape}")
    if not np.all(np.isfinite(l)):
        raise ValueError(f"GESO gains must be finite, got {l}")
    f = chain_matrices(l.size - 1)[0] - np.outer(l, np.eye(l.size)[0])
    eig = np.linalg.eigvals(f)
    if not np.all(eig.real < 0):
        raise ValueError(f"GESO gains {l} do not make A - L C Hurwitz (eigenvalues {eig}); "
                         "use geso_gains(order, bandwidth) or any Hurwitz characteristic polynomial")
    return l


def chain_matrices(order: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                                       NDArray[np.float64]]:
    """Per-axis matrices ``(A, B, B_d, C)`` of the augmented model, eq. 21 (3-axis: ``kron(., I_3)``).

    ``A`` is the (n+1) x (n+1) integrator chain, ``B = e_0`` (u* drives x0), ``B_d = e_n``
    (d^(n) drives the last state), ``C = e_0^T`` (x0 is measured).
    """
    n = _check_order(order)
    a = np.eye(n + 1, k=1)
    b = np.zeros((n + 1, 1))
    b[0, 0] = 1.0
    bd = np.zeros((n + 1, 1))
    bd[n, 0] = 1.0
    c = np.zeros((1, n + 1))
    c[0, 0] = 1.0
    return a, b, bd, c


def error_transfer(gains: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator (descending powers of s) of ``G(s) = d_tilde / d``, eq. 33.

    ``G(s) = s^n (s + l_0) / (s^(n+1) + l_0 s^n + ... + l_n)``; with the bandwidth gains this is eq. 36.
    """
    l = _check_gains(gains)
    n = l.size - 1
    num = np.zeros(n + 2)
    num[0], num[1] = 1.0, l[0]
    den = np.concatenate([[1.0], l])
    return num, den


def error_magnitude(omega: ArrayLike, order: int, bandwidth: float) -> NDArray[np.float64]:
    """``|G(j w)|`` in closed form, eq. 37.

    ``kappa^n sqrt((kappa^2 + (n+1)^2) / (kappa^2 + 1)^(n+1))`` with ``kappa = w / w_b``.
    """
    n = _check_order(order)
    k = np.asarray(omega, dtype=float) / _check_bandwidth(bandwidth)
    return k**n * np.sqrt((k**2 + (n + 1) ** 2) / (k**2 + 1) ** (n + 1))


def error_magnitude_lowfreq(omega: ArrayLike, order: int, bandwidth: float) -> NDArray[np.float64]:
    """Low-frequency asymptote of eq. 37 for ``w << w_b``, eq. 38: ``(n+1) kappa^n``."""
    n = _check_order(order)
    k = np.asarray(omega, dtype=float) / _check_bandwidth(bandwidth)
    return (n + 1) * k**n


class GesoFilter:
    """The GESO of eq. 22 for ``dim`` independent axes sharing one gain vector, exactly discretized.

    State ``x`` has shape (N, dim, n+1): ``x[..., 0]`` estimates x0, ``x[..., 1]`` the disturbance
    d, ``x[..., 1+i]`` its i-th time derivative.  :meth:`step` advances it by ``dt`` with the inputs
    ``u*`` (held) and ``y`` (held, or linearly interpolated); :meth:`derivative` is the continuous
    right-hand side (for checks).
    """

    def __init__(self, order: int | None = 3, bandwidth: float | None = 20.0,
                 gains: ArrayLike | None = None) -> None:
        if gains is None:
            if bandwidth is None or order is None:
                raise ValueError("GESO needs an order and a bandwidth [rad/s], or an explicit gain vector")
            self.order = _check_order(order)
            self.gains = geso_gains(self.order, bandwidth)
            self.bandwidth: float | None = float(bandwidth)
        else:
            self.gains = _check_gains(gains)
            self.order = self.gains.size - 1
            if order is not None and _check_order(order) != self.order:
                raise ValueError(f"GESO order {shown(order)} does not match the {self.gains.size} gains given "
                                 f"(order = len(gains) - 1 = {self.order})")
            self.bandwidth = None
        a, b, _, c = chain_matrices(self.order)
        #: observer matrix A - L C and input matrix [B, L] for the inputs (u*, y), eq. 22
        self.f = a - np.outer(self.gains, c[0])
        self.g = np.hstack([b, self.gains[:, None]])
        self._cache: dict[tuple[float, str], tuple[NDArray[np.float64], ...]] = {}   # per (dt, hold)
        self._packed: dict[tuple[float, str], NDArray[np.float64]] = {}

    def discretize(self, dt: float, hold: str = "zoh") -> tuple[NDArray[np.float64], ...]:
        """Exact discrete matrices for step ``dt``.

        ``"zoh"``: ``(Phi, Gamma)`` with ``x+ = Phi x + Gamma [u*, y]`` (expm of the augmented system; equal to
        scipy.signal.cont2discrete's zoh, checked in the tests).
        ``"foh"``: ``(Phi, Gamma0, Gamma1)`` with
        ``x+ = Phi x + Gamma0 [u*, y_k] + Gamma1 [0, y_{k+1} - y_k]`` (expm of the augmented system).
        """
        if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite positive number of seconds, got {shown(dt)}")
        if hold not in HOLDS:
            raise ValueError(f"hold must be one of {HOLDS}, got {shown(hold)}")
        key = (float(dt), hold)
        if key not in self._cache:
            m = self.order + 1
            if hold == "zoh":
                # expm([[F, G], [0, 0]] dt) = [[Phi, Gamma], [0, I]] (what scipy.signal.cont2discrete "zoh" computes;
                # done here directly so importing the observers does not import scipy.signal)
                big = np.zeros((m + 2, m + 2))
                big[:m, :m] = self.f * dt
                big[:m, m:] = self.g * dt
                e = scipy.linalg.expm(big)
                self._cache[key] = (e[:m, :m], e[:m, m:])
            else:
                big = np.zeros((m + 4, m + 4))
                big[:m, :m] = self.f * dt
                big[:m, m:m + 2] = self.g * dt
                big[m:m + 2, m + 2:] = np.eye(2)
                e = scipy.linalg.expm(big)
                self._cache[key] = (e[:m, :m], e[:m, m:m + 2], e[:m, m + 2:])
            if not np.all(np.isfinite(np.concatenate([x.ravel() for x in self._cache[key]]))):
                raise ValueError(f"GESO discretization at dt={dt} overflowed (gains {self.gains})")
        return self._cache[key]

    def step_matrix(self, dt: float, hold: str = "zoh") -> NDArray[np.float64]:
        """:meth:`discretize` packed for :func:`geso_filter_row`: ``[Phi | Gamma | Gamma1]``, shape (n+1, n+5)
        (Gamma1 = 0 for ``"zoh"``: y held)."""
        key = (float(dt), hold)
        packed = self._packed.get(key)
        if packed is None:
            mats = self.discretize(dt, hold)
            m = self.order + 1
            packed = np.zeros((m, m + 4))
            packed[:, :m], packed[:, m:m + 2] = mats[0], mats[1]
            if hold == "foh":
                packed[:, m + 2:] = mats[2]
            self._packed[key] = packed
        return packed

    def derivative(self, x: NDArray[np.float64], u_star: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
        """Continuous right-hand side of eq. 22, ``(A - L C) x + B u* + L y``, batch (..., n+1)."""
        uy = np.stack(np.broadcast_arrays(np.asarray(u_star, float), np.asarray(y, float)), axis=-1)
        return x @ self.f.T + uy @ self.g.T

    def step(self, x: NDArray[np.float64], u_star: ArrayLike, y: ArrayLike, dt: float, hold: str = "zoh",
             y_next: ArrayLike | None = None) -> NDArray[np.float64]:
        """Advance ``x`` (..., n+1) by ``dt``; ``u_star`` and ``y`` have shape (...,) (:func:`geso_filter_row`).

        With ``hold="foh"`` ``y_next`` (the measurement at the end of the step) is required.
        """
        packed = self.step_matrix(dt, hold)
        if hold == "foh" and y_next is None:
            raise ValueError("hold='foh' needs y_next, the measurement at the end of the step")
        x = np.asarray(x, dtype=float)
        u_arr, y_arr = np.asarray(u_star, dtype=float), np.asarray(y, dtype=float)
        dy = np.zeros(()) if y_next is None else np.asarray(y_next, dtype=float) - y_arr
        shape = np.broadcast_shapes(x.shape[:-1], u_arr.shape, y_arr.shape, dy.shape)
        m = self.order + 1
        rows = np.ascontiguousarray(np.broadcast_to(x, shape + (m,)).reshape(-1, m))
        flat = [np.ascontiguousarray(np.broadcast_to(a, shape).reshape(-1)) for a in (u_arr, y_arr, dy)]
        out = np.empty_like(rows)
        _geso_filter_rows(rows, flat[0], flat[1], flat[2], packed, out)
        return out.reshape(shape + (m,))


@njit(cache=True, **NO_REFCOUNT)
def geso_filter_row(x: NDArray[np.float64], u: float, y: float, dy: float, mats: NDArray[np.float64],
                    out: NDArray[np.float64]) -> None:
    """One exact sampled-data step of eq. 22 on one axis, m = len(x) = n + 1 states::

        out = Phi x + Gamma [u*, y] + Gamma1 [0, y_next - y]

    ``mats`` = [Phi | Gamma | Gamma1] (m, m + 4) of :meth:`GesoFilter.step_matrix` (Gamma1 = 0: y held)."""
    m = x.shape[0]
    for r in range(m):
        acc = mats[r, m] * u + mats[r, m + 1] * y + mats[r, m + 3] * dy
        for c in range(m):
            acc += mats[r, c] * x[c]
        out[r] = acc


@njit(cache=True)
def _geso_filter_rows(x: NDArray[np.float64], u: NDArray[np.float64], y: NDArray[np.float64],
                      dy: NDArray[np.float64], mats: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    for i in range(x.shape[0]):
        geso_filter_row(x[i], u[i], y[i], dy[i], mats, out[i])


@njit(cache=True, **NO_REFCOUNT)
def geso_signals_row(is_force: bool, mass: float, inertia: NDArray[np.float64], rate: NDArray[np.float64],
                     att: NDArray[np.float64], y: NDArray[np.float64], aux: NDArray[np.float64]) -> None:
    """The channel's measured momentum y and the state-dependent part of u* (Sec. IV-A):

    force channel: y = m v^m (world NED), aux = R^m e3 (u* = m g e3 - f aux);
    torque channel: y = J Omega^m (body FRD), aux = J Omega^m x Omega^m (u* = tau + aux)."""
    if is_force:
        for j in range(3):
            y[j] = mass * rate[j]
            aux[j] = att[j, 2]
    else:
        for j in range(3):
            y[j] = inertia[j, 0] * rate[0] + inertia[j, 1] * rate[1] + inertia[j, 2] * rate[2]
        cross_row(y, rate, aux)


@njit(cache=True)
def geso_signals(is_force: bool, mass: float, inertia: NDArray[np.float64], rate: NDArray[np.float64],
                 att: NDArray[np.float64], y: NDArray[np.float64], aux: NDArray[np.float64]) -> None:
    """:func:`geso_signals_row` of every row (``att`` (N, 3, 3) is read only by the force channel; the torque
    channel may pass one dummy matrix)."""
    for i in range(rate.shape[0]):
        geso_signals_row(is_force, mass, inertia, rate[i], att[i if is_force else 0], y[i], aux[i])


#: layout of the GESO state (N, K, 3, M + 2) per channel slot k and axis: x_hat (M entries, zero-padded beyond
#: the slot's n + 1), then the previous signals y and aux (:func:`geso_signals_row`)
PARAM_NAMES = ("mass", "gravity", "J (9, row-major)", "J^-1 (9, row-major)")


@njit(cache=True, **NO_REFCOUNT)
def geso_step(x: NDArray[np.float64], vel: NDArray[np.float64], att: NDArray[np.float64],
              rate: NDArray[np.float64], thrust: NDArray[np.float64], torque: NDArray[np.float64],
              slots: NDArray[np.int64], foh: bool, params: NDArray[np.float64], mats: NDArray[np.float64],
              x_new: NDArray[np.float64], est: NDArray[np.float64], work: NDArray[np.float64]) -> None:
    """One GESO step of every row and channel slot.

    ``x`` (N, K, 3, M + 2): per slot k (``slots[k]`` = (kind, n_k + 1), kind 0 = force, 1 = torque channel) and
    axis, x_hat (n_k + 1 entries, zero-padded to M = max n_k + 1), then the previous
    signals y, aux.  ``vel`` = v^m, ``att`` = R^m (force channel),
    ``rate`` = Omega^m (torque channel); ``mats`` (K, M, M + 4) the packed step matrices of each slot at this dt
    (:meth:`GesoFilter.step_matrix`); ``params`` as :data:`PARAM_NAMES`.  Writes ``x_new`` and ``est``
    (N, K, M, 3): per slot the disturbance (x_hat[1] of each axis), the rate (v = x0 / m or Omega = J^-1 x0),
    then the derivatives d', ..., d^(n-1) (rows beyond n_k + 1 are padding).  u* is held over the step: the
    applied input with its state-dependent part at the previous signals (zoh) or at the mean of the previous
    and the new (foh).  ``work`` (2, 3) is scratch: the kernel allocates nothing (it and its row laws are
    :data:`~fawtgym.core.kernel_types.NO_REFCOUNT`).
    """
    mass, gravity = params[0], params[1]
    inertia = params[2:11].reshape((3, 3))
    inertia_inv = params[11:20].reshape((3, 3))
    mm = x.shape[3] - 2
    y_new, aux_new = work[0], work[1]
    for i in range(x.shape[0]):
        for k in range(x.shape[1]):
            is_force = slots[k, 0] == 0
            m = slots[k, 1]                                    # the slot's n + 1
            if is_force:
                geso_signals_row(True, mass, inertia, vel[i], att[i], y_new, aux_new)
            else:
                geso_signals_row(False, mass, inertia, rate[i], att[0], y_new, aux_new)
            for j in range(3):
                xs, xo = x[i, k, j], x_new[i, k, j]
                y_old, aux_old = xs[mm], xs[mm + 1]
                a_held = 0.5 * (aux_old + aux_new[j]) if foh else aux_old
                u = (mass * gravity * (1.0 if j == 2 else 0.0) - thrust[i] * a_held) if is_force \
                    else torque[i, j] + a_held
                geso_filter_row(xs[:m], u, y_old, y_new[j] - y_old, mats[k, :m, :m + 4], xo[:m])
                for c in range(m, mm):
                    xo[c] = 0.0
                xo[mm], xo[mm + 1] = y_new[j], aux_new[j]
            slot_estimate_row(x_new[i, k], is_force, mass, inertia_inv, est[i, k])


@njit(cache=True, **NO_REFCOUNT)
def slot_estimate_row(x: NDArray[np.float64], is_force: bool, mass: float, inertia_inv: NDArray[np.float64],
                      est: NDArray[np.float64]) -> None:
    """The estimate (M, 3) of one row's channel slot from its state ``x`` (3, M + 2) (:func:`geso_step`): the
    disturbance x_hat[1] of each axis, the rate (v = x0 / m or Omega = J^-1 x0), then the derivatives."""
    mm = x.shape[1] - 2
    for j in range(3):
        est[0, j] = x[j, 1]
        for c in range(2, mm):
            est[c, j] = x[j, c]          # 0 beyond the slot's n + 1
    for j in range(3):
        if is_force:
            est[1, j] = x[j, 0] / mass
        else:
            est[1, j] = inertia_inv[j, 0] * x[0, 0] + inertia_inv[j, 1] * x[1, 0] + inertia_inv[j, 2] * x[2, 0]


@njit(cache=True)
def geso_estimate(x: NDArray[np.float64], slots: NDArray[np.int64], params: NDArray[np.float64],
                  est: NDArray[np.float64]) -> None:
    """:func:`slot_estimate_row` of every row and slot of the state ``x`` (N, K, 3, M + 2) into ``est`` (N, K, M, 3)."""
    mass = params[0]
    inertia_inv = params[11:20].reshape((3, 3))
    for i in range(x.shape[0]):
        for k in range(x.shape[1]):
            slot_estimate_row(x[i, k], slots[k, 0] == 0, mass, inertia_inv, est[i, k])


def _parse_channels(channels: str | Iterable[str]) -> tuple[str, ...]:
    try:
        items = (channels,) if isinstance(channels, str) else tuple(channels)
    except TypeError:           # not iterable (a number, None)
        items = (channels,)     # type: ignore[assignment]
    bad = [c for c in items if c not in CHANNELS]
    if bad or not items:
        raise ValueError(f"GESO channels must be a non-empty subset of {CHANNELS}, got {shown(channels)}")
    return tuple(c for c in CHANNELS if c in items)


def _per_channel(value: Any, name: str, channels: tuple[str, ...]) -> dict[str, Any]:
    if isinstance(value, Mapping):
        missing = [c for c in channels if c not in value]
        extra = [k for k in value if k not in CHANNELS]
        if missing or extra:
            raise ValueError(f"GESO {name} mapping must have keys {channels} (from {CHANNELS}), "
                             f"got {list(value)}")
        return {c: value[c] for c in channels}
    return {c: value for c in channels}


@register_observer("geso")
class GESO(Observer):
    """GESO of order n (Shi et al. 2018, eqs. 18-23, 34-35) on the force and/or torque channel.

    Options (defaults in brackets): ``order`` in 1..4 [3, the paper's recommendation, Sec. VII],
    ``bandwidth`` w_b [20 rad/s, Table 2]; each may be a number or a mapping
    ``{"force": ..., "torque": ...}``; ``channels`` ["force", "torque"]; ``hold`` "zoh" | "foh"
    ["foh"]; ``rate_key`` which measured rate feeds the torque channel ["angular_velocity"; or
    "gyro"].

    Both holds are exact discretizations of eq. 22; they differ in what is assumed about y between
    samples.  ``"zoh"``: u* and y held at their start-of-step values (classical sampled data; y
    then lags by dt/2).  ``"foh"`` (default): u* held (the applied thrust/torque averaged over the
    step, its state-dependent part at the mean of the two measurements), y linear between the
    previous and the new measurement, which the update receives anyway; at 100-250 Hz this is
    several times more accurate (tests/test_geso_discrete.py).

    ``states``: ``"velocity"`` (N, 3) and ``"force_derivatives"`` (N, n-1, 3) for the force
    channel; ``"angular_velocity"`` (N, 3) and ``"torque_derivatives"`` (N, n-1, 3) for the
    torque channel.
    """

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = GRAVITY, *,
                 order: int | Mapping[str, int] = 3, bandwidth: float | Mapping[str, float] = 20.0,
                 channels: str | Iterable[str] = CHANNELS, hold: str = "foh",
                 rate_key: str = M.ANGULAR_VELOCITY) -> None:
        super().__init__(mass, inertia, gravity)
        chans = _parse_channels(channels)
        if hold not in HOLDS:
            raise ValueError(f"hold must be one of {HOLDS}, got {shown(hold)}")
        if rate_key not in (M.ANGULAR_VELOCITY, M.GYRO):
            raise ValueError(f"rate_key must be {shown(M.ANGULAR_VELOCITY)} or {shown(M.GYRO)}, got {shown(rate_key)}")
        orders = _per_channel(order, "order", chans)
        bws = _per_channel(bandwidth, "bandwidth", chans)
        self.channels = frozenset(chans)  # instance-level: which channels this instance estimates
        self.hold = hold
        self.rate_key = rate_key
        self.filters = {c: GesoFilter(orders[c], bws[c]) for c in chans}
        #: the kernel's channel slots: (kind 0 = force / 1 = torque, n + 1) each, and M = the largest n + 1
        self._slots = np.array([[CHANNELS.index(c), f.order + 1] for c, f in self.filters.items()], dtype=np.int64)
        self._m = int(self._slots[:, 1].max())
        # the estimate buffer (N, K, M, 3) seen as (N, 3 K M): slot k's d_hat at columns 3 k M .. +3, its rate
        # estimate next, then its derivatives (n - 1 of them); the states are views made on first access
        self._wrench_cols = tuple((chan, 3 * k * self._m) for k, chan in enumerate(self.filters))
        self._states_layout: dict[str, tuple[int, int | None, tuple[int, ...]]] = {}
        for k, (chan, filt) in enumerate(self.filters.items()):
            col = 3 * k * self._m
            self._states_layout[_RATE_NAME[chan]] = (col + 3, col + 6, (3,))
            self._states_layout[_DER_NAME[chan]] = (col + 6, col + 3 * (filt.order + 1), (filt.order - 1, 3))
        self._params = np.concatenate([[self.mass, self.gravity], self.inertia.ravel(), self.inertia_inv.ravel()])
        self._mats: dict[float, NDArray[np.float64]] = {}
        self._state: NDArray[np.float64] = np.empty((0, 0))      # (N, k) after reset
        keys: tuple[str, ...] = ((M.VELOCITY, M.ATTITUDE) if "force" in chans else ()) + (
            (rate_key,) if "torque" in chans else ())
        self.required_keys = keys
        #: the exact discretisation is stable at any dt, but the sampled observer tracks a disturbance only below
        #: the Nyquist rate: its bandwidth w_b must satisfy w_b dt < pi; max_dt = 1 / max w_b keeps w_b dt <= 1
        self.max_dt = 1.0 / max(float(f.gains[0]) / (f.order + 1) for f in self.filters.values())

    def _step_matrices(self, dt: float) -> NDArray[np.float64]:
        """The packed step matrices of every slot at ``dt`` (K, M, M + 4), slot k's (n_k + 1, n_k + 5) top left."""
        mats = self._mats.get(dt)
        if mats is None:
            mats = np.zeros((len(self.filters), self._m, self._m + 4))
            for k, filt in enumerate(self.filters.values()):
                packed = filt.step_matrix(dt, self.hold)
                mats[k, :packed.shape[0], :packed.shape[1]] = packed
            self._mats[dt] = mats
        return mats

    def _reset(self, measurement: Mapping[str, NDArray[np.float64]], force: ArrayLike | None,
               torque: ArrayLike | None, rows: NDArray[np.bool_] | None) -> int:
        """Start at x0_hat = y, d_hat = the given guess (default 0), higher derivatives 0.

        State: ``_state`` (N, K, 3, M + 2), per channel slot and axis x_hat (zero-padded to M entries) and the
        previous signals y, aux (:func:`geso_step`).  The per-dt step matrices are constants, not state."""
        meas = M.batch_measurement(measurement)
        n = meas[self.required_keys[0]].shape[0]
        mm = self._m
        fresh = np.zeros((n, len(self.filters), 3, mm + 2))
        for k, chan in enumerate(self.filters):
            is_force = chan == "force"
            rate = np.ascontiguousarray(meas[M.VELOCITY if is_force else self.rate_key])
            y, aux = np.empty_like(rate), np.empty_like(rate)
            geso_signals(is_force, self.mass, self.inertia, rate, meas[M.ATTITUDE] if is_force else _EYE3, y, aux)
            fresh[:, k, :, 0] = y
            fresh[:, k, :, mm] = y
            fresh[:, k, :, mm + 1] = aux
            guess = force if is_force else torque
            if guess is not None:
                g = np.asarray(guess, dtype=float)
                if g.shape[-1:] != (3,) or not np.all(np.isfinite(g)):
                    raise ValueError(f"initial {chan} guess must be finite with shape (3,) or (N, 3), "
                                     f"got {g.shape}")
                fresh[:, k, :, 1] = np.broadcast_to(g, (n, 3))
        self._state = write_rows(self._state, fresh, rows)
        return n

    def _update(self, meas: dict[str, NDArray[np.float64]], f: NDArray[np.float64], tau: NDArray[np.float64],
                dt: float) -> tuple[ObserverEstimate, NDArray[np.float64]]:
        x = self._state
        n = x.shape[0]
        mats = self._mats.get(dt)
        if mats is None:
            mats = self._step_matrices(dt)
        # a channel's absent input is never read: the other channel's array stands in for it
        vel = meas[M.VELOCITY] if M.VELOCITY in meas else meas[self.rate_key]
        rate = meas[self.rate_key] if self.rate_key in meas else vel
        x_new = np.empty(x.shape)
        est = np.empty((n, x.shape[1], self._m, 3))
        geso_step(x, vel, meas.get(M.ATTITUDE, _EYE3), rate, f, tau, self._slots, self.hold == "foh", self._params,
                  mats, x_new, est, np.empty((2, 3)))
        return self._estimate_of(est), x_new

    def _estimate_of(self, est: NDArray[np.float64]) -> ObserverEstimate:
        """The estimate as views of the kernels' buffer ``est`` (N, K, M, 3) (zeros for a channel not estimated)."""
        n = est.shape[0]
        flat = est.reshape(n, -1)
        out = {chan: flat[:, col:col + 3] for chan, col in self._wrench_cols}
        if len(out) == 1:                                     # the channel this instance does not estimate
            out["torque" if "force" in out else "force"] = np.zeros((n, 3))
        return ObserverEstimate(force=out["force"], torque=out["torque"],
                                states=BufferStates(flat, self._states_layout))

    def estimate(self) -> ObserverEstimate:
        """The current estimate (after reset/update): the one the last update returned, from the stored state."""
        if self._n_rows is None:
            raise RuntimeError("geso: estimate() before reset(); call reset(measurement) first")
        x = self._state
        est = np.empty((x.shape[0], x.shape[1], self._m, 3))
        geso_estimate(x, self._slots, self._params, est)
        return self._estimate_of(est)
