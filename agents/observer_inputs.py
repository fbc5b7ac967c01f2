"""What a flight controller really knows: a late motion-capture pose and its commanded thrust through a model.

Two pieces, batch-first, used by :class:`fawtgym.agents.px4_agent.PX4Agent` when asked
(``pose_latency``, ``observer_inputs="commanded"``, ``thrust_model_error``); ``docs/fidelity.md`` gives
the values the FAWT study uses and their sources.

* :class:`PoseDelay`: the pose group (``position``, ``velocity``, ``attitude``) reaches the controller
  ``latency`` seconds late (a motion-capture system streaming over Wi-Fi to the autopilot; the env's
  sensor preset already holds the pose at the mocap rate).  A ring buffer of whole control steps:
  the latency must be a multiple of the control period.  The IMU keys are not delayed.
* :func:`commanded_wrench`: the collective thrust [N] and body torque [N m] the controller *commanded*
  (rotor normalized thrusts through the allocation's effectiveness, i.e. the controller's thrust curve)
  times ``1 + thrust_model_error``: the controller's model of its rotors is off by that stated relative
  error, and it knows nothing of the motor lag.  This replaces the env's ``info["applied"]`` (the exact
  wrench after motor lag, truth) as the observer's known input.  The law is the row function
  :func:`commanded_wrench_row` (compiled by numba), applied to every row by one kernel.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core import measurement as M
from fawtgym.core.checks import check_number, shown
from fawtgym.core.rows import masked

#: the measurement keys the motion-capture link delivers (the rest comes from the onboard IMU)
POSE_KEYS = (M.POSITION, M.VELOCITY, M.ATTITUDE)
#: allowed ``observer_inputs`` values
OBSERVER_INPUTS = ("applied", "commanded")


#: the longest pose latency an agent delays its pose by [s]
MAX_POSE_LATENCY = 1.0


def latency_steps(latency: float, control_dt: float) -> int:
    """``latency`` [s] as a whole number of control steps; ValueError naming the value otherwise."""
    latency = check_number(latency, "pose_latency", minimum=0.0, inclusive_minimum=True, maximum=MAX_POSE_LATENCY,
                           note="s")
    steps = latency / control_dt
    if abs(steps - round(steps)) > 1e-6:
        raise ValueError(f"pose_latency {latency:g} s must be a multiple of the control period {control_dt:g} s")
    return int(round(steps))


def check_thrust_model_error(error: float) -> float:
    """A relative thrust-model error in (-0.5, 0.5); ValueError naming the value otherwise."""
    return check_number(error, "thrust_model_error", minimum=-0.5, maximum=0.5, inclusive_maximum=False,
                        note="(a relative error)")


class PoseDelay:
    """Delays the pose keys of a batched measurement by ``steps`` calls (per-row reset: the buffer is filled)."""

    def __init__(self, steps: int) -> None:
        if not (isinstance(steps, int) and steps >= 0):
            raise ValueError(f"steps must be an int >= 0, got {shown(steps)}")
        self.steps = steps
        self._buf: dict[str, NDArray[np.float64]] = {}
        self._head = 0

    def reset(self, meas: Mapping[str, NDArray[np.float64]], rows: NDArray[np.bool_] | None = None) -> None:
        """Fill the buffer of every row (or of ``rows`` (N,)) with the current pose: no history before the start."""
        if self.steps == 0:
            return
        for key in POSE_KEYS:
            cur = np.asarray(meas[key], dtype=float)
            fill = np.broadcast_to(cur, (self.steps,) + cur.shape).copy()
            old = self._buf.get(key)
            if rows is None or old is None or old.shape != fill.shape:
                self._buf[key] = fill
            else:
                self._buf[key] = np.stack([masked(o, f, rows) for o, f in zip(old, fill, strict=True)])
        if rows is None:
            self._head = 0

    def __call__(self, meas: Mapping[str, NDArray[np.float64]]) -> dict[str, NDArray[np.float64]]:
        """Push this step's pose and return the measurement with the pose of ``steps`` calls ago (the slot it read
        now holds this step's pose: :meth:`undo` puts the read pose back)."""
        out = dict(meas)
        if self.steps == 0:
            return out
        if not self._buf:
            self.reset(meas)
        for key in POSE_KEYS:
            buf = self._buf[key]
            out[key] = buf[self._head].copy()
            buf[self._head] = meas[key]
        self._head = (self._head + 1) % self.steps
        return out

    def undo(self, delayed: Mapping[str, NDArray[np.float64]]) -> None:
        """Take back the last push, given what it returned: the slot it wrote gets the pose it held back (a caller
        whose step was refused after the push leaves the line as it was)."""
        if self.steps == 0:
            return
        self._head = (self._head - 1) % self.steps
        for key in POSE_KEYS:
            self._buf[key][self._head] = delayed[key]


@njit(cache=True, inline="always")
def commanded_wrench_row(rotor: np.ndarray, thrust_per_unit: float, allocation_matrix: np.ndarray,
                         wrench: np.ndarray) -> None:
    """``wrench`` (4,) = (collective thrust [N], torque (3,) [N m]) = B (T rotor) for one vehicle: rotor normalized
    thrusts (4,), ``thrust_per_unit`` = T_max (1 + thrust_model_error) [N], B (4, 4) the rotor effectiveness."""
    for a in range(4):
        total = 0.0
        for j in range(4):
            total += allocation_matrix[a, j] * (rotor[j] * thrust_per_unit)
        wrench[a] = total


@njit(cache=True)
def _commanded_wrench_kernel(rotor: np.ndarray, thrust_per_unit: float, allocation_matrix: np.ndarray,
                             wrench: np.ndarray) -> None:
    for i in range(rotor.shape[0]):
        commanded_wrench_row(rotor[i], thrust_per_unit, allocation_matrix, wrench[i])


def commanded_wrench(rotor_thrust_norm: NDArray[np.float64], max_rotor_thrust: float,
                     allocation_matrix: NDArray[np.float64], thrust_model_error: float
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Collective thrust (N,) [N] and body torque (N, 3) [N m] the controller believes it commanded.

    ``rotor_thrust_norm`` (N, 4) normalized rotor thrusts sent to the motors, ``max_rotor_thrust`` [N] and
    ``allocation_matrix`` (4, 4) (rows f, tau_x, tau_y, tau_z per newton of rotor thrust) the controller's
    rotor model, scaled by ``1 + thrust_model_error`` (:func:`commanded_wrench_row`).
    """
    rotor = np.ascontiguousarray(np.asarray(rotor_thrust_norm, dtype=float).reshape(-1, 4))
    wrench = np.empty((rotor.shape[0], 4))
    _commanded_wrench_kernel(rotor, float(max_rotor_thrust * (1.0 + thrust_model_error)),
                             np.ascontiguousarray(allocation_matrix, dtype=float), wrench)
    return wrench[:, 0], wrench[:, 1:]
