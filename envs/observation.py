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

import math
from collections.abc import Mapping

import numpy as np
from numba import njit
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


@njit(cache=True)
def observation_rows(pos: NDArray[np.float64], vel: NDArray[np.float64], att: NDArray[np.float64],
                     rate: NDArray[np.float64], setpoint: NDArray[np.float64], action: NDArray[np.float64],
                     low: NDArray[np.float64], high: NDArray[np.float64], out: NDArray[np.float32]
                     ) -> int:  # pragma: no cover - jitted
    """The table's 19 entries of every row into ``out`` (N, 19), clipped to [low, high]; returns -1, or
    ``19 * row + entry`` of the first non-finite entry (the caller raises)."""
    x = np.empty(19)
    for i in range(pos.shape[0]):
        for c in range(3):
            x[c] = pos[i, c] - setpoint[i, c]
            x[3 + c] = vel[i, c]
            x[6 + c] = att[i, c, 0]  # first column of R^m
            x[9 + c] = att[i, c, 1]  # second column (Zhou et al. 2019)
            x[12 + c] = rate[i, c]
        for c in range(4):
            x[15 + c] = action[i, c]
        for c in range(19):
            if not math.isfinite(x[c]):
                return 19 * i + c
            out[i, c] = min(max(x[c], low[c]), high[c])
    return -1


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
    r = np.ascontiguousarray(measurement[M.ATTITUDE], dtype=np.float64)
    pos = np.ascontiguousarray(measurement[M.POSITION], dtype=np.float64)
    n = r.shape[0] if r.ndim == 3 else -1
    vel = np.ascontiguousarray(measurement[M.VELOCITY], dtype=np.float64)
    rate = np.ascontiguousarray(measurement[M.ANGULAR_VELOCITY], dtype=np.float64)
    if r.shape[1:] != (3, 3) or pos.shape != (n, 3) or vel.shape != (n, 3) or rate.shape != (n, 3):
        raise ValueError(f"hover_observation takes a batch of N rows: position, velocity, angular_velocity (N, 3) "
                         f"and attitude (N, 3, 3), got {pos.shape}, {vel.shape}, {rate.shape} and {r.shape}")
    sp = np.asarray(setpoint, dtype=np.float64)
    if sp.shape != (n, 3):
        sp = np.ascontiguousarray(np.broadcast_to(sp, (n, 3)))
    action = np.ascontiguousarray(last_action, dtype=np.float64).reshape(n, 4)
    out = np.empty((n, OBS_SIZE), dtype=np.float32)
    bad = observation_rows(pos, vel, r, rate, sp, action, np.asarray(low, dtype=np.float64),
                           np.asarray(high, dtype=np.float64), out)
    if bad >= 0:
        row, i = divmod(bad, OBS_SIZE)
        x = np.concatenate([pos[row] - sp[row], vel[row], r[row, :, 0], r[row, :, 1], rate[row], action[row]])
        raise ValueError(f"hover_observation: entry {i} of row {row} is {x[i]}; measurements, set point and "
                         "last action must be finite")
    return out
