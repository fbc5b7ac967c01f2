"""PX4-style cascaded flight control as an agent, with optional disturbance-observer feedforward.

``PX4Agent`` runs PX4's multicopter cascade (v1.13: mc_pos_control -> mc_att_control ->
mc_rate_control -> control_allocator) on the env's measurements and outputs the env's ``"motors"``
action.  ``PX4ObserverAgent`` adds the feedforward of Wang et al. (2024) Sec. 7.2

    F = F0 - phi_hat       (position loop output: thr <- thr0 - phi_hat / thrust_scale, before thrust -> attitude)
    tau = tau0 - tau_hat   (rate loop output:     c_tau <- c_tau0 - tau_hat / torque_scale)

where ``phi_hat`` [N, world NED] and ``tau_hat`` [N m, body FRD] come from any registered observer and
``thrust_scale`` [N per unit] = ``4 T_max`` and ``torque_scale`` [N m per unit] = ``(2 l T_max, 2 l T_max,
4 k_M T_max)`` are derived from the vehicle preset in :mod:`fawtgym.agents.px4_allocation`.  The
feedforward thrust vector is tilt- and magnitude-limited like PX4's own (``MPC_TILTMAX_AIR``,
``MPC_THR_MIN/MAX``).  PX4's internal state (velocity integrator, its anti-windup, the hover-thrust
estimator) sees only the baseline ``F0``, as in the paper's "additional term" on top of unchanged PX4.

Loop rates.  ``act`` is called once per env step (``control_rate`` Hz, the env's control rate).
The rate loop, attitude loop and position loop each run when their own period has elapsed
(``rate_loop_rate``, ``attitude_rate``, ``position_rate``; each must be <= ``control_rate``) with the
true elapsed time as dt, the way PX4's modules run on their input topics.  Defaults: rate and attitude
loops at the control rate (PX4 runs both at the gyro rate, 400 Hz by ``IMU_GYRO_RATEMAX``; the
default 250 Hz divides the env's 1 kHz physics), position loop at 100 Hz (EKF2's output rate, PX4
v1.13).  The gyro is low-passed by a 2nd-order Butterworth at ``IMU_GYRO_CUTOFF`` and the rate D term
uses the Butterworth-filtered (``IMU_DGYRO_CUTOFF``) derivative of the raw gyro, as PX4's
VehicleAngularVelocity; the velocity D term uses a 5 Hz (``MPC_VELD_LP``) filtered derivative.

Hover thrust.  Initialized from the preset, ``Th = m g / (4 T_max)`` (0.275 for the s500; pass
``hover_thrust=`` for another value, e.g. ``params["MPC_THR_HOVER"]``) and, with ``MPC_USE_HTE = 1``
(PX4's default), re-estimated online by PX4's hover-thrust EKF (:mod:`fawtgym.agents.px4_hover_thrust`)
from the accelerometer and the baseline thrust setpoint; the initial value is also the EKF's ``MPC_THR_HOVER``
(bounds ``+- HTE_THR_RANGE``), and only estimates PX4 flags valid reach the position controller.
``px4_version`` ("1.13", the paper's, or "1.14") selects the position law's version differences
(:mod:`fawtgym.agents.px4_position_control`).

What the controller knows (:mod:`fawtgym.agents.observer_inputs`).  ``pose_latency`` [s] delays the pose
(position, velocity, attitude) it sees, as a motion-capture link does (default 0: the env's pose as is).
``observer_inputs`` chooses the observer's known thrust and torque: ``"applied"`` (default; the env's exact
applied wrench after motor lag, truth) or ``"commanded"`` (the controller's own commanded rotor thrusts
through its thrust model, off by the relative ``thrust_model_error``), what a real flight controller has.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.arrays import REAL_KINDS, as_array
from fawtgym.core.checks import check_flag, check_number, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.frames import FAWT_HOVER_POINT_NED
from fawtgym.core.rows import check_row_mask
from fawtgym.envs.motors import allocation_matrix
from fawtgym.envs.options import MAX_SETPOINT
from fawtgym.envs.vehicles import VehiclePreset, make_vehicle

from . import px4_cascade as C
from .base import Agent, applied_from_info, measurement_from_info, refuse_measurement
from .observer_inputs import (
    OBSERVER_INPUTS,
    POSE_KEYS,
    PoseDelay,
    check_thrust_model_error,
    commanded_wrench,
    latency_steps,
)
from .px4_allocation import QuadXAllocation
from .px4_attitude_control import AttitudeControl
from .px4_filters import butterworth_coefficients
from .px4_hover_thrust import HoverThrustEstimator
from .px4_params import PX4Params
from .px4_position_control import PositionControl
from .px4_rate_control import RateControl
from .shared_params import InPlaceArray

#: the control rates an agent takes [Hz] (PX4's slowest multicopter loop runs at tens of Hz, its fastest at kHz)
MIN_CONTROL_RATE, MAX_CONTROL_RATE = 1.0, 1e5


def _rate(name: str, value: float | None, default: float, control_rate: float) -> float:
    """A loop rate [Hz] in (0, control_rate] (None: ``default``); one-line ValueError naming it otherwise."""
    if value is None:
        return default
    v = check_number(value, name, minimum=0.0, maximum=control_rate * (1 + 1e-9), note=f"Hz (control_rate: "
                     f"{control_rate:g} Hz)")
    return min(v, control_rate)


#: the measurement keys ``gyro_key`` may name: the estimator-grade body rate or the raw gyroscope (both (N, 3) rad/s)
GYRO_KEYS = ("angular_velocity", "gyro")


#: the largest heading setpoint magnitude an agent takes [rad]
MAX_YAW = 1e3


def _yaw(value: object) -> float:
    """A heading setpoint [rad]: a finite real number within +-:data:`MAX_YAW` (bool, str, complex, NaN refused with
    one line)."""
    return check_number(value, "yaw_setpoint", minimum=-MAX_YAW, inclusive_minimum=True, maximum=MAX_YAW,
                        note="rad (a heading)")


_F64 = np.dtype(np.float64)


def _checked_setpoint(value: Any, given: Any) -> NDArray[np.float64]:
    """An agent's own setpoint option: real NED coordinates [m] of shape (3,) or (N, 3), each within the env's
    :data:`~fawtgym.envs.options.MAX_SETPOINT`; one-line ValueError naming ``given`` otherwise."""
    a = as_array(value)
    if a.dtype.kind in REAL_KINDS and a.shape[-1:] == (3,) and a.ndim <= 2 and bool(np.all(np.abs(a) <= MAX_SETPOINT)):
        return a.astype(float)
    raise ValueError(f"setpoint must be real NED coordinates [m] of shape (3,) or (N, 3), each within "
                     f"{MAX_SETPOINT:g} m, got {shown(given)}")


def _setpoint_rows(sp: Any, n: int, who: str) -> NDArray[np.float64]:
    """``info["setpoint"]`` as the cascade takes it: a C-contiguous float64 (1, 3) array (one NED point for every row,
    a view when given as a (3,) float64 array) or (N, 3); ValueError naming it if it is not real or of another shape
    (its finiteness is the kernel's check: ``BAD_SETPOINT``)."""
    a = sp
    if type(a) is not np.ndarray or a.dtype is not _F64:
        a = as_array(sp)
        a = a.astype(float) if a.dtype.kind in REAL_KINDS else None
    if a is not None and a.shape == (3,):
        return np.ascontiguousarray(a[None])
    if a is not None and a.shape in ((1, 3), (n, 3)):
        return np.ascontiguousarray(a)
    shapes = "(3,) or (1, 3)" if n == 1 else f"(3,), (1, 3) or ({n}, 3)"
    raise ValueError(f"{who}: info['setpoint'] must be real NED coordinates [m] of shape {shapes}, got {shown(sp)}")


def _bad_setpoint_row(who: str, row: int, setpoint: NDArray[np.float64]) -> ValueError:
    """The error of a setpoint row the cascade refuses (``BAD_SETPOINT``: not finite or beyond ``MAX_SETPOINT``)."""
    return ValueError(f"{who}: info['setpoint'] row {row} is not finite NED coordinates [m] within {MAX_SETPOINT:g} m: "
                      f"{setpoint[row].tolist()}")


def _rows3(x: ArrayLike, n: int) -> NDArray[np.float64]:
    """``x`` as a C-contiguous float (n, 3) array (a (3,) vector is broadcast; no copy if it already is one)."""
    a = np.asarray(x, dtype=float)
    if a.shape != (n, 3):
        a = np.broadcast_to(a, (n, 3))
    return np.ascontiguousarray(a)


class PX4Agent(Agent):
    """PX4 v1.13-style position -> attitude -> rate -> allocation cascade holding a position setpoint.

    Parameters
    ----------
    vehicle: preset name / :class:`VehiclePreset` / mapping (must match the env's vehicle).
    params: :class:`PX4Params`, a mapping of overrides on the S500 set, a parameter file, or None (S500).
    control_rate: rate [Hz] at which ``act`` is called (the env's ``control_rate``).
    rate_loop_rate, attitude_rate, position_rate: loop rates [Hz] (defaults: control rate, control rate, 100).
    setpoint: NED hover position (default: the FAWT hover point).  ``info["setpoint"]`` (the env's set
        point), when present, is followed at every step unless :meth:`set_setpoint` was called.
    yaw_setpoint: heading [rad].
    hover_thrust: normalized hover thrust, or None to derive ``m g / (4 T_max)`` from the preset.
    gyro_key: measurement key of the (bias-corrected, unfiltered) gyro fed to the filters, one of
        :data:`GYRO_KEYS` (a measurement without it: ``angular_velocity``).
    px4_version: "1.13" (the paper's) or "1.14" (position-law differences, module docstring).
    pose_latency: delay [s] of the pose the controller sees (a multiple of the control period).
    observer_inputs: "applied" (exact applied wrench) or "commanded" (commanded thrust through a thrust model).
    thrust_model_error: relative error of that thrust model (the controller believes (1 + e) times its
        commanded rotor thrusts).
    """

    def __init__(self, vehicle: str | VehiclePreset | Mapping[str, Any] = "s500",
                 params: PX4Params | Mapping[str, Any] | str | None = None, control_rate: float = 250.0,
                 rate_loop_rate: float | None = None, attitude_rate: float | None = None,
                 position_rate: float | None = None, setpoint: ArrayLike | None = None, yaw_setpoint: float = 0.0,
                 hover_thrust: float | None = None, gyro_key: str = "angular_velocity",
                 px4_version: str = "1.13", pose_latency: float = 0.0, observer_inputs: str = "applied",
                 thrust_model_error: float = 0.0) -> None:
        self.preset = make_vehicle(vehicle)
        self.params = PX4Params.coerce(params)
        self.control_rate = check_number(control_rate, "control_rate", minimum=MIN_CONTROL_RATE, inclusive_minimum=True,
                                         maximum=MAX_CONTROL_RATE, note="Hz")
        self.dt = 1.0 / self.control_rate
        self.rate_loop_rate = _rate("rate_loop_rate", rate_loop_rate, self.control_rate, self.control_rate)
        self.attitude_rate = _rate("attitude_rate", attitude_rate, self.control_rate, self.control_rate)
        self.position_rate = _rate("position_rate", position_rate, min(100.0, self.control_rate), self.control_rate)
        self.allocation = QuadXAllocation(self.preset)
        if observer_inputs not in OBSERVER_INPUTS:
            raise ValueError(f"observer_inputs must be one of {list(OBSERVER_INPUTS)}, got {shown(observer_inputs)}")
        self.observer_inputs = observer_inputs
        self.thrust_model_error = check_thrust_model_error(thrust_model_error)
        self._pose_delay = PoseDelay(latency_steps(pose_latency, self.dt))
        self.pose_latency = float(pose_latency)
        self._alloc_matrix = allocation_matrix(self.preset)
        th = (self.preset.mass * GRAVITY / self.allocation.thrust_scale if hover_thrust is None else
              check_number(hover_thrust, "hover_thrust", minimum=0.0, maximum=1.0, inclusive_maximum=False,
                           note="(normalized collective thrust)"))
        self.position_control = PositionControl(self.params, hover_thrust=th, px4_version=px4_version)
        self.use_hte = bool(self.params["MPC_USE_HTE"])
        self.hover_thrust_estimator = HoverThrustEstimator(self.params, hover_thrust=th)
        self.attitude_control = AttitudeControl(self.params)
        self.rate_control = RateControl(self.params)
        self.setpoint = _checked_setpoint(FAWT_HOVER_POINT_NED if setpoint is None else setpoint, setpoint)
        self.yaw_setpoint = _yaw(yaw_setpoint)
        if not (isinstance(gyro_key, str) and gyro_key in GYRO_KEYS):
            raise ValueError(f"gyro_key must be one of {list(GYRO_KEYS)}, got {shown(gyro_key)}")
        self.gyro_key = gyro_key
        fs = self.control_rate
        self._config = C.configuration(
            butterworth_coefficients(fs, self.params["IMU_GYRO_CUTOFF"]),
            butterworth_coefficients(fs, self.params["IMU_DGYRO_CUTOFF"]), self.params["MPC_VELD_LP"],
            (1.0 / self.position_rate, 1.0 / self.attitude_rate, 1.0 / self.rate_loop_rate), self.use_hte,
            self.allocation.thrust_scale, self.allocation.torque_scale)
        self._pack_constants()
        self._n = 0

    def _pack_constants(self) -> None:
        """One constants vector for the cascade kernel (:func:`~fawtgym.agents.px4_cascade.pack_constants`); the
        laws keep views of it as their parameter arrays (so a parameter changed in place, or an array assigned to a
        law's parameter attribute, :class:`~fawtgym.agents.shared_params.InPlaceArray`, reaches the kernel)."""
        alloc = self.allocation
        self._constants, views = C.pack_constants(
            self._config, self.position_control.params, self.hover_thrust_estimator.params,
            self.attitude_control.params, self.rate_control.params, alloc.mix_t, alloc.effectiveness, alloc.scale,
            alloc.rotor_map)
        self._config = views[0]
        owners = ((self.position_control, "params"), (self.hover_thrust_estimator, "params"),
                  (self.attitude_control, "params"), (self.rate_control, "params"), (alloc, "mix_t"),
                  (alloc, "effectiveness"), (alloc, "scale"), (alloc, "rotor_map"))
        for (law, name), view in zip(owners, views[1:], strict=True):  # InPlaceArray: a later assignment writes here
            InPlaceArray.bind(law, name, view)

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled / deep-copied: the views of the constants vector come back as separate arrays; share again."""
        self.__dict__.update(state)
        self._pack_constants()

    #: (the gyro key and observer the measurement keys depend on, the keys act reads, the keys the cascade needs
    #: (``position`` first), the agent's name): see :meth:`_measurement_keys`
    _keys: tuple[Any, Any, tuple[str, ...] | None, tuple[str, ...], str] = (None, None, (), (), "")
    #: the observer's latest (force (N, 3), torque (N, 3)) estimates (None: no observer, or before the first act)
    raw_estimate: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    @classmethod
    def for_env(cls, env: Any, **kwargs: Any) -> PX4Agent:
        """An agent matched to ``env`` (its vehicle preset, control rate and setpoint)."""
        base = getattr(env, "unwrapped", env)
        kwargs.setdefault("vehicle", base.preset)
        kwargs.setdefault("control_rate", 1.0 / base.dt)
        kwargs.setdefault("setpoint", getattr(base, "setpoint", None))
        return cls(**kwargs)

    # ---- feedforward hook (zero for plain PX4) --------------------------------------------------
    def _estimate(self, meas: dict[str, NDArray[np.float64]], info: Mapping[str, Any],
                  dt: float) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        return None, None

    def _reset_estimator(self, meas: dict[str, NDArray[np.float64]], seed: int | None,
                         rows: NDArray[np.bool_] | None) -> None:
        return None

    def _bad_estimate(self, row: int) -> str:
        return f"{type(self).__name__}: non-finite disturbance estimate for row {row}"

    # ---- Agent API ------------------------------------------------------------------------------
    def reset(self, info: Mapping[str, Any], seed: int | None = None, rows: ArrayLike | None = None) -> None:
        """Start episodes from the env's reset ``info``: every row, or only the rows of ``rows`` (bool (N,)).

        A reset row's state (integrators, filters, hover-thrust estimate, loop phases, setpoints, observer)
        becomes exactly a fresh agent's; the other rows are untouched.  ``rows`` needs an earlier full reset
        with the same number of vehicles N.
        """
        if seed is not None and (isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer))
                                 or seed < 0):
            raise ValueError(f"{type(self).__name__}.reset: seed must be None or an int >= 0, got {shown(seed)}")
        meas, _ = measurement_from_info(info)
        n = meas["position"].shape[0]
        if rows is not None and n != self._n:
            raise ValueError(f"{type(self).__name__}.reset: rows needs an earlier full reset of the same batch; "
                             f"the agent holds {self._n} rows, the info {n}")
        mask = None if rows is None else check_row_mask(rows, n, f"{type(self).__name__}.reset")
        if mask is not None and mask.all():
            mask = None
        who = type(self).__name__
        sp = info.get("setpoint") if isinstance(info, Mapping) else None
        new_sp = _rows3(self.setpoint if sp is None else _setpoint_rows(sp, n, who), n)
        # a refused reset changes nothing: the inputs are checked first (the setpoint, the cascade's measurement of
        # the rows that start), then the estimator (it checks its own inputs before it changes), then the rest
        starts = np.ones(n, dtype=bool) if mask is None else mask
        bad = np.flatnonzero(starts & ~(np.abs(new_sp) <= MAX_SETPOINT).all(axis=1))  # NaN fails too
        if bad.size:
            row = int(bad[0])
            raise _bad_setpoint_row(who, row, new_sp)
        if mask is None or mask.any():
            starting = meas if mask is None else {k: v[mask] for k, v in meas.items()}
            refuse_measurement(starting, self._cascade_keys(starting), int(starting["position"].shape[0]), who)
            self._reset_estimator(meas, seed, mask)
        if mask is None:
            self._n = n
            self._pose_delay.reset(meas)
            self.position_control.reset(n)
            self.hover_thrust_estimator.reset(n)
            self.rate_control.reset(n)
            self._state = np.tile(C.fresh_state(self.position_control.initial_hover_thrust), (n, 1))
            self._att_sp = np.tile(np.eye(3), (n, 1, 1))
            self._setpoint = new_sp.copy()
            self._setpoint_override = False
            self._action = np.empty((n, 4))
            self._work = np.empty(C.N_WORK)  # the cascade kernel's scratch
            self._no_estimate = np.zeros((n, 3))
            self.last_estimate: tuple[NDArray[np.float64] | None, NDArray[np.float64] | None] = (None, None)
            return
        if not mask.any():
            return
        # the full reset's state, written into the rows of mask only
        self._pose_delay.reset(meas, rows=mask)
        self.position_control.reset(n, rows=mask)
        self.hover_thrust_estimator.reset(n, rows=mask)
        self.rate_control.reset(n, rows=mask)
        self._state[mask] = C.fresh_state(self.position_control.initial_hover_thrust)
        self._att_sp[mask] = np.eye(3)
        if not self._setpoint_override:
            self._setpoint = _rows3(self._setpoint, n).copy()
            self._setpoint[mask] = new_sp[mask]

    def set_setpoint(self, position: ArrayLike, yaw: float | None = None) -> None:
        """Change the NED position setpoint (and heading) during an episode; overrides ``info["setpoint"]``."""
        pos = _checked_setpoint(position, position)
        n = max(self._n, 1)
        if pos.ndim == 2 and pos.shape[0] not in (1, n):
            raise ValueError(f"setpoint must be of shape (3,), (1, 3) or ({n}, 3) (the {n} vehicle(s) this agent "
                             f"flies), got shape {pos.shape}")
        heading = self.yaw_setpoint if yaw is None else _yaw(yaw)  # checked before anything changes
        self._setpoint = _rows3(pos, n).copy()
        self._setpoint_override = True
        self.yaw_setpoint = heading

    def _measurement_keys(self) -> tuple[str, ...] | None:
        """The measurement keys ``act`` reads: the cascade's (pose, gyro, accelerometer); None: every key."""
        return tuple(dict.fromkeys((*POSE_KEYS, "angular_velocity", self.gyro_key, "specific_force")))

    def _cascade_keys(self, meas: Mapping[str, Any], optional: bool = False) -> tuple[str, ...]:
        """The measurement keys the cascade needs (``position`` first): the pose and the gyro (``gyro_key``, or
        ``angular_velocity`` when the measurement has no ``gyro_key``); with ``optional``, also the specific force
        if present (the hover-thrust estimator's, checked when given)."""
        gyro = self.gyro_key if self.gyro_key in meas else "angular_velocity"
        return (*POSE_KEYS, gyro, *(("specific_force",) if optional and "specific_force" in meas else ()))

    def act(self, observation: Any, info: Mapping[str, Any]) -> NDArray[np.float64]:
        """The motor commands for this step (module docstring).

        A measurement the cascade cannot use -- a key missing, a non-finite position, velocity, gyro or specific
        force, an attitude that is not a rotation -- is refused with the observers' one-line ValueError (named
        ``PX4Agent: ...``, the same text at every N) before any state changes (the kernel's ``BAD_MEASUREMENT``).
        """
        keys = self._keys  # only the keys read are converted (rebuilt if the gyro key or the observer changes)
        if keys[0] != self.gyro_key or keys[1] is not getattr(self, "observer", None):
            keys = self._keys = (self.gyro_key, getattr(self, "observer", None), self._measurement_keys(),
                                 (*POSE_KEYS, self.gyro_key), type(self).__name__)
        meas, batched = measurement_from_info(info, keys[2], keys[3], keys[4])
        pos = meas["position"]
        n = pos.shape[0]
        if n != self._n:
            if self._n == 0:
                raise RuntimeError(f"{type(self).__name__}.act() before reset(): call reset(info) first")
            raise ValueError(f"act() got {n} vehicles but reset() saw {self._n}; call reset() first")
        try:
            gyro = meas.get(self.gyro_key)
            if gyro is None:
                gyro = meas["angular_velocity"]
            vel, att = meas["velocity"], meas["attitude"]
        except KeyError:
            refuse_measurement(meas, self._cascade_keys(meas), n, keys[4])  # names the missing keys
            raise
        setpoint = self._setpoint
        if not self._setpoint_override:
            sp = info.get("setpoint")
            if sp is not None:  # one NED point (3,) for every row is passed as a (1, 3) view, not copied
                setpoint = (sp[None] if type(sp) is np.ndarray and sp.dtype is _F64 and sp.shape == (3,)
                            and sp.flags.c_contiguous else _setpoint_rows(sp, n, keys[4]))
        sf = meas.get("specific_force")
        _c = np.ascontiguousarray
        pos, vel, att, gyro = _c(pos), _c(vel), _c(att), _c(gyro)
        sf = self._no_estimate if sf is None else _c(sf)
        if self._pose_delay.steps:
            # the pose enters the delay line (the kernel sees it steps later): checked now, with the cascade's other
            # inputs (the kernel's own check), so that a bad pose is refused at once and a refused act changes nothing
            code, row = C.first_bad_input(pos, vel, att, gyro, sf, setpoint)
            if code:
                self._raise_status(code, row, meas, setpoint)
            meas = self._pose_delay(meas)
            pos, vel, att = _c(meas["position"]), _c(meas["velocity"]), _c(meas["attitude"])
        taken = self._snapshot()  # what the estimator's step replaces (references): taken back if the cascade refuses
        try:
            force_hat, torque_hat = self._estimate(meas, info, self.dt)
            raw = self.raw_estimate
            force, torque = (self._no_estimate, self._no_estimate) if raw is None else raw
            code, row = C.cascade_step(
                pos, vel, att, gyro, sf, sf is not self._no_estimate,
                setpoint, self.yaw_setpoint, force, force_hat is not None, torque, torque_hat is not None, self.dt,
                self._constants, self._state, self.position_control.state, self.hover_thrust_estimator.state,
                self.rate_control.state, self._att_sp, self._action, self._work)
        except BaseException:
            if self._pose_delay.steps:  # refused after the push (the observer's inputs): the line as it was
                self._pose_delay.undo(meas)
            raise
        if code:
            if code == C.BAD_MEASUREMENT or code == C.BAD_SETPOINT:  # refused before the cascade changed anything
                self._take_back(taken)
                if self._pose_delay.steps:
                    self._pose_delay.undo(meas)
            self._raise_status(code, row, meas, setpoint)
        self.last_estimate = (force_hat, torque_hat)
        self._setpoint = setpoint
        return self._action.copy() if batched else self._action[0].copy()  # unbatched: N = 1 (pos was (3,))

    def _snapshot(self) -> Any:
        """What ``act``'s estimator step replaces, for :meth:`_take_back` (None: PX4Agent has no estimator)."""
        return None

    def _take_back(self, taken: Any) -> None:
        """Undo the estimator's step of a refused ``act`` (:meth:`_snapshot`)."""

    def _raise_status(self, code: int, row: int, meas: Mapping[str, NDArray[np.float64]],
                      setpoint: NDArray[np.float64]) -> None:
        """The error of a cascade status code: :data:`~fawtgym.agents.px4_cascade.BAD_MEASUREMENT` -> the
        observers' ValueError (:func:`~fawtgym.agents.base.refuse_measurement`),
        :data:`~fawtgym.agents.px4_cascade.BAD_SETPOINT` -> ValueError naming the setpoint row,
        :data:`~fawtgym.agents.px4_cascade.BAD_ESTIMATE`, :data:`~fawtgym.agents.px4_cascade.BAD_ACTION` ->
        FloatingPointError."""
        who = type(self).__name__
        if code == C.BAD_MEASUREMENT:  # a row, or -1: the keys' row counts differ
            refuse_measurement(meas, self._cascade_keys(meas, optional=True), meas["position"].shape[0], who)
            raise ValueError(f"{who}: measurement row {row} refused by the cascade (not finite, the attitude not a "
                             "rotation, or rows missing)")  # the check above words it; kept should the two disagree
        if code == C.BAD_SETPOINT:
            raise _bad_setpoint_row(who, row, setpoint)
        if code == C.BAD_ESTIMATE:
            raise FloatingPointError(self._bad_estimate(row))
        if code == C.BAD_ACTION:
            bad = np.flatnonzero(~np.isfinite(self._action).all(axis=1)).tolist()
            raise FloatingPointError(f"PX4Agent produced a non-finite action for rows {bad}; measured position "
                                     f"{meas['position'][bad[0]].tolist()}")

    @property
    def _rotor(self) -> NDArray[np.float64]:
        """Rotor normalized thrusts (N, 4) sent to the motors at the last step."""
        return self._state[:, C.ROTOR:C.ROTOR + 4]

    @property
    def attitude_setpoint(self) -> NDArray[np.float64]:
        """The current attitude setpoint R_d (N, 3, 3) (for the principal-angle metric)."""
        return self._att_sp

    @property
    def collective_thrust(self) -> NDArray[np.float64]:
        """The current collective thrust set point [N] (N,): |thrust vector set point| * ``thrust_scale``, the
        thrust that goes with :attr:`attitude_setpoint` to an autopilot's attitude loop (SET_ATTITUDE_TARGET)."""
        thr = self._state[:, C.THR_SP:C.THR_SP + 3]
        return np.sqrt(np.einsum("ni,ni->n", thr, thr)) * self.allocation.thrust_scale


class PX4ObserverAgent(PX4Agent):
    """PX4Agent + disturbance-observer feedforward F = F0 - phi_hat, tau = tau0 - tau_hat (Wang et al. (2024) Sec. 7.2).

    ``observer``: a registered observer name (built with the preset's mass and inertia and
    ``observer_kwargs``) or an :class:`fawtgym.observers.base.Observer`.  ``force_ff`` / ``torque_ff``
    switch the two feedforward paths (the paper's Boolean parameters); a channel the observer does
    not estimate is never fed forward.  The observer is updated once per ``act`` with the env's
    applied thrust/torque over the step just taken.
    """

    def __init__(self, observer: Any = "ffts_eso", force_ff: bool = True, torque_ff: bool = True,
                 observer_kwargs: Mapping[str, Any] | None = None, **kwargs: Any) -> None:
        force_ff = check_flag(force_ff, "force_ff")
        torque_ff = check_flag(torque_ff, "torque_ff")
        super().__init__(**kwargs)
        from fawtgym.observers.base import Observer, make_observer

        if observer_kwargs is not None and not isinstance(observer_kwargs, Mapping):
            raise ValueError(f"observer_kwargs must be None or a mapping of the observer's options, got "
                             f"{shown(observer_kwargs)}")
        if isinstance(observer, str):
            import fawtgym.observers  # noqa: F401  (registers every observer)

            observer = make_observer(observer, self.preset.mass, self.preset.inertia_matrix,
                                     **dict(observer_kwargs or {}))
        elif observer_kwargs:
            raise ValueError("observer_kwargs is only used when observer is given by name")
        if not isinstance(observer, Observer):
            raise TypeError(f"observer must be a registered name or an Observer, got {type(observer).__name__}")
        self.observer = observer
        #: the observer's latest (force (N, 3), torque (N, 3)) estimates, None before the first act
        self.raw_estimate: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self.force_ff = force_ff and "force" in observer.channels
        self.torque_ff = torque_ff and "torque" in observer.channels

    def _snapshot(self) -> Any:
        return self.observer.snapshot(), self.raw_estimate

    def _take_back(self, taken: Any) -> None:
        snapshot, self.raw_estimate = taken
        self.observer.restore(snapshot)

    def _reset_estimator(self, meas: dict[str, NDArray[np.float64]], seed: int | None,
                         rows: NDArray[np.bool_] | None) -> None:
        if rows is None:
            self.observer.reset(meas)
            self.raw_estimate = None
        else:
            self.observer.reset(meas, rows=rows)

    def _measurement_keys(self) -> tuple[str, ...] | None:
        """The cascade's measurement keys and the observer's; None (every key) for an observer that states none (e.g.
        one that overrides ``update`` and reads what it likes)."""
        if not self.observer.required_keys:
            return None
        cascade = super()._measurement_keys()
        assert cascade is not None  # PX4Agent's own keys
        return tuple(dict.fromkeys((*cascade, *self.observer.required_keys)))

    def known_inputs(self, info: Mapping[str, Any]) -> Mapping[str, Any]:
        """The info whose ``"applied"`` the observer reads: the env's (exact applied wrench) or, with
        ``observer_inputs="commanded"``, the wrench commanded over the step just taken through the thrust model."""
        if self.observer_inputs == "applied":
            return info
        thrust, torque = commanded_wrench(self._rotor, self.allocation.max_rotor_thrust, self._alloc_matrix,
                                          self.thrust_model_error)
        return {"applied": {"thrust": thrust, "torque": torque}}

    def _estimate(self, meas: dict[str, NDArray[np.float64]], info: Mapping[str, Any],
                  dt: float) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        n = meas["position"].shape[0]
        # known_inputs is info itself for "applied" (skipped then, unless a subclass overrides it)
        own = type(self).known_inputs is PX4ObserverAgent.known_inputs
        known = info if own and self.observer_inputs == "applied" else self.known_inputs(info)
        thrust, torque = applied_from_info(known, n, self.preset.mass * GRAVITY)
        est = self.observer.update(meas, thrust, torque, dt)
        force, tau = est.force, est.torque
        # float64 (n, 3) arrays go to the cascade as they are, strided or not (an observer's estimate is often the
        # columns of one buffer: copying them would cost ~5 us each at N = 1024); anything else is converted
        if (type(force) is not np.ndarray or type(tau) is not np.ndarray or force.dtype is not _F64
                or tau.dtype is not _F64 or force.shape != (n, 3) or tau.shape != (n, 3)):
            force = np.ascontiguousarray(force, dtype=float).reshape(n, 3)
            tau = np.ascontiguousarray(tau, dtype=float).reshape(n, 3)
        self.raw_estimate = (force, tau)  # checked finite by the cascade kernel before it uses either
        return (force if self.force_ff else None), (tau if self.torque_ff else None)

    def _bad_estimate(self, row: int) -> str:
        return f"observer {self.observer.name!r} returned a non-finite estimate (row {row})"

    def disturbance_estimate(self) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
        """The observer's latest estimates (None for a channel it does not estimate, or before the first act)."""
        est = getattr(self, "raw_estimate", None)
        if est is None:
            return None, None
        return (est[0] if "force" in self.observer.channels else None,
                est[1] if "torque" in self.observer.channels else None)
