"""Known inputs from a log: collective thrust f [N] and body torque tau [N m, FRD] through the vehicle model.

Every source is first turned into four normalized rotor commands ``c`` in [0, 1] (PX4 quad X motor order),
then one law gives the wrench (the observers' known inputs, seed-000 eq. 38)::

    T_i = s * T_max * rho(c_i)          per-rotor thrust [N]
    [f, tau] = B [T_1 .. T_4]           B: :func:`fawtgym.envs.motors.allocation_matrix` of the preset

Sources (``--inputs``):

* ``motors``: ``actuator_motors.control[0..3]`` (PX4 v1.13+), the allocator's per-motor commands.
* ``setpoints``: ``vehicle_thrust_setpoint`` / ``vehicle_torque_setpoint`` (v1.13+) or, in older logs,
  ``actuator_controls_0`` (roll, pitch, yaw, thrust), mixed with PX4's quad X mixer table
  (``c_i = u_T + M_i u_tau``, M_i = (-y_i, x_i, d_i) with the unit arm (x_i, y_i) and spin d_i:
  +-0.707107, +-0.707107, +-1 as in PX4's ``quad_x`` geometry), unsaturated.
* ``outputs``: ``actuator_outputs.output[0..3]`` (PWM) normalized by the log's PWM_MAIN_MIN/MAX
  (PWM_MIN/MAX before v1.13; 1000/2000 us if absent).
* ``auto``: the first of motors, setpoints, outputs that the log has.

Thrust curve ``rho`` (``--thrust-curve``): ``px4`` is PX4's own model of its motors, the parameter
THR_MDL_FAC ``rho(c) = fac c^2 + (1 - fac) c``; ``preset`` is our env's rotor model
(:func:`fawtgym.envs.motors.command_to_thrust`, speed linear in c, T = k_T omega^2) divided by T_max.
``T_max = k_T omega_max^2`` of the preset.

Thrust scale ``s`` (``--thrust-scale``), candidates in the order ``auto`` tries them:

* ``estimate``: four rotors at PX4's own in-flight hover thrust (``hover_thrust_estimate``, v1.12+; its
  valid samples while airborne, averaged) hold the weight;
* ``hover``: over the hover phase (past the settle time after take-off, so no spool-up on the ground),
  the modelled thrust equals the thrust the accelerometer felt,
  ``s = mean(-m a_z) / mean(f_model)`` with the body-z specific force ``a_z`` (this attributes any mean
  body-z force in hover to the thrust model: a log cannot tell a mass error from a steady vertical
  disturbance);
* ``param``: four rotors at MPC_THR_HOVER hold the weight (a tuning parameter, the least direct);
* ``preset``: s = 1 (the preset's thrust as it is); a number is used as given.

All candidates are reported, and one more than :data:`CONTRADICTION` away from 1 warns that the log
contradicts the preset.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.checks import shown
from fawtgym.core.constants import GRAVITY
from fawtgym.envs.motors import command_to_thrust, rotor_wrench
from fawtgym.envs.vehicles import QUAD_X_ARMS, QUAD_X_DIRECTIONS, VehiclePreset

from .errors import FlightLogError
from .logdata import FlightLog
from .topics import Signal, missing_topic

INPUT_SOURCES: tuple[str, ...] = ("auto", "motors", "setpoints", "outputs")
THRUST_CURVES: tuple[str, ...] = ("auto", "px4", "preset")
CONTRADICTION = 0.25  #: |s - 1| above which the log is said to contradict the preset

#: PX4 quad X mixer (roll, pitch, yaw) per motor: (-y_i, x_i, d_i) of the unit arm and spin direction
QUAD_X_MIX = np.stack([-QUAD_X_ARMS[:, 1], QUAD_X_ARMS[:, 0], QUAD_X_DIRECTIONS], axis=1)


def rotor_commands(log: FlightLog, source: str) -> tuple[Signal, str]:
    """Four rotor commands in [0, 1] as a signal, and the source actually used."""
    if source not in INPUT_SOURCES:
        raise FlightLogError(f"unknown --inputs {shown(source)}; allowed: {list(INPUT_SOURCES)}")
    if source == "auto":
        for cand, topics in (("motors", ("actuator_motors",)),
                             ("setpoints", ("vehicle_thrust_setpoint", "vehicle_torque_setpoint")),
                             ("setpoints", ("actuator_controls_0",)), ("outputs", ("actuator_outputs",))):
            if all(log.has(t) for t in topics):
                return rotor_commands(log, cand)
        raise missing_topic("actuator_motors", "the known thrust and torque")
    if source == "motors":
        if not log.has("actuator_motors"):
            raise missing_topic("actuator_motors", "--inputs motors")
        tp = log.topics["actuator_motors"]
        c = tp.vector("control", 4)
        return Signal(tp.t, np.clip(np.nan_to_num(c, nan=0.0), 0.0, 1.0), "actuator_motors.control[0..3]"), source
    if source == "outputs":
        if not log.has("actuator_outputs"):
            raise missing_topic("actuator_outputs", "--inputs outputs")
        tp = log.topics["actuator_outputs"]
        lo = log.params.get("PWM_MAIN_MIN", log.params.get("PWM_MIN", 1000.0))
        hi = log.params.get("PWM_MAIN_MAX", log.params.get("PWM_MAX", 2000.0))
        if not hi > lo:
            raise FlightLogError(f"PWM range of the log is empty (min {lo}, max {hi}); use --inputs motors or "
                                 "setpoints")
        c = (tp.vector("output", 4) - lo) / (hi - lo)
        return Signal(tp.t, np.clip(c, 0.0, 1.0), f"actuator_outputs.output[0..3] (PWM {lo:g}..{hi:g})"), source
    # setpoints
    if log.has("vehicle_thrust_setpoint") and log.has("vehicle_torque_setpoint"):
        th, tq = log.topics["vehicle_thrust_setpoint"], log.topics["vehicle_torque_setpoint"]
        u_t = -th.vector("xyz", 3)[:, 2]
        u_tau = tq.vector("xyz", 3)
        t, u_t, u_tau = _merge(th.t, u_t, tq.t, u_tau)
        what = "vehicle_thrust_setpoint + vehicle_torque_setpoint via the quad X mixer"
    elif log.has("actuator_controls_0"):
        ac = log.topics["actuator_controls_0"]
        u = ac.vector("control", 4)
        t, u_t, u_tau = ac.t, u[:, 3], u[:, :3]
        what = "actuator_controls_0 via the quad X mixer"
    else:
        raise missing_topic("vehicle_thrust_setpoint" if not log.has("vehicle_thrust_setpoint")
                            else "vehicle_torque_setpoint", "--inputs setpoints")
    c = u_t[:, None] + np.nan_to_num(u_tau) @ QUAD_X_MIX.T
    return Signal(t, np.clip(np.nan_to_num(c), 0.0, 1.0), what), source


def _merge(t1: NDArray[np.float64], v1: NDArray[np.float64], t2: NDArray[np.float64],
           v2: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Two signals on the union of their times, each held (no look-ahead) from its latest sample."""
    from .timebase import hold

    t = np.union1d(t1, t2)
    a, va = hold(t1, v1, t)
    b, vb = hold(t2, v2, t)
    ok = va & vb
    return t[ok], a[ok], b[ok]


