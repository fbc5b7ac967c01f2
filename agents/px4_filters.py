"""The low-pass filters of PX4's control pipeline, batch-first.

* :class:`Butterworth2` -- PX4's ``LowPassFilter2p``: a 2nd-order Butterworth biquad designed by the
  bilinear transform with pre-warping at the cut-off.  Used on the gyro (``IMU_GYRO_CUTOFF``) before the
  rate loop and on the angular acceleration for the rate D term (``IMU_DGYRO_CUTOFF``), as in PX4's
  ``VehicleAngularVelocity``.  The coefficients come from :func:`scipy.signal.butter`.
* :class:`FirstOrderLowPass` -- PX4's ``BlockLowPass``: ``y += a (u - y)`` with ``a = b / (1 + b)``,
  ``b = 2 pi f_c dt``.
* :class:`FilteredDerivative` -- PX4's ``BlockDerivative``: first-order low-pass of the backward
  difference; mc_pos_control (v1.13) uses it with ``MPC_VELD_LP`` (5 Hz) for the velocity derivative of
  the velocity D term.

All filters hold arrays with a leading row axis (one row per vehicle) and any trailing shape;
``reset(x)`` sets the steady state at ``x``, ``reset(x, rows=mask)`` only for the rows of ``mask``
(rows of a batched env end at different times); ``dt`` may be one per row (loops whose rows run at
different phases).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from fawtgym.core.rows import check_dt, masked, per_row


def _check_rates(sample_rate: float, cutoff: float) -> None:
    if not (math.isfinite(sample_rate) and sample_rate > 0):
        raise ValueError(f"sample_rate must be a finite positive frequency [Hz], got {sample_rate!r}")
    if not (math.isfinite(cutoff) and cutoff >= 0):
        raise ValueError(f"cutoff must be a finite frequency >= 0 [Hz] (0 disables the filter), got {cutoff!r}")


class Butterworth2:
    """2nd-order Butterworth low-pass (direct form II transposed), batch-first.

    As PX4's ``LowPassFilter2p``, a cut-off of 0 or at/above 0.5 x the sample rate (no valid design)
    makes the filter a pass-through.
    """

    def __init__(self, sample_rate: float, cutoff: float) -> None:
        _check_rates(sample_rate, cutoff)
        self.sample_rate = float(sample_rate)
        self.cutoff = float(cutoff)
        self.enabled = 0.0 < cutoff < 0.5 * sample_rate * 0.999
        if self.enabled:
            b, a = signal.butter(2, cutoff, btype="low", fs=sample_rate)
            self.b = b / a[0]
            self.a = a / a[0]
        else:
            self.b = np.array([1.0, 0.0, 0.0])
            self.a = np.array([1.0, 0.0, 0.0])
        self._z1: NDArray[np.float64] | None = None
        self._z2: NDArray[np.float64] | None = None

    def reset(self, x: ArrayLike, rows: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        """Put the filter in steady state at ``x`` (output = x); only the rows of ``rows`` (N,) if given."""
        x = np.array(x, dtype=float)
        b, a = self.b, self.a
        # DF-II transposed steady state for constant input x (DC gain 1): y = x
        z2 = (b[2] - a[2]) * x
        z1 = (b[1] - a[1]) * x + z2
        if rows is not None and self._z1 is not None and self._z1.shape == x.shape:
            z1, z2 = masked(self._z1, z1, rows), masked(self._z2, z2, rows)
        self._z1, self._z2 = z1, z2
        return x.copy()

    def update(self, x: ArrayLike) -> NDArray[np.float64]:
        """Filter one sample (any shape; the first call resets to it)."""
        x = np.asarray(x, dtype=float)
        if self._z1 is None or self._z1.shape != x.shape:
            return self.reset(x)
        if not self.enabled:
            return x.copy()
        b, a = self.b, self.a
        y = b[0] * x + self._z1
        self._z1 = b[1] * x - a[1] * y + self._z2
        self._z2 = b[2] * x - a[2] * y
        return y


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
        if self.cutoff == 0.0 or self.state is None or self.state.shape != u.shape:
            self.state = u.copy()
            return self.state
        b = 2.0 * math.pi * self.cutoff * per_row(check_dt(dt), u.ndim)
        a = b / (1.0 + b)
        self.state = a * u + (1.0 - a) * self.state
        return self.state


class FilteredDerivative:
    """PX4 ``BlockDerivative``: low-passed backward difference; 0 on the first sample after reset.

    Per row: ``reset(rows=mask)`` makes the next sample of those rows a first sample again;
    ``update(u, dt, rows=mask)`` advances only those rows (the others keep their state; their output
    entries are then not meaningful).
    """

    def __init__(self, cutoff: float) -> None:
        self.lowpass = FirstOrderLowPass(cutoff)
        self.previous: NDArray[np.float64] | None = None
        self._first: NDArray[np.bool_] | None = None  # (N,) rows whose next sample is a first sample

    def reset(self, x: ArrayLike | None = None, rows: NDArray[np.bool_] | None = None) -> None:
        """Forget the history (all rows, or the rows of ``rows``); with ``x``, start from it instead."""
        if rows is not None and self.previous is not None:
            if x is not None:
                self.previous = masked(self.previous, np.asarray(x, dtype=float), rows)
                self.lowpass.state = masked(self.lowpass.state, np.zeros_like(self.previous), rows)
                self._first = self._first & ~rows
            else:
                self._first = self._first | rows
            return
        self.previous = None if x is None else np.array(x, dtype=float)
        self.lowpass.state = None if x is None else np.zeros_like(self.previous)
        self._first = None if x is None else np.zeros(self.previous.shape[0], dtype=bool)

    def update(self, u: ArrayLike, dt: float | ArrayLike, rows: NDArray[np.bool_] | None = None
               ) -> NDArray[np.float64]:
        """The filtered derivative of ``u`` (N, ...); ``dt`` [s] scalar or per row; ``rows`` the rows to advance."""
        dt = check_dt(dt)
        u = np.array(u, dtype=float)
        if self.previous is None or self.previous.shape != u.shape:
            self.previous = u
            self.lowpass.reset(np.zeros_like(u))
            self._first = np.zeros(u.shape[0], dtype=bool)
            return np.zeros_like(u)
        raw = (u - self.previous) / per_row(dt, u.ndim)
        first = self._first if self._first.any() else None
        if first is not None:  # rows reset since their last sample: this one is their first
            raw = masked(raw, np.zeros_like(raw), first)
        old_prev, old_state = self.previous, self.lowpass.state
        if first is not None:
            self.lowpass.state = masked(old_state, np.zeros_like(old_state), first)
        out = self.lowpass.update(raw, dt)
        if first is not None:
            out = self.lowpass.state = masked(out, np.zeros_like(out), first)
        self.previous = u
        if rows is not None:
            self.previous = masked(old_prev, u, rows)
            self.lowpass.state = masked(old_state, self.lowpass.state, rows)
            if first is not None:
                self._first = first & ~rows
        elif first is not None:
            self._first = np.zeros_like(first)
        return out
