"""The hover observation: what a policy sees, built from a measurement mapping (one law, batch-first).

Used by :class:`~fawtgym.envs.hover_env.HoverEnv`, :class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv` and
``fawtgym replay`` (which builds the measurement from MAVLink telemetry), so a trained policy sees the same
19 entries per row in simulation and on an autopilot:

=====  ==================================================================  ======  ==============================
index  entry                                                                unit    bound (``observation_bounds``)
=====  ==================================================================  ======  ==============================
0-2    position error b^m - b_sp (world NED)                                m       +- (max_position_error + 1)
3-5    velocity v^m (world NED)                                             m/s     +- 30
6-8    first column of the attitude R^m (body FRD -> world NED)             --      +- 1
9-11   second column of R^m (the 6D rotation representation, Zhou et al.    --      +- 1
       2019)
12-14  body rate Omega^m (FRD)                                              rad/s   +- 40
15-18  the last action applied to the env (after clipping; at reset the     --      the action space
       hover action)
=====  ==================================================================  ======  ==============================

Every entry is clipped to its bound, then cast to float32.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M

#: observation entries per row
OBS_SIZE = 19


def observation_bounds(max_position_error: float, action_low: ArrayLike, action_high: ArrayLike
                       ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """(low, high), float32 (19,), of the observation box (module docstring's last column)."""
    lim = float(max_position_error) + 1.0
    high = np.array([lim] * 3 + [30.0] * 3 + [1.0] * 6 + [40.0] * 3 + [1.0] * 4, dtype=np.float32)
    low = -high
    low[-4:] = np.asarray(action_low, dtype=np.float32)
    high[-4:] = np.asarray(action_high, dtype=np.float32)
    return low, high


def hover_observation(measurement: Mapping[str, ArrayLike], setpoint: ArrayLike, last_action: ArrayLike,
                      low: ArrayLike, high: ArrayLike) -> NDArray[np.float32]:
    """Observations (N, 19) float32 of N rows (module docstring's table).

    Args:
        measurement: ``position`` (N, 3), ``velocity`` (N, 3), ``attitude`` (N, 3, 3), ``angular_velocity``
            (N, 3), as ``info["measurement"]`` of the batch env (other keys are ignored).
        setpoint: (N, 3) or (3,) NED set point [m].
        last_action: (N, 4) the action last applied to the env (clipped to the action space).
        low, high: (19,) bounds, :func:`observation_bounds`.
    """
    r = np.asarray(measurement[M.ATTITUDE], dtype=float)
    pos = np.asarray(measurement[M.POSITION], dtype=float)
    if r.ndim != 3 or r.shape[1:] != (3, 3) or pos.shape != (r.shape[0], 3):
        raise ValueError(f"hover_observation takes a batch of N rows: position (N, 3) and attitude (N, 3, 3), "
                         f"got {pos.shape} and {r.shape}")
    x = np.concatenate([pos - np.asarray(setpoint, dtype=float), np.asarray(measurement[M.VELOCITY], dtype=float),
                        r[:, :, 0], r[:, :, 1], np.asarray(measurement[M.ANGULAR_VELOCITY], dtype=float),
                        np.asarray(last_action, dtype=float).reshape(r.shape[0], 4)], axis=1)
    finite = np.isfinite(x)
    if not finite.all():
        row, i = (int(v) for v in np.argwhere(~finite)[0])
        raise ValueError(f"hover_observation: entry {i} of row {row} is {x[row, i]}; measurements, set point and "
                         "last action must be finite")
    return np.minimum(np.maximum(x, low), high).astype(np.float32)