@dataclasses.dataclass
class ThrustModel:
    """Rotor commands -> (f, tau) for a preset: ``T_i = scale * T_max * rho(c_i)``, see the module docstring."""

    preset: VehiclePreset
    curve: str  #: "px4" or "preset"
    thr_mdl_fac: float = 0.0
    scale: float = 1.0

    def rho(self, c: NDArray[np.float64]) -> NDArray[np.float64]:
        """Relative thrust in [0, 1] of commands c in [0, 1]."""
        if self.curve == "px4":
            return self.thr_mdl_fac * c**2 + (1.0 - self.thr_mdl_fac) * c
        return command_to_thrust(self.preset, c) / self.preset.max_thrust_per_rotor

    def wrench(self, c: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Collective thrust (K,) [N] and body torque (K, 3) [N m] of commands (K, 4)."""
        return rotor_wrench(self.preset, self.scale * self.preset.max_thrust_per_rotor * self.rho(c))


def make_thrust_model(log: FlightLog, preset: VehiclePreset, curve: str) -> ThrustModel:
    if curve not in THRUST_CURVES:
        raise FlightLogError(f"unknown --thrust-curve {shown(curve)}; allowed: {list(THRUST_CURVES)}")
    fac = log.params.get("THR_MDL_FAC")
    if curve == "auto":
        curve = "px4" if fac is not None else "preset"
    fac = 0.0 if fac is None else float(fac)
    if not 0.0 <= fac <= 1.0:
        raise FlightLogError(f"THR_MDL_FAC of the log is {fac}, outside [0, 1]")
    return ThrustModel(preset, curve, fac)


def thrust_scales(model: ThrustModel, log: FlightLog, c_grid: NDArray[np.float64],
                  specific_force_z: NDArray[np.float64], hover: NDArray[np.bool_],
                  airborne_times: NDArray[np.float64]) -> dict[str, object]:
    """The candidate scales (None where the log does not pin one), see the module docstring."""
    weight = model.preset.mass * GRAVITY
    base = dataclasses.replace(model, scale=1.0)
    out: dict[str, object] = {"estimate": None, "hover": None, "param": None, "preset": 1.0}

    def at(thr: float) -> float:
        return weight / float(base.wrench(np.full((1, 4), thr))[0][0])

    if log.has("hover_thrust_estimate") and airborne_times.size:
        h = log.topics["hover_thrust_estimate"]
        ok = (np.asarray(h.fields.get("valid", np.ones(len(h)))) != 0) & (h.t >= airborne_times.min()) \
            & (h.t <= airborne_times.max())
        if ok.any():
            thr = float(np.mean(h.fields["hover_thrust"][ok]))
            out["estimate"] = at(thr)
            out["estimate_source"] = f"hover_thrust_estimate = {thr:.3f} (mean of {int(ok.sum())} valid samples)"
    if hover.any():
        f, _ = base.wrench(c_grid[hover])
        lift = float(np.mean(f))
        felt = float(np.mean(-model.preset.mass * specific_force_z[hover]))
        if lift > 0 and felt > 0:
            out["hover"] = felt / lift
            out["hover_mean_command"] = float(np.mean(c_grid[hover]))
    if log.params.get("MPC_THR_HOVER", 0.0) > 0:
        thr = float(log.params["MPC_THR_HOVER"])
        out["param"] = at(thr)
        out["param_source"] = f"MPC_THR_HOVER = {thr:.3f}"
    return out


SCALE_CHOICES: tuple[str, ...] = ("auto", "estimate", "hover", "param", "preset")


#: the largest ``--thrust-scale`` (a factor on the preset's rotor thrust)
MAX_THRUST_SCALE = 1e3


def given_scale(choice: object) -> float | None:
    """``--thrust-scale`` checked without the log: None for a named choice (:data:`SCALE_CHOICES`), else the number
    it gives, in (0, :data:`MAX_THRUST_SCALE`]; FlightLogError for anything else."""
    if isinstance(choice, str) and choice in SCALE_CHOICES:
        return None
    try:
        value = float(choice) if isinstance(choice, (str, float, int)) and not isinstance(choice, bool) else math.nan
    except (ValueError, OverflowError):  # not a number; an int beyond float range
        raise FlightLogError(f"--thrust-scale must be one of {list(SCALE_CHOICES)} or a positive number, "
                             f"got {shown(choice)}") from None
    if not (math.isfinite(value) and 0 < value <= MAX_THRUST_SCALE):
        raise FlightLogError(f"--thrust-scale must be one of {list(SCALE_CHOICES)} or a finite number in (0, "
                             f"{MAX_THRUST_SCALE:g}], got {shown(choice)}")
    return value


def choose_scale(scales: dict[str, object], choice: str) -> tuple[float, str]:
    """The scale for ``--thrust-scale`` (auto | estimate | hover | param | preset | number) and its origin.

    ``auto`` takes the first candidate the log pins in the order estimate, hover, param, preset; a named
    candidate the log does not pin raises FlightLogError naming what it needs (a number: :func:`given_scale`).
    """
    value = given_scale(choice)
    if value is not None:
        return value, "given"
    if choice == "auto":
        for key in ("estimate", "hover", "param", "preset"):
            if scales.get(key) is not None:
                return float(scales[key]), key  # type: ignore[arg-type]
    if scales.get(choice) is None:
        need = {"estimate": "the topic hover_thrust_estimate (PX4 v1.12+) while airborne",
                "hover": "a hover phase", "param": "the parameter MPC_THR_HOVER"}[choice]
        raise FlightLogError(f"--thrust-scale {choice} needs {need}, which the log lacks; allowed here: "
                             f"{[k for k in SCALE_CHOICES[1:] if scales.get(k) is not None]} or a number")
    return float(scales[choice]), choice  # type: ignore[arg-type]


def contradictions(scales: dict[str, object], preset: VehiclePreset) -> list[str]:
    """Warnings where a scale pinned by the log differs from the preset's (1) by more than CONTRADICTION."""
    out = []
    for key, what in (("estimate", str(scales.get("estimate_source", ""))), ("hover", "the hover phase"),
                      ("param", str(scales.get("param_source", "")))):
        s = scales.get(key)
        if isinstance(s, (int, float)) and abs(float(s) - 1.0) > CONTRADICTION:
            out.append(f"the log contradicts vehicle {preset.name!r}: {what} needs {float(s):.2f} x the preset's "
                       f"rotor thrust to hold m = {preset.mass:g} kg (check the mass, thrust curve or preset)")
    return out
