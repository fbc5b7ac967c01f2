"""The low-pass filters of PX4's control pipeline: compiled row laws and batch-first classes around them.

* :class:`Butterworth2` -- PX4's ``LowPassFilter2p``: a 2nd-order Butterworth biquad designed by the
  bilinear transform with pre-warping at the cut-off.  Used on the gyro (``IMU_GYRO_CUTOFF``) before the
  rate loop and on the angular acceleration for the rate D term (``IMU_DGYRO_CUTOFF``), as in PX4's
  ``VehicleAngularVelocity``.  The coefficients come from :func:`scipy.signal.butter`.
* :class:`FirstOrderLowPass` -- PX4's ``BlockLowPass``: ``y += a (u - y)`` with ``a = b / (1 + b)``,
  ``b = 2 pi f_c dt``.
* :class:`FilteredDerivative` -- PX4's ``BlockDerivative``: first-order low-pass of the backward
  difference; mc_pos_control (v1.13) uses it with ``MPC_VELD_LP`` (5 Hz) for the velocity derivative of
  the velocity D term.

Each law is written once, as a row function compiled by numba (:func:`butterworth_row`,
:func:`lowpass_row`, :func:`filtered_derivative_row`) that the PX4 cascade kernel
(:mod:`fawtgym.agents.px4_cascade`) calls per vehicle and the classes below call through small batch
kernels.  The classes hold arrays with a leading row axis (one row per vehicle) and any trailing shape;
``reset(x)`` sets the steady state at ``x``, ``reset(x, rows=mask)`` only for the rows of ``mask``
(rows of a batched env end at different times); ``dt`` may be one per row (loops whose rows run at
different phases).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from fawtgym.core.checks import shown
from fawtgym.core.rows import check_dt, masked

#: layout of a biquad's coefficient vector (``a0`` normalized to 1); ``ENABLED`` 0 makes it a pass-through
B0, B1, B2, A1, A2, ENABLED = 0, 1, 2, 3, 4, 5
N_BIQUAD = 6


def _check_rates(sample_rate: float, cutoff: float) -> None:
    if not (math.isfinite(sample_rate) and sample_rate > 0):
        raise ValueError(f"sample_rate must be a finite positive frequency [Hz], got {shown(sample_rate)}")
    if not (math.isfinite(cutoff) and cutoff >= 0):
        raise ValueError(f"cutoff must be a finite frequency >= 0 [Hz] (0 disables the filter), got {shown(cutoff)}")


def butterworth_coefficients(sample_rate: float, cutoff: float) -> NDArray[np.float64]:
    """The coefficient vector (b0, b1, b2, a1, a2, enabled) of PX4's ``LowPassFilter2p``.

    A cut-off of 0 or at/above 0.5 x the sample rate (no valid design) gives a pass-through, as PX4.
    """
    _check_rates(sample_rate, cutoff)
    coef = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    if 0.0 < cutoff < 0.5 * sample_rate * 0.999:
        b, a = signal.butter(2, cutoff, btype="low", fs=sample_rate)
        coef[:] = (b[0] / a[0], b[1] / a[0], b[2] / a[0], a[1] / a[0], a[2] / a[0], 1.0)
    return coef


@njit(cache=True, inline="always")
def butterworth_reset_row(x: np.ndarray, z: np.ndarray, coef: np.ndarray) -> None:
    """Steady state of the direct-form-II-transposed biquad at the constant input ``x`` (k,) (DC gain 1: y = x).

    ``z`` (2k,) holds the two delay registers (z1 then z2) of every component.
    """
    k = x.shape[0]
    for j in range(k):
        z2 = (coef[B2] - coef[A2]) * x[j]
        z[k + j] = z2
        z[j] = (coef[B1] - coef[A1]) * x[j] + z2


@njit(cache=True, inline="always")
def butterworth_row(x: np.ndarray, z: np.ndarray, coef: np.ndarray, y: np.ndarray) -> None:
    """One sample ``x`` (k,) through the biquad (DF-II transposed) into ``y`` (k,); ``y`` may alias nothing."""
    k = x.shape[0]
    if coef[ENABLED] == 0.0:
        for j in range(k):
            y[j] = x[j]
        return
    for j in range(k):
        out = coef[B0] * x[j] + z[j]
        z[j] = coef[B1] * x[j] - coef[A1] * out + z[k + j]
        z[k + j] = coef[B2] * x[j] - coef[A2] * out
        y[j] = out


@njit(cache=True, inline="always")
def lowpass_alpha(cutoff: float, dt: float) -> float:
    """PX4 ``BlockLowPass`` weight ``a = b / (1 + b)``, ``b = 2 pi f_c dt`` (1 for f_c = 0: a pass-through)."""
    if cutoff == 0.0:
        return 1.0
    b = 2.0 * math.pi * cutoff * dt
    return b / (1.0 + b)


@njit(cache=True, inline="always")
def lowpass_row(u: np.ndarray, state: np.ndarray, alpha: float) -> None:
    """``state <- alpha u + (1 - alpha) state`` (k,), PX4 ``BlockLowPass::update``."""
    for j in range(u.shape[0]):
        state[j] = alpha * u[j] + (1.0 - alpha) * state[j]


@njit(cache=True, inline="always")
def filtered_derivative_row(u: np.ndarray, s: np.ndarray, cutoff: float, dt: float, out: np.ndarray) -> None:
    """PX4 ``BlockDerivative``: ``out`` (k,) = low-pass of ``(u - u_prev) / dt``; 0 on a first sample.

    ``s`` (2k + 1,) = (previous input (k), low-pass state (k), first-sample flag): a first sample (flag 1)
    gives 0 and starts the low-pass from 0.
    """
    k = u.shape[0]
    first = s[2 * k] != 0.0
    alpha = lowpass_alpha(cutoff, dt)
    for j in range(k):
        raw = 0.0 if first else (u[j] - s[j]) / dt
        state = 0.0 if first else alpha * raw + (1.0 - alpha) * s[k + j]
        s[k + j] = state
        out[j] = state
        s[j] = u[j]
    s[2 * k] = 0.0


@njit(cache=True)
def _butterworth_kernel(x: np.ndarray, z: np.ndarray, coef: np.ndarray, y: np.ndarray) -> None:
    for i in range(x.shape[0]):
        butterworth_row(x[i], z[i], coef, y[i])


@njit(cache=True)
def _butterworth_reset_kernel(x: np.ndarray, z: np.ndarray, coef: np.ndarray, rows: np.ndarray) -> None:
    for i in range(x.shape[0]):
        if rows[i]:
            butterworth_reset_row(x[i], z[i], coef)


@njit(cache=True)
def _lowpass_kernel(u: np.ndarray, state: np.ndarray, cutoff: float, dt: np.ndarray) -> None:
    for i in range(u.shape[0]):
        lowpass_row(u[i], state[i], lowpass_alpha(cutoff, dt[i]))


@njit(cache=True)
def _derivative_kernel(u: np.ndarray, s: np.ndarray, cutoff: float, dt: np.ndarray, rows: np.ndarray,
                       out: np.ndarray) -> None:
    for i in range(u.shape[0]):
        if rows[i]:
            filtered_derivative_row(u[i], s[i], cutoff, dt[i], out[i])


def _rows2d(x: ArrayLike) -> NDArray[np.float64]:
    """``x`` as a C-contiguous (N, k) float array: the leading axis is the row axis (a scalar is one row)."""
    a = np.asarray(x, dtype=float)
    return np.ascontiguousarray(a.reshape(a.shape[0] if a.ndim else 1, -1))


def _dt_rows(dt: float | ArrayLike, n: int) -> NDArray[np.float64]:
    return np.ascontiguousarray(np.broadcast_to(check_dt(dt), (n,)), dtype=float)


class Butterworth2:
    """2nd-order Butterworth low-pass (direct form II transposed), batch-first.

    As PX4's ``LowPassFilter2p``, a cut-off of 0 or at/above 0.5 x the sample rate (no valid design)
    makes the filter a pass-through.
    """

    def __init__(self, sample_rate: float, cutoff: float) -> None:
        self.coef = butterworth_coefficients(sample_rate, cutoff)
        self.sample_rate = float(sample_rate)
        self.cutoff = float(cutoff)
        self.enabled = bool(self.coef[ENABLED])
        self.b = self.coef[[B0, B1, B2]]
        self.a = np.array([1.0, self.coef[A1], self.coef[A2]])
        self._z: NDArray[np.float64] | None = None
        self._shape: tuple[int, ...] | None = None

    def reset(self, x: ArrayLike, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Put the filter in steady state at ``x`` (output = x); only the rows of ``rows`` (N,) if given."""
        x = np.array(x, dtype=float)
        x2 = _rows2d(x)
        if rows is None or self._z is None or self._shape != x.shape:
            self._z = np.zeros((x2.shape[0], 2 * x2.shape[1]))
            self._shape = x.shape
            rows = np.ones(x2.shape[0], dtype=bool)
        _butterworth_reset_kernel(x2, self._z, self.coef, np.asarray(rows, dtype=bool))
        return x.copy()

    def update(self, x: ArrayLike) -> NDArray[np.float64]:
        """Filter one sample (any shape; the first call resets to it)."""
        x = np.asarray(x, dtype=float)
        if self._z is None or self._shape != x.shape:
            return self.reset(x)
        x2 = _rows2d(x)
        y = np.empty_like(x2)
        _butterworth_kernel(x2, self._z, self.coef, y)
        return y.reshape(x.shape)


