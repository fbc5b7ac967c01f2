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

All filters hold arrays with any trailing shape; ``reset(x)`` sets the steady state at ``x``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal


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

    def reset(self, x: ArrayLike) -> NDArray[np.float64]:
        """Put the filter in steady state at ``x`` (output = x)."""
        x = np.array(x, dtype=float)
        b, a = self.b, self.a
        # DF-II transposed steady state for constant input x (DC gain 1): y = x
        self._z2 = (b[2] - a[2]) * x
        self._z1 = (b[1] - a[1]) * x + self._z2
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

    def update(self, u: ArrayLike, dt: float) -> NDArray[np.float64]:
        u = np.asarray(u, dtype=float)
        if self.cutoff == 0.0 or self.state is None or self.state.shape != u.shape:
            self.state = u.copy()
            return self.state
        b = 2.0 * math.pi * self.cutoff * dt
        a = b / (1.0 + b)
        self.state = a * u + (1.0 - a) * self.state
        return self.state


class FilteredDerivative:
    """PX4 ``BlockDerivative``: low-passed backward difference; 0 on the first sample after reset."""

    def __init__(self, cutoff: float) -> None:
        self.lowpass = FirstOrderLowPass(cutoff)
        self.previous: NDArray[np.float64] | None = None

    def reset(self, x: ArrayLike | None = None) -> None:
        self.previous = None if x is None else np.array(x, dtype=float)
        self.lowpass.state = None if x is None else np.zeros_like(self.previous)

    def update(self, u: ArrayLike, dt: float) -> NDArray[np.float64]:
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite positive number of seconds, got {dt!r}")
        u = np.array(u, dtype=float)
        if self.previous is None or self.previous.shape != u.shape:
            self.previous = u
            self.lowpass.reset(np.zeros_like(u))
            return np.zeros_like(u)
        raw = (u - self.previous) / dt
        self.previous = u
        return self.lowpass.update(raw, dt)
