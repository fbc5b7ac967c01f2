"""Sensor presets (noise, rates) and the single-vehicle view of the sensor law (:mod:`.sensors_batch`).

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
from fawtgym.core.checks import check_number, listed, shown

#: The physical range of each :class:`SensorSpec` field: (lowest, highest, unit), lowest inclusive.  Every range spans
#: orders of magnitude beyond the presets (a consumer IMU's gyro density is ~1e-3 (rad/s)/sqrt(Hz)); beyond it a value
#: is a typo or a unit slip and the samples overflow (an attitude sigma of 1e300 rad) or the reward does.
#: ``pose_rate`` may also be None (every control step).
FIELD_RANGES: dict[str, tuple[float, float, str]] = {
    "position_density": (0.0, 10.0, "m/sqrt(Hz)"),
    "velocity_density": (0.0, 10.0, "(m/s)/sqrt(Hz)"),
    "attitude_density": (0.0, 1.0, "rad/sqrt(Hz)"),
    "angular_velocity_density": (0.0, 10.0, "(rad/s)/sqrt(Hz)"),
    "position_sigma": (0.0, 100.0, "m"),
    "velocity_sigma": (0.0, 100.0, "m/s"),
    "attitude_sigma": (0.0, math.pi, "rad"),
    "gyro_density": (0.0, 10.0, "(rad/s)/sqrt(Hz)"),
    "accel_density": (0.0, 100.0, "(m/s^2)/sqrt(Hz)"),
    "mag_sigma": (0.0, 10.0, "gauss"),
    "gyro_bias_sigma": (0.0, 10.0, "rad/s"),
    "accel_bias_sigma": (0.0, 100.0, "m/s^2"),
    "pose_rate": (0.01, 1e5, "Hz"),
}


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
        for field, (lowest, highest, unit) in FIELD_RANGES.items():
            v = getattr(self, field)
            if v is None and field == "pose_rate":
                continue
            # any real number (numpy scalars too, stored as float); bool, str, None and complex are refused
            v = check_number(v, f"sensor field {field!r}", minimum=lowest, maximum=highest, inclusive_minimum=True,
                             note=unit + (" or None" if field == "pose_rate" else ""))
            object.__setattr__(self, field, v)


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
    """A :class:`SensorSpec` from a preset name, a spec, or ``{"base": preset, field: value, ...}``."""
    if isinstance(spec, SensorSpec):
        return spec
    if isinstance(spec, Mapping):
        data = dict(spec)
        base = data.pop("base", "none")
        fields = [f.name for f in dataclasses.fields(SensorSpec)]
        unknown = [k for k in data if k not in fields]
        if unknown:
            raise ValueError(f"unknown sensor field(s) {listed(unknown)}; valid: ['base', {str(fields)[1:]}")
        return dataclasses.replace(make_sensor_spec(base), **data)
    if isinstance(spec, str) and spec in SENSOR_PRESETS:
        return SENSOR_PRESETS[spec]
    raise ValueError(f"unknown sensor preset {shown(spec)}; valid: {list(SENSOR_PRESETS)} (or a SensorSpec/mapping)")


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
    if pose is None:
        raise ValueError(f"sensor preset {shown(spec.name)} has no pose_rate: every control rate is allowed")
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


def _batch_sigma(name: str) -> property:
    """The batch model's per-sample sigma ``name`` (read-only: assigning raises, as there)."""
    def get(self: Any) -> float:
        return float(getattr(self._batch, name))

    def put(self: Any, value: object) -> None:
        setattr(self._batch, name, value)  # raises (fixed at construction)

    return property(get, put, doc=f"per-sample sigma ({name}) of the batch model; read-only")


class SensorModel:
    """One vehicle's sensors: :class:`~fawtgym.envs.sensors_batch.BatchSensorModel` (the one law) as a batch of one,
    with 1-D arrays in and out.

    ``physics_dt`` (optional) is only used to list the allowed control rates when the pose rate does not divide
    the control rate.
    """

    def __init__(self, spec: SensorSpec, control_dt: float, physics_dt: float | None = None) -> None:
        from .sensors_batch import BatchSensorModel  # the law's module imports this one's specs

        self._batch = BatchSensorModel(spec, control_dt, 1, physics_dt)
        b = self._batch
        self.spec, self.dt, self.noisy = b.spec, b.dt, b.noisy

    sig_pos, sig_vel, sig_att = _batch_sigma("sig_pos"), _batch_sigma("sig_vel"), _batch_sigma("sig_att")
    sig_rate, sig_acc, sig_gyro = _batch_sigma("sig_rate"), _batch_sigma("sig_acc"), _batch_sigma("sig_gyro")
    sig_mag = _batch_sigma("sig_mag")

    @property
    def pose_every(self) -> int:
        """Control steps per pose sample (the batch model's; read-only: assigning raises)."""
        return self._batch.pose_every

    @pose_every.setter
    def pose_every(self, value: object) -> None:
        self._batch.pose_every = value  # raises (fixed at construction)

    def reset(self, rng: np.random.Generator) -> None:
        """A new episode: turn-on biases from ``rng``, which then draws the per-step noise too (the batch model's
        draws at N = 1: ``standard_normal((1, 21))`` per step)."""
        self.rng = rng
        self._batch.set_noise_rng(rng)
        self._batch.reset_rows(np.zeros(1, dtype=np.intp), [rng])

    @property
    def gyro_bias(self) -> NDArray[np.float64]:
        """Gyroscope turn-on bias [rad/s] (3,), drawn at :meth:`reset`; assign to set it (e.g. a bias sweep)."""
        return self._batch.gyro_bias[0].copy()

    @gyro_bias.setter
    def gyro_bias(self, value: Any) -> None:
        self._batch.gyro_bias = _bias("gyro_bias", value)

    @property
    def accel_bias(self) -> NDArray[np.float64]:
        """Accelerometer turn-on bias [m/s^2] (3,), drawn at :meth:`reset`; assign to set it."""
        return self._batch.accel_bias[0].copy()

    @accel_bias.setter
    def accel_bias(self, value: Any) -> None:
        self._batch.accel_bias = _bias("accel_bias", value)

    def measure(self, t: float, position: NDArray[np.float64], velocity: NDArray[np.float64],
                rotation: NDArray[np.float64], angular_velocity: NDArray[np.float64],
                acceleration: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Measurement at time ``t`` from the true state (position (3,), velocity (3,), rotation (3, 3), body rate
        (3,)) and the NED acceleration (3,): the batch law's row 0."""
        rows = self._batch.measure(np.array([t], dtype=float), *(np.asarray(x)[None] for x in (
            position, velocity, rotation, angular_velocity, acceleration)))
        out = {key: value[0] for key, value in rows.items()}
        out[M.TIME] = np.asarray(float(t))
        return out


def _bias(name: str, value: Any) -> NDArray[np.float64]:
    try:
        raw = np.asarray(value)
    except ValueError:  # ragged nested sequences
        raw = np.asarray(None)
    b = raw.astype(np.float64) if raw.dtype.kind in "iuf" else np.full(1, np.nan)  # bool/complex/str refused
    if b.shape != (3,) or not np.all(np.isfinite(b)):
        raise ValueError(f"{name} must be 3 finite real numbers, got {shown(value)}")
    return b
