"""The sensor law: N vehicles' measurements at the control rate, one compiled kernel over rows.

Noise model and presets: :mod:`fawtgym.envs.sensors`.  Per row: the pose group (position, velocity,
attitude) is sampled and held every ``pose_every`` control steps (counted from that vehicle's own
episode start), the IMU group every step, with constant turn-on biases drawn per vehicle at its reset::

    position = b + sigma_p n_p,  velocity = v + sigma_v n_v,  attitude = R exp((sigma_R n_R)^x)   (Wang 2024, eq. 39)
    angular_velocity = Omega + sigma_Omega n_Omega             (estimator grade: bias removed)
    specific_force   = R^T (a - g e3) + b_a + sigma_a n_a
    gyro             = Omega + b_g + sigma_g n_g
    magnetometer     = R^T m_E + sigma_m n_m

Random streams.  Per-step noise for all N rows comes from one generator, ``standard_normal((N, 21))`` per step
(columns: n_p, n_v, n_R, n_Omega, n_a, n_g, n_m), so one row's trajectory never changes how many numbers another
row consumes (rows stay independent).  The turn-on biases of a row are drawn from that row's own generator
(passed to :meth:`BatchSensorModel.reset_rows`).  With N = 1 and the row's generator as the noise generator,
this is the single-vehicle model (:class:`fawtgym.envs.sensors.SensorModel`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core import measurement as M
from fawtgym.core.arrays import ReadOnlyState, as_f64, read_only
from fawtgym.core.checks import shown
from fawtgym.core.normals import standard_normals
from fawtgym.core.so3_kernels import exp_so3_row, mat_mul_row

from .sensors import SensorSpec, make_sensor_spec, pose_rate_error
from .vehicles import GRAVITY

_FIELD = np.ascontiguousarray(M.EARTH_FIELD_NED, dtype=float)
#: the error of a measurement that is not finite (the same at every N, whoever calls the kernel)
SENSOR_NOT_FINITE = ("sensor measurement is not finite: check position, velocity, rotation, angular_velocity and "
                     "acceleration for NaN/inf")

#: the entries of :attr:`BatchSensorModel.sigma`, each also a read-only attribute (e.g. ``sig_pos``)
SIGMA_FIELDS = ("sig_pos", "sig_vel", "sig_att", "sig_rate", "sig_acc", "sig_gyro", "sig_mag")


class _SigmaEntry:
    """A read-only attribute reading one entry of the owner's ``sigma`` (fixed at construction: assigning raises)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name, self.index = name, SIGMA_FIELDS.index(name)

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        return self if obj is None else float(obj.sigma[self.index])

    def __set__(self, obj: Any, value: object) -> None:
        raise AttributeError(_FIXED.format(self.name))


#: the error of assigning kernel state (the compiled kernels trust its shape and dtype)
_KERNEL_STATE = ("BatchSensorModel.{name} is the sensor kernel's state (read-only): set the turn-on biases through "
                 "gyro_bias / accel_bias (or a randomizer's gyro_bias / accel_bias draws); the rest follows from reset")
#: the error of assigning a sensor setting fixed at construction
_FIXED = ("BatchSensorModel.{} is fixed at construction (derived from the sensor spec, copied into the env's step "
          "parameters): build the sensors (or the env, sensors=...) with a SensorSpec or a mapping of its fields "
          "instead")


