"""Batched sensor model: :class:`fawtgym.envs.sensors.SensorModel` for N vehicles at once.

Same noise model, presets and rates as the single-vehicle model (the per-sample sigmas are taken
from a :class:`~fawtgym.envs.sensors.SensorModel` built with the same spec, so the two can never
disagree): pose group sample-and-hold every ``pose_every`` control steps (per vehicle, counted from
that vehicle's own episode start), IMU group every step, constant turn-on biases drawn per vehicle
at its reset, attitude noise ``R exp(Delta^x)`` (Wang et al. (2024) eq. 39).

Random streams.  Per-step noise for all N rows comes from one generator in fixed-size blocks
(N, 21) per step, so one row's trajectory never changes how many numbers another row consumes
(rows stay independent).  The turn-on biases of a row are drawn from that row's own generator
(passed to :meth:`BatchSensorModel.reset_rows`), exactly as :meth:`SensorModel.reset` draws them,
so a row's biases equal a single env's for the same sensor seed.  With N = 1 the caller may pass
the row's generator as the noise generator too; the draws then equal the single model's
(``normal(size=18)`` then ``normal(size=3)`` per step = ``standard_normal((1, 21))``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from fawtgym.core import measurement as M
from fawtgym.core.so3 import exp_so3

from .sensors import SensorModel, SensorSpec, make_sensor_spec
from .vehicles import GRAVITY

_GRAVITY_NED = np.array([0.0, 0.0, GRAVITY])


class BatchSensorModel:
    """Measurements of N vehicles (batch-first) at the control rate; see the module docstring."""

    def __init__(self, spec: SensorSpec | str, control_dt: float, n: int, physics_dt: float | None = None) -> None:
        if not (isinstance(n, (int, np.integer)) and n >= 1):
            raise ValueError(f"number of vehicles n must be a positive int, got {n!r}")
        single = SensorModel(make_sensor_spec(spec), control_dt, physics_dt)
        self.spec = single.spec
        self.dt = control_dt
        self.n = int(n)
        self.pose_every = single.pose_every
        self.sig_pos, self.sig_vel, self.sig_att = single.sig_pos, single.sig_vel, single.sig_att
        self.sig_rate, self.sig_gyro, self.sig_acc = single.sig_rate, single.sig_gyro, single.sig_acc
        self.noisy = single.noisy
        self.gyro_bias = np.zeros((self.n, 3))
        self.accel_bias = np.zeros((self.n, 3))
        self._count = np.zeros(self.n, dtype=np.int64)
        self._pose = {M.POSITION: np.zeros((self.n, 3)), M.VELOCITY: np.zeros((self.n, 3)),
                      M.ATTITUDE: np.broadcast_to(np.eye(3), (self.n, 3, 3)).copy()}
        self.rng = np.random.default_rng(0)

    @property
    def gyro_bias(self) -> NDArray[np.float64]:
        """Turn-on gyro biases (N, 3) [rad/s]; assign (3,) or (N, 3) finite values (checked)."""
        return self._gyro_bias

    @gyro_bias.setter
    def gyro_bias(self, value: Any) -> None:
        self._gyro_bias = self._bias("gyro_bias", value)

    @property
    def accel_bias(self) -> NDArray[np.float64]:
        """Turn-on accelerometer biases (N, 3) [m/s^2]; assign (3,) or (N, 3) finite values (checked)."""
        return self._accel_bias

    @accel_bias.setter
    def accel_bias(self, value: Any) -> None:
        self._accel_bias = self._bias("accel_bias", value)

    def _bias(self, name: str, value: Any) -> NDArray[np.float64]:
        b = np.asarray(value, dtype=float)
        if b.shape not in ((3,), (self.n, 3)) or not np.all(np.isfinite(b)):
            raise ValueError(f"{name} must be 3 finite numbers or ({self.n}, 3), got {value!r}")
        return np.broadcast_to(b, (self.n, 3)).copy()

    def set_noise_rng(self, rng: np.random.Generator) -> None:
        """The generator of the per-step noise of every row."""
        self.rng = rng

    def reset_rows(self, rows: NDArray[np.intp], rngs: list[np.random.Generator]) -> None:
        """Start new episodes for ``rows``: turn-on biases from each row's generator, pose hold restarted."""
        rows = np.asarray(rows, dtype=np.intp)
        if len(rngs) != rows.size:
            raise ValueError(f"need one generator per reset row: {rows.size} rows, {len(rngs)} generators")
        sg, sa = self.spec.gyro_bias_sigma, self.spec.accel_bias_sigma
        for row, rng in zip(rows.tolist(), rngs, strict=True):  # reset path only (not per step)
            self.gyro_bias[row] = rng.normal(0.0, sg, 3) if sg else 0.0
            self.accel_bias[row] = rng.normal(0.0, sa, 3) if sa else 0.0
        self._count[rows] = 0

    def measure(self, t: NDArray[np.float64], position: NDArray[np.float64], velocity: NDArray[np.float64],
                rotation: NDArray[np.float64], angular_velocity: NDArray[np.float64],
                acceleration: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Measurements (N, ...) at times ``t`` (N,) from true states (N, 3) / (N, 3, 3) and NED accelerations."""
        # R^T (a - g e3) and R^T m_E, row by row
        f_sp = np.einsum("nj,nji->ni", acceleration - _GRAVITY_NED, rotation)
        mag = M.EARTH_FIELD_NED @ rotation
        time = np.array(t, dtype=float)
        if not self.noisy:
            return {M.POSITION: position.copy(), M.VELOCITY: velocity.copy(), M.ATTITUDE: rotation.copy(),
                    M.ANGULAR_VELOCITY: angular_velocity.copy(), M.SPECIFIC_FORCE: f_sp,
                    M.GYRO: angular_velocity.copy(), M.MAGNETOMETER: mag, M.TIME: time}
        z = self.rng.standard_normal((self.n, 21))
        take = self._count % self.pose_every == 0
        pose = self._pose
        if take.all():
            pose[M.POSITION] = position + self.sig_pos * z[:, 0:3]
            pose[M.VELOCITY] = velocity + self.sig_vel * z[:, 3:6]
            pose[M.ATTITUDE] = rotation @ exp_so3(self.sig_att * z[:, 6:9])
        elif take.any():
            pose[M.POSITION][take] = position[take] + self.sig_pos * z[take, 0:3]
            pose[M.VELOCITY][take] = velocity[take] + self.sig_vel * z[take, 3:6]
            pose[M.ATTITUDE][take] = rotation[take] @ exp_so3(self.sig_att * z[take, 6:9])
        self._count += 1
        return {M.POSITION: pose[M.POSITION].copy(), M.VELOCITY: pose[M.VELOCITY].copy(),
                M.ATTITUDE: pose[M.ATTITUDE].copy(),
                M.ANGULAR_VELOCITY: angular_velocity + self.sig_rate * z[:, 9:12],
                M.SPECIFIC_FORCE: f_sp + self.accel_bias + self.sig_acc * z[:, 12:15],
                M.GYRO: angular_velocity + self.gyro_bias + self.sig_gyro * z[:, 15:18],
                M.MAGNETOMETER: mag + self.spec.mag_sigma * z[:, 18:21],
                M.TIME: time}
