"""Small helpers shared by the Wang et al. (2024) observers (FFTS-ESO, LESO, FxTSDO, STO).

Not an observer itself (the leading underscore keeps it out of the auto-import/registry).  The row helpers
(``*_row``) are compiled and called by the observers' kernels per row.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.arrays import REAL_KINDS, as_array
from fawtgym.core.checks import check_positive
from fawtgym.core.so3_kernels import known_angular_acceleration_entries


def batch_vec(x: ArrayLike | None, n: int, label: str, who: str) -> NDArray[np.float64]:
    """(3,) or (N, 3) or None -> (N, 3) float array (zeros for None); ValueError on wrong shape."""
    if x is None:
        return np.zeros((n, 3))
    a = np.asarray(x, dtype=float)
    if a.shape == (3,):
        a = np.broadcast_to(a, (n, 3))
    if a.shape != (n, 3) or not np.all(np.isfinite(a)):
        raise ValueError(f"{who}: {label} must be finite with shape (3,) or ({n}, 3), got shape {a.shape}")
    return np.array(a)


#: the largest rate gain [rad/s] (a bandwidth, a pole) an observer accepts: its Euler step needs dt below about
#: 1 / gain, under a microsecond beyond it (no env or flight log steps that fast), and the gains' powers of the
#: bandwidth rules (omega^3, omega^(n+1)) overflow float64 long before 1e300
MAX_RATE_GAIN = 1e6


def real_vector(value: object, size: int) -> NDArray[np.float64] | None:
    """``value`` as a finite float64 vector (``size``,) if it holds real numbers (bool, complex, str refused), else
    None (the caller words the error, naming its argument)."""
    a = as_array(value)
    if a.dtype.kind not in REAL_KINDS or a.shape != (size,) or not np.all(np.isfinite(a)):
        return None
    return a.astype(np.float64)


def positive(who: str, maximum: float = math.inf, **values: float) -> tuple[float, ...]:
    """The ``values`` as floats; ValueError naming the first that is not a real, finite number in (0, ``maximum``]
    (:func:`fawtgym.core.checks.check_positive`)."""
    return tuple(check_positive(v, f"{who}: gain {k}", maximum=maximum) for k, v in values.items())


@njit(cache=True)
def sig_row(x: float, a: float) -> float:
    """sig^a(x) = |x|^a sign(x) of one number (0 at 0 for a > 0); |x|^(1/2) and |x|^(3/2) by a square root,
    several times cheaper than pow (the STO's and the default FxTSDO's exponents)."""
    ax = abs(x)
    if a == 0.5:
        mag = math.sqrt(ax)
    elif a == 1.5:
        mag = ax * math.sqrt(ax)
    else:
        mag = ax**a
    if x > 0.0:
        return mag
    if x < 0.0:
        return -mag
    return 0.0


@njit(cache=True)
def known_acceleration_row(att: NDArray[np.float64], thrust: float, mass: float, gravity: float,
                           out: NDArray[np.float64]) -> None:
    """out = g e3 - (f/m) R e3: the known part of v' in Wang et al. (2024) eq. (38) (world NED)."""
    f_over_m = thrust / mass
    out[0] = -f_over_m * att[0, 2]
    out[1] = -f_over_m * att[1, 2]
    out[2] = gravity - f_over_m * att[2, 2]


@njit(cache=True)
def known_angular_acceleration_row(omega: NDArray[np.float64], torque: NDArray[np.float64],
                                   inertia: NDArray[np.float64], inertia_inv: NDArray[np.float64],
                                   out: NDArray[np.float64]) -> None:
    """out = J^-1 (J Omega x Omega + tau): the known part of Omega' in Wang et al. (2024) eq. (38) (body FRD)."""
    out[0], out[1], out[2] = known_angular_acceleration_entries(inertia, inertia_inv, omega[0], omega[1], omega[2],
                                                                torque[0], torque[1], torque[2])
