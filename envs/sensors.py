"""Sensor models: noise presets, sample-and-hold rates, the measurement the agent sees.

Every noise figure is given as a white-noise *density* ``d`` (unit/sqrt(Hz)), i.e. a one-sided
power spectral density ``P = d^2``.  Sampled every ``dt`` seconds, white noise of density ``d``
has per-sample standard deviation ``sigma = d / sqrt(dt)``; this is how seed-000 Table 2's PSDs
(ffts_eso_tse3_fawt_wang2024.txt, eq. 39 noise model) become samples, independent of the rate.

Groups and what they produce (see :mod:`fawtgym.envs.measurement` for the keys):

* pose group (``position``, ``velocity``, ``attitude``) at ``pose_rate`` (motion capture fused by
  the autopilot's estimator; held between samples).  Attitude noise is ``R exp(Delta^x)``
  (eq. 39).
* IMU group at the control rate: ``gyro = Omega + b_g + n_g`` (constant turn-on bias per episode),
  ``specific_force = R^T (a - g e3) + b_a + n_a``, ``magnetometer = R^T m_E + n_m``, and the
  estimator-grade ``angular_velocity = Omega + n_Omega`` (bias removed, as PX4's
  vehicle_angular_velocity after the EKF's bias estimate).

Presets:

* ``"none"``: exact measurements, every control step.
* ``"seed000"``: Table 2 of seed-000, P_b = 3e-8, P_v = 3e-7, P_R = 3e-8, P_Omega = 3e-7 (also used
  for the gyro); accelerometer and magnetometer as ``"mocap_imu"``; no biases; pose every step.
* ``"mocap_imu"``: a VICON-fed PX4 as in seed-000 Sec. 7: pose at 100 Hz with 0.5 mm / 0.1 deg
  noise (VICON marker-fit accuracy), velocity noise 0.01 m/s from the estimator; IMU noise
  densities chosen so that at 250 Hz the per-sample sigmas equal PX4's EKF2_GYR_NOISE (0.015 rad/s)
  and EKF2_ACC_NOISE (0.35 m/s^2) defaults; gyro turn-on bias sigma 0.003 rad/s, accel 0.05 m/s^2;
  magnetometer 0.005 gauss (EKF2_MAG_NOISE 0.05 of ~0.5 gauss field scaled to a calibrated sensor).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fawtgym.observers.lie import exp_so3

from . import measurement as M
from .vehicles import GRAVITY


@dataclasses.dataclass(frozen=True)
class SensorSpec:
    """Noise densities (unit/sqrt(Hz)) or per-sample sigmas, biases, and the pose rate."""

    name: str
    position_density: float = 0.0  #: m/sqrt(Hz)
    velocity_density: float = 0.0  #: (m/s)/sqrt(Hz)
    attitude_density: float = 0.0  #: rad/sqrt(Hz) (rotation-vector noise)
    angular_velocity_density: float = 0.0  #: (rad/s)/sqrt(Hz)
    position_sigma: float = 0.0  #: per-sample sigma added to the density term [m]
    velocity_sigma: float = 0.0
    attitude_sigma: float = 0.0
    gyro_density: float = 0.0
    accel_density: float = 0.0
    mag_sigma: float = 0.0  #: gauss, per sample
    gyro_bias_sigma: float = 0.0  #: rad/s, turn-on bias
    accel_bias_sigma: float = 0.0  #: m/s^2, turn-on bias
    pose_rate: float | None = None  #: Hz; None = every control step

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name in ("name",) or v is None:
                continue
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"sensor field {f.name!r} must be finite and >= 0, got {v!r}")
        if self.pose_rate is not None and self.pose_rate <= 0:
            raise ValueError(f"sensor field 'pose_rate' must be > 0 Hz, got {self.pose_rate!r}")


_GRAVITY_NED = np.array([0.0, 0.0, GRAVITY])
_IMU_250 = dict(gyro_density=0.015 / math.sqrt(250.0), accel_density=0.35 / math.sqrt(250.0), mag_sigma=0.005)

SENSOR_PRESETS: dict[str, SensorSpec] = {
    "none": SensorSpec("none"),
    "seed000": SensorSpec("seed000", position_density=math.sqrt(3e-8), velocity_density=math.sqrt(3e-7),
                          attitude_density=math.sqrt(3e-8), angular_velocity_density=math.sqrt(3e-7),
                          **{**_IMU_250, "gyro_density": math.sqrt(3e-7)}),
    "mocap_imu": SensorSpec("mocap_imu", position_sigma=0.0005, attitude_sigma=math.radians(0.1),
                            velocity_sigma=0.01, angular_velocity_density=0.015 / math.sqrt(250.0),
                            gyro_bias_sigma=0.003, accel_bias_sigma=0.05, pose_rate=100.0, **_IMU_250),
}


def make_sensor_spec(spec: str | SensorSpec | Mapping[str, Any]) -> SensorSpec:
    if isinstance(spec, SensorSpec):
        return spec
    if isinstance(spec, Mapping):
        data = dict(spec)
        base = data.pop("base", "none")
        return dataclasses.replace(make_sensor_spec(base), **data)
    if isinstance(spec, str) and spec in SENSOR_PRESETS:
        return SENSOR_PRESETS[spec]
    raise ValueError(f"unknown sensor preset {spec!r}; valid: {list(SENSOR_PRESETS)} (or a SensorSpec/mapping)")


class SensorModel:
    """Turns the true state into a measurement mapping, for one vehicle, at the control rate."""

    def __init__(self, spec: SensorSpec, control_dt: float) -> None:
        self.spec = spec
        self.dt = control_dt
        if spec.pose_rate is None:
            self.pose_every = 1
        else:
            ratio = 1.0 / (spec.pose_rate * control_dt)
            if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
                raise ValueError(f"sensor pose_rate {spec.pose_rate} Hz must divide the control rate "
                                 f"{1.0 / control_dt:g} Hz")
            self.pose_every = int(round(ratio))
        pose_dt = self.pose_every * control_dt
        root_dt, root_pose = math.sqrt(control_dt), math.sqrt(pose_dt)
        self.sig_pos = math.hypot(spec.position_density / root_pose, spec.position_sigma)
        self.sig_vel = math.hypot(spec.velocity_density / root_pose, spec.velocity_sigma)
        self.sig_att = math.hypot(spec.attitude_density / root_pose, spec.attitude_sigma)
        self.sig_rate = spec.angular_velocity_density / root_dt
        self.sig_gyro = spec.gyro_density / root_dt
        self.sig_acc = spec.accel_density / root_dt
        self.noisy = any(s > 0 for s in (self.sig_pos, self.sig_vel, self.sig_att, self.sig_rate, self.sig_gyro,
                                         self.sig_acc, spec.mag_sigma, spec.gyro_bias_sigma, spec.accel_bias_sigma))

    def reset(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self._vecs = np.array([np.zeros(3), M.EARTH_FIELD_NED])
        self.gyro_bias = rng.normal(0.0, self.spec.gyro_bias_sigma, 3) if self.spec.gyro_bias_sigma else np.zeros(3)
        self.accel_bias = rng.normal(0.0, self.spec.accel_bias_sigma, 3) if self.spec.accel_bias_sigma else np.zeros(3)
        self._pose: dict[str, NDArray[np.float64]] | None = None
        self._count = 0

    def measure(self, t: float, position: NDArray[np.float64], velocity: NDArray[np.float64],
                rotation: NDArray[np.float64], angular_velocity: NDArray[np.float64],
                acceleration: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Measurement at time ``t`` from the true state and NED acceleration."""
        # one product for both body-frame vectors: rows [a - g e3, m_E] @ R = (R^T [a - g e3, m_E])^T
        vecs = self._vecs
        np.subtract(acceleration, _GRAVITY_NED, out=vecs[0])
        f_sp, mag = vecs @ rotation
        if not self.noisy:
            pose = {M.POSITION: position.copy(), M.VELOCITY: velocity.copy(), M.ATTITUDE: rotation.copy()}
            return {**pose, M.ANGULAR_VELOCITY: angular_velocity.copy(), M.SPECIFIC_FORCE: f_sp,
                    M.GYRO: angular_velocity.copy(), M.MAGNETOMETER: mag, M.TIME: np.asarray(t)}
        n = self.rng.normal(size=18)
        if self._pose is None or self._count % self.pose_every == 0:
            self._pose = {M.POSITION: position + self.sig_pos * n[0:3],
                          M.VELOCITY: velocity + self.sig_vel * n[3:6],
                          M.ATTITUDE: rotation @ exp_so3(self.sig_att * n[6:9])}
        self._count += 1
        return {**{k: v.copy() for k, v in self._pose.items()},
                M.ANGULAR_VELOCITY: angular_velocity + self.sig_rate * n[9:12],
                M.SPECIFIC_FORCE: f_sp + self.accel_bias + self.sig_acc * n[12:15],
                M.GYRO: angular_velocity + self.gyro_bias + self.sig_gyro * n[15:18],
                M.MAGNETOMETER: mag + self.spec.mag_sigma * self.rng.normal(size=3),
                M.TIME: np.asarray(t)}
