"""PX4 flight-control parameters by their PX4 names, with PX4's defaults, ranges and the S500 overrides.

Wang et al. (2024), Sec. 7.2 flies PX4 v1.13.2 with "the flight control
parameters of the multi-rotor frame S500" of PX4-Autopilot.  The defaults below are the PX4 v1.13
parameter definitions (``mc_pos_control``, ``mc_att_control``, ``mc_rate_control``, ``sensors``
modules) and the S500 airframe file ``ROMFS/px4fmu_common/init.d/airframes/4014_s500`` overrides
``MC_ROLLRATE_P/PITCHRATE_P = 0.18``, ``MC_ROLLRATE_I/PITCHRATE_I = 0.15``, ``MC_ROLLRATE_D/PITCHRATE_D
= 0.003``.  Angles and angular rates are in degrees (deg/s) here, as PX4 names them; the control
classes convert to radians.

Files: :meth:`PX4Params.save` writes QGroundControl's parameter-file format (``# ...`` header, then
tab-separated ``vehicle-id component-id NAME value type``); :meth:`PX4Params.load` reads that format
and also plain ``NAME value`` lines (as ``param show`` prints them or a user writes them).  Unknown
names raise ``ValueError`` suggesting the closest valid names (difflib); values outside PX4's
range are refused.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fawtgym.core.checks import shown

#: MAVLink parameter types used in QGroundControl files.
_MAV_PARAM_TYPE_INT32 = 6
_MAV_PARAM_TYPE_REAL32 = 9


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """One PX4 parameter: default (PX4 v1.13), allowed range, unit, and a one-line meaning."""

    default: float
    min: float
    max: float
    unit: str
    doc: str
    integer: bool = False


_INF = math.inf

#: Every parameter the PX4-style controllers read, keyed by PX4 name.
PARAM_SPECS: dict[str, ParamSpec] = {
    # ---- mc_pos_control: position / velocity loop -----------------------------------------
    "MPC_XY_P": ParamSpec(0.95, 0.0, 2.0, "1/s", "horizontal position P gain (velocity per position error)"),
    "MPC_Z_P": ParamSpec(1.0, 0.1, 1.5, "1/s", "vertical position P gain"),
    "MPC_XY_VEL_P_ACC": ParamSpec(1.8, 1.2, 5.0, "1/s", "horizontal velocity P gain (acceleration per velocity error)"),
    "MPC_XY_VEL_I_ACC": ParamSpec(0.4, 0.0, 60.0, "1/s^2", "horizontal velocity I gain"),
    "MPC_XY_VEL_D_ACC": ParamSpec(0.2, 0.1, 2.0, "-", "horizontal velocity D gain (on the velocity derivative)"),
    "MPC_Z_VEL_P_ACC": ParamSpec(4.0, 2.0, 15.0, "1/s", "vertical velocity P gain"),
    "MPC_Z_VEL_I_ACC": ParamSpec(2.0, 0.2, 3.0, "1/s^2", "vertical velocity I gain"),
    "MPC_Z_VEL_D_ACC": ParamSpec(0.0, 0.0, 2.0, "-", "vertical velocity D gain"),
    "MPC_XY_VEL_MAX": ParamSpec(12.0, 0.0, 20.0, "m/s", "maximum horizontal velocity setpoint"),
    "MPC_Z_VEL_MAX_UP": ParamSpec(3.0, 0.5, 8.0, "m/s", "maximum ascent velocity setpoint"),
    "MPC_Z_VEL_MAX_DN": ParamSpec(1.5, 0.5, 4.0, "m/s", "maximum descent velocity setpoint"),
    "MPC_TILTMAX_AIR": ParamSpec(45.0, 20.0, 89.0, "deg", "maximum tilt in air"),
    "MPC_THR_MIN": ParamSpec(0.12, 0.05, 0.5, "norm", "minimum collective thrust"),
    "MPC_THR_MAX": ParamSpec(1.0, 0.0, 1.0, "norm", "maximum collective thrust"),
    "MPC_THR_HOVER": ParamSpec(0.5, 0.1, 0.8, "norm", "hover thrust (the agent derives it from the preset)"),
    "MPC_THR_XY_MARG": ParamSpec(0.3, 0.0, 0.5, "norm", "horizontal thrust margin kept under vertical priority"),
    "MPC_VELD_LP": ParamSpec(5.0, 0.0, 10.0, "Hz", "low-pass cut-off of the velocity derivative (D term)"),
    "MPC_USE_HTE": ParamSpec(1, 0, 1, "bool", "use the hover-thrust estimator", integer=True),
    # ---- mc_hover_thrust_estimator ---------------------------------------------------------
    "HTE_HT_NOISE": ParamSpec(0.0036, 0.0001, 1.0, "norm", "hover-thrust process noise"),
    "HTE_ACC_GATE": ParamSpec(3.0, 1.0, 10.0, "SD", "gate size of the acceleration innovation"),
    "HTE_HT_ERR_INIT": ParamSpec(0.1, 0.0, 1.0, "norm", "initial 1-sigma hover-thrust uncertainty"),
    "HTE_VXY_THR": ParamSpec(10.0, 1.0, 20.0, "m/s",
                            "horizontal speed above which the measurement noise is inflated"),
    "HTE_VZ_THR": ParamSpec(2.0, 1.0, 10.0, "m/s", "vertical speed above which the measurement noise is inflated"),
    "HTE_THR_RANGE": ParamSpec(0.2, 0.01, 0.4, "norm", "max deviation of the estimate from MPC_THR_HOVER"),
    # ---- mc_att_control: attitude loop -----------------------------------------------------
    "MC_ROLL_P": ParamSpec(6.5, 0.0, 12.0, "1/s", "roll attitude P gain"),
    "MC_PITCH_P": ParamSpec(6.5, 0.0, 12.0, "1/s", "pitch attitude P gain"),
    "MC_YAW_P": ParamSpec(2.8, 0.0, 5.0, "1/s", "yaw attitude P gain"),
    "MC_YAW_WEIGHT": ParamSpec(0.4, 0.0, 1.0, "-", "yaw weight of the reduced/full attitude mix"),
    "MC_ROLLRATE_MAX": ParamSpec(220.0, 0.0, 1800.0, "deg/s", "maximum roll rate setpoint"),
    "MC_PITCHRATE_MAX": ParamSpec(220.0, 0.0, 1800.0, "deg/s", "maximum pitch rate setpoint"),
    "MC_YAWRATE_MAX": ParamSpec(200.0, 0.0, 1800.0, "deg/s", "maximum yaw rate setpoint"),
    # ---- mc_rate_control: rate loop ----------------------------------------------------------
    "MC_ROLLRATE_P": ParamSpec(0.15, 0.01, 0.5, "-", "roll rate P gain"),
    "MC_ROLLRATE_I": ParamSpec(0.2, 0.0, _INF, "-", "roll rate I gain"),
    "MC_ROLLRATE_D": ParamSpec(0.003, 0.0, 0.01, "-", "roll rate D gain (on measured angular acceleration)"),
    "MC_ROLLRATE_FF": ParamSpec(0.0, 0.0, _INF, "-", "roll rate feedforward"),
    "MC_ROLLRATE_K": ParamSpec(1.0, 0.01, 5.0, "-", "roll rate controller gain K (scales P, I, D)"),
    "MC_RR_INT_LIM": ParamSpec(0.3, 0.0, _INF, "norm", "roll rate integrator limit"),
    "MC_PITCHRATE_P": ParamSpec(0.15, 0.01, 0.6, "-", "pitch rate P gain"),
    "MC_PITCHRATE_I": ParamSpec(0.2, 0.0, _INF, "-", "pitch rate I gain"),
    "MC_PITCHRATE_D": ParamSpec(0.003, 0.0, _INF, "-", "pitch rate D gain"),
    "MC_PITCHRATE_FF": ParamSpec(0.0, 0.0, _INF, "-", "pitch rate feedforward"),
    "MC_PITCHRATE_K": ParamSpec(1.0, 0.01, 5.0, "-", "pitch rate controller gain K"),
    "MC_PR_INT_LIM": ParamSpec(0.3, 0.0, _INF, "norm", "pitch rate integrator limit"),
    "MC_YAWRATE_P": ParamSpec(0.2, 0.0, 0.6, "-", "yaw rate P gain"),
    "MC_YAWRATE_I": ParamSpec(0.1, 0.0, _INF, "-", "yaw rate I gain"),
    "MC_YAWRATE_D": ParamSpec(0.0, 0.0, _INF, "-", "yaw rate D gain"),
    "MC_YAWRATE_FF": ParamSpec(0.0, 0.0, _INF, "-", "yaw rate feedforward"),
    "MC_YAWRATE_K": ParamSpec(1.0, 0.0, 5.0, "-", "yaw rate controller gain K"),
    "MC_YR_INT_LIM": ParamSpec(0.3, 0.0, _INF, "norm", "yaw rate integrator limit"),
    # ---- sensors: gyro filtering ---------------------------------------------------------
    "IMU_GYRO_CUTOFF": ParamSpec(40.0, 0.0, 1000.0, "Hz", "gyro low-pass cut-off (2nd-order Butterworth; 0 = off)"),
    "IMU_DGYRO_CUTOFF": ParamSpec(30.0, 0.0, 1000.0, "Hz",
                                  "angular-acceleration (D-term) low-pass cut-off (2nd-order Butterworth; 0 = off)"),
}

#: The S500 airframe's overrides (PX4 ``4014_s500``).
S500_OVERRIDES: dict[str, float] = {
    "MC_ROLLRATE_P": 0.18, "MC_PITCHRATE_P": 0.18,
    "MC_ROLLRATE_I": 0.15, "MC_PITCHRATE_I": 0.15,
    "MC_ROLLRATE_D": 0.003, "MC_PITCHRATE_D": 0.003,
}

#: The shipped S500 parameter file (package data).
S500_PARAMS_FILE = Path(__file__).with_name("px4_s500.params")


#: the filter cut-offs (0 = off) and the lowest cut-off a filter is designed for [Hz]
_CUTOFFS = ("IMU_GYRO_CUTOFF", "IMU_DGYRO_CUTOFF")
MIN_CUTOFF = 0.01


def _check_name(name: str) -> str:
    if not isinstance(name, str) or name not in PARAM_SPECS:
        close = difflib.get_close_matches(name.upper(), PARAM_SPECS, n=3, cutoff=0.5) if isinstance(name, str) else []
        hint = f"; did you mean {', '.join(close)}?" if close else f"; valid names: {sorted(PARAM_SPECS)}"
        raise ValueError(f"unknown PX4 parameter {shown(name)}{hint}")
    return name


def _check_value(name: str, value: Any) -> float:
    spec = PARAM_SPECS[name]
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"PX4 parameter {name} must be a number, got {shown(value)}")
    try:
        v = float(value)
    except OverflowError:  # an int beyond float range
        v = math.inf
    except (TypeError, ValueError):
        raise ValueError(f"PX4 parameter {name} must be a number, got {shown(value)}") from None
    if not math.isfinite(v):
        raise ValueError(f"PX4 parameter {name} must be finite, got {shown(value)}")
    if not spec.min <= v <= spec.max:
        raise ValueError(f"PX4 parameter {name}={v:g} is out of range [{spec.min:g}, {spec.max:g}] {spec.unit}")
    if name in _CUTOFFS and 0.0 < v < MIN_CUTOFF:
        raise ValueError(f"PX4 parameter {name}={v:g} must be 0 (filter off) or in [{MIN_CUTOFF:g}, {spec.max:g}] "
                         f"{spec.unit}")
    if spec.integer and v != int(v):
        raise ValueError(f"PX4 parameter {name} must be an integer, got {shown(value)}")
    return v


class PX4Params(Mapping[str, float]):
    """A validated set of PX4 parameters (read-only mapping; change with :meth:`set` / :meth:`replace`).

    ``PX4Params()`` gives PX4's defaults; ``PX4Params.s500()`` adds the S500 airframe overrides;
    ``PX4Params.s500(MPC_XY_P=1.2)`` or ``PX4Params({"MPC_XY_P": 1.2})`` override by name.
    """

    def __init__(self, values: Mapping[str, Any] | None = None, **kwargs: Any) -> None:
        self._values: dict[str, float] = {k: s.default for k, s in PARAM_SPECS.items()}
        for src in (values or {}), kwargs:
            for name, value in src.items():
                self.set(name, value)

    @classmethod
    def s500(cls, values: Mapping[str, Any] | None = None, **kwargs: Any) -> PX4Params:
        """PX4 defaults + the S500 airframe overrides (+ any given overrides)."""
        out = cls(S500_OVERRIDES)
        for src in (values or {}), kwargs:
            for name, value in src.items():
                out.set(name, value)
        return out

    @classmethod
    def coerce(cls, spec: PX4Params | Mapping[str, Any] | str | Path | None) -> PX4Params:
        """Params from an instance, a mapping of overrides on the S500 set, a file path, or None (S500)."""
        if spec is None:
            return cls.s500()
        if isinstance(spec, PX4Params):
            return spec
        if isinstance(spec, Mapping):
            return cls.s500(spec)
        if isinstance(spec, (str, Path)):
            return cls.load(spec)
        raise TypeError(f"params must be PX4Params, a mapping, a file path or None, got {type(spec).__name__}")

    # ---- mapping ------------------------------------------------------------------------------
    def __getitem__(self, name: str) -> float:
        return self._values[_check_name(name)]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        changed = {k: v for k, v in self._values.items() if v != PARAM_SPECS[k].default}
        return f"PX4Params(non-default={changed})"

    def set(self, name: str, value: Any) -> None:
        """Set one parameter; unknown names and out-of-range values raise ValueError."""
        name = _check_name(name)
        self._values[name] = _check_value(name, value)

    def replace(self, **changes: Any) -> PX4Params:
        """A copy with some parameters changed."""
        out = PX4Params(self._values)
        for name, value in changes.items():
            out.set(name, value)
        return out

    def non_default(self) -> dict[str, float]:
        """Parameters that differ from PX4's defaults."""
        return {k: v for k, v in self._values.items() if v != PARAM_SPECS[k].default}

    # ---- files ------------------------------------------------------------------------------
    def save(self, path: str | Path, vehicle_id: int = 1, component_id: int = 1) -> Path:
        """Write a QGroundControl-format parameter file (all parameters, sorted by name)."""
        path = Path(path)
        lines = ["# Onboard parameters for Vehicle 1 (fawtgym PX4-style controller)", "#",
                 "# Stack: PX4 Pro", "# Vehicle: Multi-Rotor", "# Version: 1.13.2 (fawtgym re-implementation)", "#",
                 "# Vehicle-Id Component-Id Name Value Type"]
        for name in sorted(self._values):
            spec = PARAM_SPECS[name]
            value = self._values[name]
            text = str(int(value)) if spec.integer else repr(float(value))
            kind = _MAV_PARAM_TYPE_INT32 if spec.integer else _MAV_PARAM_TYPE_REAL32
            lines.append(f"{vehicle_id}\t{component_id}\t{name}\t{text}\t{kind}")
        path.write_text("\n".join(lines) + "\n")
        return path

    @classmethod
    def load(cls, path: str | Path, base: PX4Params | None = None) -> PX4Params:
        """Read a parameter file (QGroundControl 5-column or ``NAME value`` lines) on top of ``base``.

        ``base`` defaults to PX4's defaults (not the S500 set), so a file states exactly what it sets.
        Raises ValueError naming the file and line of an unknown name, bad value or malformed line.
        """
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"parameter file {str(path)!r} does not exist")
        out = PX4Params(base._values if base is not None else None)
        for lineno, raw in enumerate(path.read_text().splitlines(), start=1):
            line = raw.split("#", 1)[0].strip()
            if not line:
                continue
            fields = line.replace(",", " ").split()
            if len(fields) == 5:
                name, value = fields[2], fields[3]
            elif len(fields) == 2:
                name, value = fields
            else:
                raise ValueError(f"{path}:{lineno}: expected 'NAME value' or QGroundControl's "
                                 f"'vehicle component NAME value type', got {shown(raw)}")
            try:
                out.set(name, value)
            except ValueError as exc:
                raise ValueError(f"{path}:{lineno}: {exc}") from None
        return out