class FirstOrderLowPass:
    """PX4 ``BlockLowPass``: ``y <- a u + (1 - a) y``, ``a = b/(1+b)``, ``b = 2 pi f_c dt`` (f_c = 0: pass-through)."""

    def __init__(self, cutoff: float) -> None:
        _check_rates(1.0, cutoff)
        self.cutoff = float(cutoff)
        self.state: NDArray[np.float64] | None = None

    def reset(self, x: ArrayLike) -> None:
        self.state = np.array(x, dtype=float)

    def update(self, u: ArrayLike, dt: float | ArrayLike) -> NDArray[np.float64]:
        """Filter one sample; ``dt`` [s] scalar or one per row (N,)."""
        u = np.asarray(u, dtype=float)
        if self.state is None or self.state.shape != u.shape:
            self.state = u.copy()
            return self.state
        u2 = _rows2d(u)
        state = _rows2d(self.state).copy()
        _lowpass_kernel(u2, state, self.cutoff, _dt_rows(dt, u2.shape[0]))
        self.state = state.reshape(u.shape)
        return self.state


class FilteredDerivative:
    """PX4 ``BlockDerivative``: low-passed backward difference; 0 on the first sample after reset.

    Per row: ``reset(rows=mask)`` makes the next sample of those rows a first sample again;
    ``update(u, dt, rows=mask)`` advances only those rows (the others keep their state; their output
    entries are then 0).  The state of a row is (previous input, low-pass state, first-sample flag).
    """

    def __init__(self, cutoff: float) -> None:
        _check_rates(1.0, cutoff)
        self.cutoff = float(cutoff)
        self.state: NDArray[np.float64] | None = None  # (N, 2k + 1); None: the next sample is a first sample
        self._shape: tuple[int, ...] | None = None

    def reset(self, x: ArrayLike | None = None, rows: NDArray[np.bool_] | None = None) -> None:
        """Forget the history (all rows, or the rows of ``rows``); with ``x``, start from it instead."""
        if x is None:
            if rows is None or self.state is None:
                self.state = None
            else:
                self.state[np.asarray(rows, dtype=bool), -1] = 1.0
            return
        x = np.asarray(x, dtype=float)
        x2 = _rows2d(x)
        k = x2.shape[1]
        fresh = np.concatenate([x2, np.zeros((x2.shape[0], k + 1))], axis=1)
        if rows is not None and self.state is not None and self._shape == x.shape:
            self.state = masked(self.state, fresh, np.asarray(rows, dtype=bool))
        else:
            self.state, self._shape = fresh, x.shape

    def update(self, u: ArrayLike, dt: float | ArrayLike, rows: NDArray[np.bool_] | None = None
               ) -> NDArray[np.float64]:
        """The filtered derivative of ``u`` (N, ...); ``dt`` [s] scalar or per row; ``rows`` the rows to advance."""
        u = np.asarray(u, dtype=float)
        u2 = _rows2d(u)
        n, k = u2.shape
        dt_rows = _dt_rows(dt, n)
        if self.state is None or self._shape != u.shape:
            self.state = np.zeros((n, 2 * k + 1))
            self.state[:, -1] = 1.0
            self._shape = u.shape
        out = np.zeros_like(u2)
        advance = np.ones(n, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
        _derivative_kernel(u2, self.state, self.cutoff, dt_rows, advance, out)
        return out.reshape(u.shape)
