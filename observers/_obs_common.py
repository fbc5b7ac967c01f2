"""Small helpers shared by the Wang et al. (2024) observers (FFTS-ESO, LESO, FxTSDO, STO).

Not an observer itself (the leading underscore keeps it out of the auto-import/registry).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.measurement import batch_measurement

if TYPE_CHECKING:
    from fawtgym.observers.base import Observer


def require(measurement: Mapping[str, ArrayLike], keys: Sequence[str], who: str) -> dict[str, NDArray[np.float64]]:
    """Batch the measurement and check that ``keys`` are present and finite (ValueError otherwise)."""
    meas = batch_measurement(measurement)
    missing = [k for k in keys if k not in meas]
    if missing:
        raise ValueError(f"{who} needs measurement keys {list(keys)}; missing {missing} (got {sorted(meas)})")
    n = meas[keys[0]].shape[0]
    for k in keys:
        if meas[k].shape[0] != n:
            raise ValueError(f"{who}: measurement[{k!r}] has batch size {meas[k].shape[0]}, expected {n}")
        if not np.all(np.isfinite(meas[k])):
            raise ValueError(f"{who}: measurement[{k!r}] contains non-finite values")
    return meas


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


def batch_thrust(f: NDArray[np.float64], n: int, who: str) -> NDArray[np.float64]:
    """Thrust (1,) or (N,) -> (N,)."""
    if f.shape == (1,) and n != 1:
        f = np.broadcast_to(f, (n,))
    if f.shape != (n,):
        raise ValueError(f"{who}: thrust must have shape ({n},), got {f.shape}")
    return f


def batch_torque(tau: NDArray[np.float64], n: int, who: str) -> NDArray[np.float64]:
    if tau.shape == (1, 3) and n != 1:
        tau = np.broadcast_to(tau, (n, 3))
    if tau.shape != (n, 3):
        raise ValueError(f"{who}: torque must have shape (3,) or ({n}, 3), got {tau.shape}")
    return tau


def step_inputs(obs: Observer, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
                dt: float, keys: Sequence[str], n: int, who: str
                ) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.float64], NDArray[np.float64]]:
    """The common input checks of ``update()`` for an observer whose state holds ``n`` vehicles (fixed at reset).

    ``dt``, thrust and torque as in :meth:`Observer._inputs`; the measurement through :func:`require`; its batch
    size (that of ``keys[0]``) must equal ``n``.  Returns (measurement, thrust (n,), torque (n, 3)).
    """
    _, f, tau = obs._inputs({}, thrust, torque, dt)
    m = require(measurement, keys, who)
    if m[keys[0]].shape[0] != n:
        raise ValueError(f"{who}: measurement batch size {m[keys[0]].shape[0]} != reset batch size {n}")
    return m, batch_thrust(f, n, who), batch_torque(tau, n, who)


def check_finite(who: str, **arrays: NDArray[np.float64]) -> None:
    """Raise FloatingPointError naming the first non-finite state (never return NaN/inf silently)."""
    for name, a in arrays.items():
        if not np.all(np.isfinite(a)):
            bad = np.unique(np.nonzero(~np.isfinite(a))[0])
            raise FloatingPointError(f"{who}: state {name!r} became non-finite for batch rows {bad.tolist()}; "
                                     "the observer diverged (check gains, dt and the measurement)")


def positive(who: str, **values: float) -> None:
    """ValueError unless every value is a finite positive number."""
    for k, v in values.items():
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{who}: gain {k} must be a finite positive number, got {v!r}")


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
    jw0 = inertia[0, 0] * omega[0] + inertia[0, 1] * omega[1] + inertia[0, 2] * omega[2]
    jw1 = inertia[1, 0] * omega[0] + inertia[1, 1] * omega[1] + inertia[1, 2] * omega[2]
    jw2 = inertia[2, 0] * omega[0] + inertia[2, 1] * omega[1] + inertia[2, 2] * omega[2]
    m0 = jw1 * omega[2] - jw2 * omega[1] + torque[0]
    m1 = jw2 * omega[0] - jw0 * omega[2] + torque[1]
    m2 = jw0 * omega[1] - jw1 * omega[0] + torque[2]
    for j in range(3):
        out[j] = inertia_inv[j, 0] * m0 + inertia_inv[j, 1] * m1 + inertia_inv[j, 2] * m2


_I1 = [1, 2, 0]
_I2 = [2, 0, 1]


def cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """a x b over the last axis (..., 3); a lean replacement for np.cross on small batches."""
    return a[..., _I1] * b[..., _I2] - a[..., _I2] * b[..., _I1]


def all_finite(*arrays: NDArray[np.float64]) -> bool:
    """True iff every entry of every array is finite (one reduction per array)."""
    return bool(np.isfinite(sum(float(np.sum(a)) for a in arrays)))


def floats(x: object) -> list[float]:
    """All entries of ``x`` as a flat list of Python floats (the N = 1 fast paths; one call for a float64 ndarray).

    Raises what ``np.asarray(x, dtype=float)`` raises for input that is not numeric.
    """
    if type(x) is np.ndarray and x.dtype.char == "d":
        return x.ravel().tolist()
    return np.asarray(x, dtype=float).ravel().tolist()


_SIZES = {"position": 3, "velocity": 3, "attitude": 9, "angular_velocity": 3, "specific_force": 3, "gyro": 3,
          "magnetometer": 3}


def single_inputs(measurement: Mapping[str, object], keys: tuple[str, ...], thrust: object, torque: object,
                  dt: object) -> tuple[list[list[float]], float, list[float]] | None:
    """The N = 1 fast paths' inputs as Python floats: ``([floats per key], thrust, torque)``.

    Returns None unless the step is a well-formed, finite single-vehicle step (keys present with sizes
    3 / 9, one thrust, three torques, a finite positive ``dt``); the caller then takes its general path,
    which raises the usual errors.
    """
    try:
        values = [floats(measurement[k]) for k in keys]
        fl = floats(thrust)
        tq = floats(torque)
    except (KeyError, ValueError, TypeError):
        return None
    if (len(fl) != 1 or len(tq) != 3 or any(len(v) != _SIZES[k] for k, v in zip(keys, values, strict=True))
            or not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0)
            or not math.isfinite(sum(sum(v) for v in values) + fl[0] + sum(tq))):
        return None
    return values, fl[0], tq


def single_state(obs: Observer, names: Sequence[str]) -> list[float]:
    """The N = 1 state of ``obs`` (its ``_s`` dict of (1, 3) arrays under ``names``) as one flat float list:
    the floats the last fast step cached while ``_s`` is still the dict it stored, else read from ``_s``."""
    cache = obs._single
    if cache is not None and cache[0] is obs._s:
        return cache[1]
    flat: list[float] = []
    for k in names:
        flat += obs._s[k][0].tolist()
    return flat


def store_single_state(obs: Observer, who: str, names: Sequence[str], flat: list[float]) -> None:
    """Keep a fast step's new N = 1 state: :func:`check_finite` (FloatingPointError naming the first non-finite
    state), then ``obs._s`` = (1, 3) views of one buffer under ``names`` and ``obs._single`` = (that dict, ``flat``)."""
    buf = np.array(flat)
    state = {k: buf[None, 3 * i:3 * i + 3] for i, k in enumerate(names)}
    if not math.isfinite(sum(flat)):
        check_finite(who, **{k: v[0] for k, v in state.items()})
    obs._s = state
    obs._single = (state, flat)