@njit(cache=True)
def measure_rows(position: NDArray[np.float64], velocity: NDArray[np.float64], rotation: NDArray[np.float64],
                 rate: NDArray[np.float64], accel: NDArray[np.float64], z: NDArray[np.float64],
                 sigma: NDArray[np.float64], field: NDArray[np.float64], state: NDArray[np.float64],
                 count: NDArray[np.int64], pose_every: int, out_pos: NDArray[np.float64],
                 out_vel: NDArray[np.float64], out_att: NDArray[np.float64],
                 out_rate: NDArray[np.float64], out_fsp: NDArray[np.float64], out_gyro: NDArray[np.float64],
                 out_mag: NDArray[np.float64]) -> int:
    """Every row's measurement (module docstring) into the ``out_*`` arrays; returns -1, or the first row whose
    measurement is not finite (NaN/inf in its state).

    ``sigma`` = (position, velocity, attitude, angular_velocity, accelerometer, gyro, magnetometer) per-sample
    sigmas; ``z`` (N, 21) the step's normals; ``state`` (N, 21) per row the held pose sample (position 0-2, velocity
    3-5, attitude 6-14 row-major) and the turn-on biases (gyro 15-17, accelerometer 18-20): the pose hold and
    ``count`` are updated in place.
    """
    s_pos, s_vel, s_att, s_rate, s_acc, s_gyro, s_mag = (sigma[0], sigma[1], sigma[2], sigma[3], sigma[4],
                                                         sigma[5], sigma[6])
    delta, noise_rot, att = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    for i in range(position.shape[0]):
        r = rotation[i]
        if count[i] % pose_every == 0:  # pose group: a new sample, held until the next one
            for c in range(3):
                state[i, c] = position[i, c] + s_pos * z[i, c]
                state[i, 3 + c] = velocity[i, c] + s_vel * z[i, 3 + c]
                delta[c] = s_att * z[i, 6 + c]
            exp_so3_row(delta, noise_rot)
            mat_mul_row(r, noise_rot, att)  # attitude noise R exp(Delta^x) (Wang 2024, eq. 39)
            for c in range(3):
                for k in range(3):
                    state[i, 6 + 3 * c + k] = att[c, k]
        count[i] += 1
        ax, ay, az = accel[i, 0], accel[i, 1], accel[i, 2] - GRAVITY  # a - g e3 (NED)
        for c in range(3):
            f_sp = r[0, c] * ax + r[1, c] * ay + r[2, c] * az  # R^T (a - g e3)
            mag = r[0, c] * field[0] + r[1, c] * field[1] + r[2, c] * field[2]  # R^T m_E
            out_pos[i, c] = state[i, c]
            out_vel[i, c] = state[i, 3 + c]
            out_rate[i, c] = rate[i, c] + s_rate * z[i, 9 + c]
            out_fsp[i, c] = f_sp + state[i, 18 + c] + s_acc * z[i, 12 + c]  # + accelerometer bias
            out_gyro[i, c] = rate[i, c] + state[i, 15 + c] + s_gyro * z[i, 15 + c]  # + gyro bias
            out_mag[i, c] = mag + s_mag * z[i, 18 + c]
            for k in range(3):
                out_att[i, c, k] = state[i, 6 + 3 * c + k]
        total = 0.0
        for c in range(3):
            total += (out_pos[i, c] + out_vel[i, c] + out_rate[i, c] + out_fsp[i, c] + out_gyro[i, c] + out_mag[i, c]
                      + out_att[i, c, 0] + out_att[i, c, 1] + out_att[i, c, 2])
        if not math.isfinite(total):
            return i
    return -1


