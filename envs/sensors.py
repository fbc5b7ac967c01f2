"""Sensor models: noise presets, sample-and-hold rates, the measurement the agent sees.

Every noise figure is given as a white-noise *density* ``d`` (unit/sqrt(Hz)), i.e. a one-sided
power spectral density ``P = d^2``.  Sampled every ``dt`` seconds, white noise of density ``d``
has per-sample standard deviation ``sigma = d / sqrt(dt)``; this is how Wang et al. (2024) Table 2's PSDs
(the eq. 39 noise model) become samples, independent of the rate.

Groups and what they produce (see :mod:`fawtgym.core.measurement` for the keys):

* pose group (``position``, ``velocity``, ``attitude``) at ``pose_rate`` (motion capture fused by
  the autopilot's estimator; held between samples).  Attitude noise is ``R exp(Delta^x)``
  (eq. 39).
* IMU group at the control rate: ``gyro = Omega + b_g + n_g`` (constant turn-on bias per episode),
  ``specific_force = R^T (a - g e3) + b_a + n_a``, ``magnetometer = R^T m_E + n_m``, and the
  estimator-grade ``angular_velocity = Omega + n_Omega`` (bias removed, as PX4's
  vehicle_angular_velocity after the EKF's bias estimate).

Presets:

* ``"none"``: exact measurements, every control step.
* ``"seed000"``: Table 2 of Wang et al. (2024), P_b = 3e-8, P_v = 3e-7, P_R = 3e-8, P_Omega = 3e-7 (also used
  for the gyro); accelerometer and magnetometer as ``"mocap_imu"``; no biases; pose every step.
* ``"mocap_imu"``: a VICON-fed PX4 as in Wang et al. (2024), Sec. 7: pose at 100 Hz with 0.5 mm / 0.1 deg
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

from fawtgym.core import measurement as M
from fawtgym.core.so3 import exp_so3_floats, matmul33_floats

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


def allowed_control_rates(pose_rate: float, physics_rate: float) -> list[float]:
    """Control rates [Hz] that a sensor with ``pose_rate`` allows under ``physics_rate``: the multiples of the pose
    rate that divide the physics rate, ascending; empty if the pose rate does not divide the physics rate."""
    m = physics_rate / pose_rate
    if m < 1.0 - 1e-9 or abs(m - round(m)) > 1e-6:
        return []
    m = int(round(m))
    return [pose_rate * d for d in range(1, m + 1) if m % d == 0]


def pose_rate_error(spec: SensorSpec, control_rate: float, physics_rate: float | None) -> str:
    """The one-line message for a control rate that the pose rate of ``spec`` does not divide: names the preset
    and the control rates allowed with it (given the physics rate when known)."""
    pose = spec.pose_rate
    head = (f"sensor preset {spec.name!r}: sensor pose_rate {pose} Hz must divide the control rate "
            f"{control_rate:g} Hz; allowed: ")
    if physics_rate is None:
        return head + f"multiples of {pose:g} Hz that divide the physics rate"
    rates = allowed_control_rates(pose, physics_rate)
    if not rates:
        return head + (f"none with physics_rate {physics_rate:g} Hz, which {pose:g} Hz does not divide "
                       "(choose a physics rate that is a multiple of the pose rate)")
    listed = ", ".join(f"{r:g}" for r in rates[:24]) + (", ..." if len(rates) > 24 else "")
    return head + f"multiples of {pose:g} Hz that divide the physics rate {physics_rate:g} Hz: {listed}"


class SensorModel:
    """Turns the true state into a measurement mapping, for one vehicle, at the control rate.

    ``physics_dt`` (optional) is only used to list the allowed control rates when the pose rate does not divide
    the control rate.
    """

    def __init__(self, spec: SensorSpec, control_dt: float, physics_dt: float | None = None) -> None:
        self.spec = spec
        self.dt = control_dt
        if spec.pose_rate is None:
            self.pose_every = 1
        else:
            ratio = 1.0 / (spec.pose_rate * control_dt)
            if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
                raise ValueError(pose_rate_error(spec, 1.0 / control_dt,
                                                 None if physics_dt is None else 1.0 / physics_dt))
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
        self.gyro_bias = rng.normal(0.0, self.spec.gyro_bias_sigma, 3) if self.spec.gyro_bias_sigma else np.zeros(3)
        self.accel_bias = rng.normal(0.0, self.spec.accel_bias_sigma, 3) if self.spec.accel_bias_sigma else np.zeros(3)
        self._pose: tuple[list[float], list[float], tuple[float, ...]] | None = None
        self._count = 0

    @property
    def gyro_bias(self) -> NDArray[np.float64]:
        """Gyroscope turn-on bias [rad/s] (3,), drawn at :meth:`reset`; assign to set it (e.g. a bias sweep)."""
        return np.array(self._gyro_bias)

    @gyro_bias.setter
    def gyro_bias(self, value: Any) -> None:
        self._gyro_bias = _bias("gyro_bias", value)

    @property
    def accel_bias(self) -> NDArray[np.float64]:
        """Accelerometer turn-on bias [m/s^2] (3,), drawn at :meth:`reset`; assign to set it."""
        return np.array(self._accel_bias)

    @accel_bias.setter
    def accel_bias(self, value: Any) -> None:
        self._accel_bias = _bias("accel_bias", value)

    def measure(self, t: float, position: NDArray[np.float64], velocity: NDArray[np.float64],
                rotation: NDArray[np.float64], angular_velocity: NDArray[np.float64],
                acceleration: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Measurement at time ``t`` from the true state (arrays) and NED acceleration."""
        lists = self.measure_floats(np.ravel(position).tolist(), np.ravel(velocity).tolist(),
                                    np.ravel(rotation).tolist(), np.ravel(angular_velocity).tolist(),
                                    np.ravel(acceleration).tolist())
        return as_measurement(lists, t)

    def measure_floats(self, b: list[float], v: list[float], r: list[float], w: list[float],
                       acc: list[float]) -> tuple[list[float], ...]:
        """:meth:`measure` in float arithmetic (the env's hot path): state as lists (``r``: R row-major, 9),
        returns ``(position, velocity, attitude (9, row-major), angular_velocity, specific_force, gyro,
        magnetometer)`` as fresh lists; :func:`as_measurement` turns them into the measurement mapping."""
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = r
        # body-frame vectors R^T (a - g e3) and R^T m_E
        ax, ay, az = acc[0], acc[1], acc[2] - GRAVITY
        f_sp = [r0 * ax + r3 * ay + r6 * az, r1 * ax + r4 * ay + r7 * az, r2 * ax + r5 * ay + r8 * az]
        mx, my, mz = _FIELD
        mag = [r0 * mx + r3 * my + r6 * mz, r1 * mx + r4 * my + r7 * mz, r2 * mx + r5 * my + r8 * mz]
        if not self.noisy:
            return list(b), list(v), list(r), list(w), f_sp, list(w), mag
        n = self.rng.normal(size=18).tolist()
        if self._pose is None or self._count % self.pose_every == 0:
            sp, sv, st = self.sig_pos, self.sig_vel, self.sig_att
            self._pose = ([b[0] + sp * n[0], b[1] + sp * n[1], b[2] + sp * n[2]],
                          [v[0] + sv * n[3], v[1] + sv * n[4], v[2] + sv * n[5]],
                          matmul33_floats(r, exp_so3_floats(st * n[6], st * n[7], st * n[8])))
        self._count += 1
        sr, sa, sg = self.sig_rate, self.sig_acc, self.sig_gyro
        ba, bg = self._accel_bias, self._gyro_bias
        m = self.rng.normal(size=3).tolist()
        sm = self.spec.mag_sigma
        pos, vel, att = self._pose
        return (list(pos), list(vel), list(att),
                [w[0] + sr * n[9], w[1] + sr * n[10], w[2] + sr * n[11]],
                [f_sp[0] + ba[0] + sa * n[12], f_sp[1] + ba[1] + sa * n[13], f_sp[2] + ba[2] + sa * n[14]],
                [w[0] + bg[0] + sg * n[15], w[1] + bg[1] + sg * n[16], w[2] + bg[2] + sg * n[17]],
                [mag[0] + sm * m[0], mag[1] + sm * m[1], mag[2] + sm * m[2]])


_FIELD = tuple(M.EARTH_FIELD_NED.tolist())


def _bias(name: str, value: Any) -> list[float]:
    b = np.array(value, dtype=float)
    if b.shape != (3,) or not np.all(np.isfinite(b)):
        raise ValueError(f"{name} must be 3 finite values, got {value!r}")
    return b.tolist()


def as_measurement(lists: tuple[list[float], ...], t: float) -> dict[str, NDArray[np.float64]]:
    """The measurement mapping (fresh arrays) from :meth:`SensorModel.measure_floats`' lists."""
    pos, vel, att, rate, f_sp, gyro, mag = lists
    return {M.POSITION: np.array(pos), M.VELOCITY: np.array(vel), M.ATTITUDE: np.array(att).reshape(3, 3),
            M.ANGULAR_VELOCITY: np.array(rate), M.SPECIFIC_FORCE: np.array(f_sp), M.GYRO: np.array(gyro),
            M.MAGNETOMETER: np.array(mag), M.TIME: np.asarray(float(t))}
