"""Keys and helpers for the measurement mapping the env reports in ``info["measurement"]``.

A measurement is a plain mapping of arrays (so Gymnasium's vector envs can stack it), every
entry with an optional leading batch axis:

================== ========= ==========================================================
key                shape     meaning
================== ========= ==========================================================
``position``       (N, 3)    b^m, world NED [m] (Wang et al. (2024) eq. 39)
``velocity``       (N, 3)    v^m, world NED [m/s]
``attitude``       (N, 3, 3) R^m, body FRD -> world NED
``angular_velocity`` (N, 3)  Omega^m, body FRD [rad/s] (estimator-grade, as PX4's vehicle_angular_velocity)
``specific_force`` (N, 3)    accelerometer, body FRD [m/s^2] (R^T (a - g e3))
``gyro``           (N, 3)    raw gyroscope, body FRD [rad/s]
``magnetometer``   (N, 3)    magnetic field, body FRD [gauss]
``time``           (N,)      time of the sample [s]
================== ========= ==========================================================
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.checks import shown

from .arrays import REAL_KINDS
from .constants import EARTH_FIELD_NED as _EARTH_FIELD_NED

POSITION = "position"
VELOCITY = "velocity"
ATTITUDE = "attitude"
ANGULAR_VELOCITY = "angular_velocity"
SPECIFIC_FORCE = "specific_force"
GYRO = "gyro"
MAGNETOMETER = "magnetometer"
TIME = "time"

MEASUREMENT_KEYS = (POSITION, VELOCITY, ATTITUDE, ANGULAR_VELOCITY, SPECIFIC_FORCE, GYRO, MAGNETOMETER, TIME)
#: trailing shape of every measurement key (after the optional batch axis)
TRAILING_SHAPES = {POSITION: (3,), VELOCITY: (3,), ATTITUDE: (3, 3), ANGULAR_VELOCITY: (3,), SPECIFIC_FORCE: (3,),
                   GYRO: (3,), MAGNETOMETER: (3,), TIME: ()}

#: Earth magnetic field used by the simulated magnetometer, world NED [gauss] (:mod:`fawtgym.core.constants`).
EARTH_FIELD_NED = _EARTH_FIELD_NED


_F64 = np.dtype(np.float64)


def batch_measurement(measurement: Mapping[str, object], keys: tuple[str, ...] | None = None,
                      who: str | None = None) -> dict[str, NDArray[np.float64]]:
    """Return the measurement with a leading batch axis on every known key (N = 1 added if absent).

    ``keys``: only these keys (those of them present), e.g. the ones a controller reads; default all.
    A float64 array is passed on as is (batched) or as a (1, *trailing) view (unbatched: the single env's
    info), never copied; anything else goes through ``np.asarray(value, dtype=float)``.
    Raises ValueError naming a key whose trailing shape is wrong or whose value is ragged, TypeError naming a key
    whose value is not real numbers (bool, complex, str, object refused); ``who`` (an agent's or observer's name)
    prefixes the message.
    """
    out: dict[str, NDArray[np.float64]] = {}
    if keys is None:
        for key, value in measurement.items():
            trailing = TRAILING_SHAPES.get(key)
            if trailing is not None and type(value) is np.ndarray and value.dtype is _F64:
                shape = value.shape
                if shape == trailing:
                    out[key] = value[None]
                    continue
                if shape[1:] == trailing and len(shape) == len(trailing) + 1:
                    out[key] = value
                    continue
            _convert_entry(out, key, value, trailing, who)
        return out
    spec = _KEY_SPECS.get(keys)
    if spec is None:
        spec = _KEY_SPECS[keys] = tuple((k, TRAILING_SHAPES.get(k)) for k in keys)
    get = measurement.get
    for key, trailing in spec:
        value = get(key)
        if trailing is not None and type(value) is np.ndarray and value.dtype is _F64:
            shape = value.shape
            if shape == trailing:       # the single env's (the common case): a (1, *trailing) view
                out[key] = value[None]
                continue
            if shape[1:] == trailing and len(shape) == len(trailing) + 1:
                out[key] = value
                continue
        if value is not None or key in measurement:
            _convert_entry(out, key, value, trailing, who)
    return out


#: (key, trailing shape or None) of each key tuple :func:`batch_measurement` was asked for (memoized)
_KEY_SPECS: dict[tuple[str, ...], tuple[tuple[str, tuple[int, ...] | None], ...]] = {}


def _convert_entry(out: dict[str, NDArray[np.float64]], key: str, value: object,
                   trailing: tuple[int, ...] | None, who: str | None = None) -> None:
    """``out[key]`` = ``value`` as a float64 array with a leading batch axis (:func:`batch_measurement`, for what is
    not already a float64 array of the key's shape)."""
    prefix = f"{who}: " if who else ""
    try:
        arr = np.asarray(value)
    except ValueError:  # ragged
        raise ValueError(f"{prefix}measurement[{shown(key)}] must be an array of real numbers, got a ragged "
                         f"{type(value).__name__}") from None
    if arr.dtype.kind not in REAL_KINDS:
        raise TypeError(f"{prefix}measurement[{shown(key)}] must hold real numbers, got {type(value).__name__} of "
                        f"dtype {arr.dtype}")
    arr = arr.astype(float, copy=False)
    if trailing is None:
        out[key] = arr
        return
    if arr.shape == trailing:
        arr = arr[None, ...]
    elif arr.shape[1:] != trailing:
        raise ValueError(f"{prefix}measurement[{shown(key)}] must have shape {trailing} or (N, *{trailing}), got "
                         f"{arr.shape}")
    out[key] = arr