class BatchSensorModel:
    """Measurements of N vehicles (batch-first) at the control rate; see the module docstring.

    ``physics_dt`` (optional) is only used to list the allowed control rates when the pose rate does not divide
    the control rate.
    """

    #: the per-sample sigmas, one float each (the entries of :attr:`sigma`; read-only)
    sig_pos, sig_vel, sig_att = _SigmaEntry(), _SigmaEntry(), _SigmaEntry()
    sig_rate, sig_acc, sig_gyro, sig_mag = _SigmaEntry(), _SigmaEntry(), _SigmaEntry(), _SigmaEntry()

    def __init__(self, spec: SensorSpec | str, control_dt: float, n: int, physics_dt: float | None = None) -> None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"number of vehicles n must be a positive int, got {shown(n)}")
        self.spec = spec = make_sensor_spec(spec)
        self.dt = control_dt
        self.n = int(n)
        if spec.pose_rate is None:
            self._pose_every = 1
        else:
            ratio = 1.0 / (spec.pose_rate * control_dt)
            if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
                raise ValueError(pose_rate_error(spec, 1.0 / control_dt,
                                                 None if physics_dt is None else 1.0 / physics_dt))
            self._pose_every = int(round(ratio))
        # white noise of density d sampled every dt has sigma d / sqrt(dt) (sensors module docstring)
        root_dt, root_pose = math.sqrt(control_dt), math.sqrt(self._pose_every * control_dt)
        sigma = np.array([math.hypot(spec.position_density / root_pose, spec.position_sigma),
                          math.hypot(spec.velocity_density / root_pose, spec.velocity_sigma),
                          math.hypot(spec.attitude_density / root_pose, spec.attitude_sigma),
                          spec.angular_velocity_density / root_dt, spec.accel_density / root_dt,
                          spec.gyro_density / root_dt, spec.mag_sigma])  # SIGMA_FIELDS' order
        sigma.flags.writeable = False  # fixed by the spec (the env copies it into its step parameters)
        self._sigma = sigma
        self.noisy = bool(np.any(sigma > 0) or spec.gyro_bias_sigma > 0 or spec.accel_bias_sigma > 0)
        #: per row: the held pose sample (position 3, velocity 3, attitude 9) and the turn-on biases (gyro 3,
        #: accelerometer 3), one (N, 21) array (the kernel's one argument; the properties below are views of it)
        self._state = np.zeros((self.n, 21))
        self._state[:, 6:15] = np.eye(3).ravel()
        #: steps since each row's episode start (the pose hold's clock), updated in place by the kernel
        self._count = np.zeros(self.n, dtype=np.int64)
        #: exact sensors: the kernel reads zero normals (never written)
        self._no_noise = np.zeros((self.n, 21))
        self.rng = np.random.default_rng(0)

    @property
    def pose_every(self) -> int:
        """Control steps per pose sample (from the spec's ``pose_rate``); read-only."""
        return self._pose_every

    @pose_every.setter
    def pose_every(self, value: object) -> None:
        raise AttributeError(_FIXED.format("pose_every"))

    @property
    def sigma(self) -> NDArray[np.float64]:
        """The per-sample sigmas of :func:`measure_rows` (position, velocity, attitude, rate, accel, gyro, mag), (7,)
        read-only (derived from the spec's densities and ``pose_every``)."""
        view = self._sigma.view()
        view.flags.writeable = False  # (a copy of the model, e.g. deepcopy, would hold a writeable one)
        return view

    @sigma.setter
    def sigma(self, value: object) -> None:
        raise AttributeError(_FIXED.format("sigma"))

    state = ReadOnlyState("Per row the held pose sample (position 3, velocity 3, attitude 9) and the turn-on biases "
                          "(gyro 3, accelerometer 3), (N, 21): a read-only view of the kernel's state (set the biases "
                          "through :attr:`gyro_bias` / :attr:`accel_bias`; the pose hold is the kernel's).",
                          _KERNEL_STATE)
    count = ReadOnlyState("Steps since each row's episode start (N,) (the pose hold's clock): a read-only view.",
                          _KERNEL_STATE)
    no_noise = ReadOnlyState("The zero normals (N, 21) the kernel reads for exact sensors: a read-only view.",
                             _KERNEL_STATE)

    @property
    def pose_pos(self) -> NDArray[np.float64]:
        """The held position samples (N, 3) (a read-only view of :attr:`state`)."""
        return read_only(self._state[:, 0:3])

    @property
    def pose_vel(self) -> NDArray[np.float64]:
        """The held velocity samples (N, 3) (a read-only view of :attr:`state`)."""
        return read_only(self._state[:, 3:6])

    @property
    def pose_att(self) -> NDArray[np.float64]:
        """The held attitude samples (N, 3, 3) (a read-only view of :attr:`state`)."""
        return read_only(self._state[:, 6:15].reshape(self.n, 3, 3))

    @property
    def gyro_bias(self) -> NDArray[np.float64]:
        """Turn-on gyro biases (N, 3) [rad/s] (a read-only view of :attr:`state`); assign (3,) or (N, 3) finite
        values (checked)."""
        return read_only(self._state[:, 15:18])

    @gyro_bias.setter
    def gyro_bias(self, value: Any) -> None:
        self._state[:, 15:18] = self._bias("gyro_bias", value)

    @property
    def accel_bias(self) -> NDArray[np.float64]:
        """Turn-on accelerometer biases (N, 3) [m/s^2] (a read-only view of :attr:`state`); assign (3,) or (N, 3)
        finite values (checked)."""
        return read_only(self._state[:, 18:21])

    @accel_bias.setter
    def accel_bias(self, value: Any) -> None:
        self._state[:, 18:21] = self._bias("accel_bias", value)

    def set_bias_rows(self, rows: NDArray[np.intp], gyro: NDArray[np.float64] | None = None,
                      accel: NDArray[np.float64] | None = None) -> None:
        """Turn-on biases of ``rows`` (k,): ``gyro`` / ``accel`` (k, 3) finite (the caller checked them)."""
        if gyro is not None:
            self._state[rows, 15:18] = gyro
        if accel is not None:
            self._state[rows, 18:21] = accel

    def _bias(self, name: str, value: Any) -> NDArray[np.float64]:
        try:
            raw = np.asarray(value)
        except ValueError:  # ragged nested sequences
            raw = np.asarray(None)
        b = raw.astype(np.float64) if raw.dtype.kind in "iuf" else np.full(1, np.nan)  # bool/complex/str refused
        if b.shape not in ((3,), (self.n, 3)) or not np.all(np.isfinite(b)):
            raise ValueError(f"{name} must be 3 finite real numbers or ({self.n}, 3), got {shown(value)}")
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
            self._state[row, 15:18] = rng.normal(0.0, sg, 3) if sg else 0.0
            self._state[row, 18:21] = rng.normal(0.0, sa, 3) if sa else 0.0
        self._count[rows] = 0

    def measure(self, t: NDArray[np.float64], position: NDArray[np.float64], velocity: NDArray[np.float64],
                rotation: NDArray[np.float64], angular_velocity: NDArray[np.float64],
                acceleration: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Measurements (N, ...) at times ``t`` (N,) from true states (N, 3) / (N, 3, 3) and NED accelerations.

        Every array handed out is a fresh C-contiguous array.
        """
        return self._measure(None, self.noise(), t, position, velocity, rotation, angular_velocity, acceleration)

    def noise(self) -> NDArray[np.float64]:
        """One step's normals of every row, (N, 21) (module docstring's columns) from the noise generator (the
        numbers of ``rng.standard_normal((N, 21))``, a fresh array: :func:`fawtgym.core.normals.standard_normals`);
        the zeros :attr:`no_noise` (nothing drawn) for exact sensors.  What :meth:`measure` draws: the env draws it
        and runs the kernel in its own step kernel (:func:`fawtgym.envs.step_kernels.observe_rows`)."""
        return standard_normals(self.rng, (self.n, 21)) if self.noisy else self._no_noise

    def measure_rows(self, rows: NDArray[np.intp], rngs: list[np.random.Generator], t: NDArray[np.float64],
                     position: NDArray[np.float64], velocity: NDArray[np.float64], rotation: NDArray[np.float64],
                     angular_velocity: NDArray[np.float64], acceleration: NDArray[np.float64]
                     ) -> dict[str, NDArray[np.float64]]:
        """The measurement of ``rows`` only (their true states, (k, ...)), each row's noise from its own generator
        ``rngs[j]`` (21 normals); the other rows' state (pose hold, counters, noise stream) is untouched."""
        rows = np.asarray(rows, dtype=np.intp)
        if len(rngs) != rows.size:
            raise ValueError(f"need one generator per measured row: {rows.size} rows, {len(rngs)} generators")
        if self.noisy:
            z = np.stack([g.standard_normal(21) for g in rngs]) if rngs else np.zeros((0, 21))
        else:
            z = np.zeros((rows.size, 21))
        return self._measure(rows, z, t, position, velocity, rotation, angular_velocity, acceleration)

    def _measure(self, rows: NDArray[np.intp] | None, z: NDArray[np.float64], t: NDArray[np.float64],
                 position: NDArray[np.float64], velocity: NDArray[np.float64], rotation: NDArray[np.float64],
                 angular_velocity: NDArray[np.float64], acceleration: NDArray[np.float64]
                 ) -> dict[str, NDArray[np.float64]]:
        """The kernel on ``rows`` (None: every row, the model's own state in place; else their state, written back)."""
        every = rows is None
        n = self.n if rows is None else rows.size
        position, velocity = as_f64(position, "position"), as_f64(velocity, "velocity")
        rotation, angular_velocity = as_f64(rotation, "rotation"), as_f64(angular_velocity, "angular_velocity")
        acceleration = as_f64(acceleration, "acceleration")
        if (position.shape != (n, 3) or velocity.shape != (n, 3) or rotation.shape != (n, 3, 3)
                or angular_velocity.shape != (n, 3) or acceleration.shape != (n, 3)):
            raise ValueError(f"sensor inputs must be position, velocity, angular_velocity, acceleration (N, 3) and "
                             f"rotation (N, 3, 3) with N = {n}; got {position.shape}, {velocity.shape}, "
                             f"{angular_velocity.shape}, {acceleration.shape}, {rotation.shape}")
        pose_every = self.pose_every if self.noisy else 1  # exact measurements every step (no hold without noise)
        state = self._state if every else self._state[rows]  # the rows' copy, written back below
        count = self._count if every else self._count[rows]
        e = np.empty
        out = {M.POSITION: e((n, 3)), M.VELOCITY: e((n, 3)), M.ATTITUDE: e((n, 3, 3)), M.ANGULAR_VELOCITY: e((n, 3)),
               M.SPECIFIC_FORCE: e((n, 3)), M.GYRO: e((n, 3)), M.MAGNETOMETER: e((n, 3)),
               M.TIME: np.array(t, dtype=float)}
        if measure_rows(position, velocity, rotation, angular_velocity, acceleration, z, self.sigma, _FIELD,
                        state, count, pose_every, out[M.POSITION], out[M.VELOCITY], out[M.ATTITUDE],
                        out[M.ANGULAR_VELOCITY],
                        out[M.SPECIFIC_FORCE], out[M.GYRO], out[M.MAGNETOMETER]) >= 0:
            raise ValueError(SENSOR_NOT_FINITE)
        if rows is not None:
            self._count[rows] = count
            self._state[rows] = state
        return out
