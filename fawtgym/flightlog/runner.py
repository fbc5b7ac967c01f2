"""Run registered observers over the airborne segments of a log (batch-first, N = 1).

Pipeline: read the log -> measurement signals and rotor commands (:mod:`.topics`, :mod:`.inputs`) ->
one grid at ``rate`` Hz with sample-and-hold (:mod:`.timebase`) -> phases (:mod:`.phases`) -> thrust scale
-> for each run of grid points that are airborne with every signal present, a fresh observer is reset on
the first point and updated on the next ones.  The update at ``t_k`` takes the measurement held at
``t_k`` and the known inputs held at ``t_{k-1}`` (what was commanded over the step just taken, as the env's
``info["applied"]``), with ``dt = 1 / rate``.  Points outside those runs are not estimated: their estimate
is NaN in the arrays and ``estimated`` is False (the CSV leaves the cells empty).  A channel an observer
does not estimate (``Observer.channels``: e.g. ``hc_eso`` estimates torque only) is NaN throughout;
an observer without a disturbance channel (``pdt_sta``) is refused with a one-line error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.checks import shown
from fawtgym.envs.vehicles import VehiclePreset, make_vehicle

from .errors import FlightLogError, log_number
from .inputs import choose_scale, contradictions, given_scale, make_thrust_model, rotor_commands, thrust_scales
from .logdata import FlightLog, read_log
from .phases import PHASES, Phases, detect_phases, segments
from .timebase import check_rate, hold, make_grid
from .topics import measurement_signals

DEFAULT_RATE = 50.0  #: observer rate [Hz]
DEFAULT_SETTLE = 2.0  #: seconds after each (re)start left out of the per-phase summary (observer transient)


@dataclasses.dataclass
class ObserveResult:
    """Everything ``fawtgym observe`` writes: grid, phases, known inputs, estimates per observer, report."""

    log: FlightLog
    vehicle: VehiclePreset
    t: NDArray[np.float64]  #: grid [s since log start] (M,)
    phases: Phases
    estimated: NDArray[np.bool_]  #: (M,) points where the observers ran
    settled: NDArray[np.bool_]  #: (M,) estimated and past the settle time of their segment
    thrust: NDArray[np.float64]  #: known collective thrust [N] (M,)
    torque: NDArray[np.float64]  #: known body torque [N m] (M, 3)
    estimates: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]  #: name -> (force (M,3), torque (M,3))
    report: dict[str, Any]  #: sources, thrust scales, rates, warnings

    @property
    def warnings(self) -> list[str]:
        return self.report["warnings"]


def observe(log: FlightLog | str | Path, observers: Sequence[str], vehicle: str | VehiclePreset | Path, *,
            rate: float = DEFAULT_RATE, inputs: str = "auto", thrust_curve: str = "auto",
            thrust_scale: str = "auto", settle: float = DEFAULT_SETTLE,
            observer_options: dict[str, dict[str, Any]] | None = None) -> ObserveResult:
    """Estimate the disturbance wrench of a logged flight with each named observer.  See the module docstring."""
    from fawtgym.observers import make_observer, observer_names
    from fawtgym.observers.base import observer_class

    if not observers:
        raise FlightLogError(f"no observer given; valid names: {observer_names()}")
    unknown = [o for o in observers if o not in observer_names()]
    if unknown:
        raise FlightLogError(f"unknown observer(s) {unknown}; valid names: {observer_names()}")
    rate = check_rate(rate)  # before the log is read (a bad value is told at once, not after parsing)
    settle = log_number(settle, "--settle", minimum=0.0, inclusive_minimum=True, maximum=1e6, note="s")
    given_scale(thrust_scale)
    try:
        preset = make_vehicle(vehicle)
    except (ValueError, TypeError, OSError) as exc:
        raise FlightLogError(str(exc)) from None
    log = log if isinstance(log, FlightLog) else read_log(log)

    signals = measurement_signals(log)
    commands, used_inputs = rotor_commands(log, inputs)
    t_start = max(float(s.t[0]) for s in (*signals.values(), commands) if s.t.size)
    t_end = log.duration
    grid = make_grid(t_start, t_end, rate)
    meas: dict[str, NDArray[np.float64]] = {}
    valid = np.ones(grid.size, dtype=bool)
    for key, sig in signals.items():
        meas[key], ok = hold(sig.t, sig.values, grid)
        valid &= ok
    meas["time"] = grid
    c_grid, ok = hold(commands.t, commands.values, grid)
    valid &= ok
    finite = np.all(np.isfinite(np.concatenate([v.reshape(grid.size, -1) for v in meas.values()] + [c_grid],
                                               axis=1)), axis=1)
    phases = detect_phases(log, grid, meas["position"], meas["velocity"])

    airborne = phases.airborne & valid & finite
    n = grid.size
    runs = [(a, b) for a, b in segments(airborne) if b - a >= 2]
    estimated = np.zeros(n, dtype=bool)
    settled = np.zeros(n, dtype=bool)
    for a, b in runs:
        estimated[a:b] = True
        settled[a + int(np.ceil(settle * rate)):b] = True

    model = make_thrust_model(log, preset, thrust_curve)
    hover = settled & (phases.label == PHASES.index("hover"))  # past the spool-up, as in the summary
    scales = thrust_scales(model, log, c_grid, meas["specific_force"][:, 2], hover, grid[airborne])
    model.scale, scale_from = choose_scale(scales, thrust_scale)
    thrust, torque = model.wrench(c_grid)
    estimates: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
    dt = 1.0 / rate
    opts = observer_options or {}
    for name in observers:
        if not observer_class(name).channels:
            raise FlightLogError(f"observer {shown(name)} estimates no disturbance (state estimates only); choose one "
                                 f"that estimates force or torque: {_disturbance_observers()}")
    for name in observers:
        force_out = np.full((n, 3), np.nan)
        torque_out = np.full((n, 3), np.nan)
        obs = None
        for a, b in runs:
            obs = make_observer(name, preset.mass, preset.inertia_matrix, **opts.get(name, {}))
            k = a
            try:
                obs.reset({key: v[a:a + 1] for key, v in meas.items()})
                force_out[a] = 0.0
                torque_out[a] = 0.0
                for k in range(a + 1, b):
                    est = obs.update({key: v[k:k + 1] for key, v in meas.items()}, thrust[k - 1:k],
                                     torque[k - 1:k], dt)
                    force_out[k] = est.force[0]
                    torque_out[k] = est.torque[0]
            except (FloatingPointError, ValueError) as exc:
                raise FlightLogError(f"observer {shown(name)} failed at t = {grid[k]:.2f} s of the log at --rate "
                                     f"{rate:g} "
                                     f"Hz ({' '.join(str(exc).split())}); a higher --rate (smaller step) or another "
                                     "observer may help") from None
        channels = frozenset(obs.channels) if obs is not None else observer_class(name).channels
        kept = [arr for ch, arr in (("force", force_out), ("torque", torque_out)) if ch in channels]
        bad = estimated & ~np.all(np.isfinite(np.concatenate(kept, axis=1)), axis=1)
        if bad.any():
            raise FlightLogError(f"observer {shown(name)} diverged (non-finite estimate) at t = {grid[bad][0]:.2f} s; "
                                 "try a higher --rate or another observer")
        for ch, arr in (("force", force_out), ("torque", torque_out)):
            if ch not in channels:  # the observer reports zeros there; zeros are not an estimate
                arr[:] = np.nan
        estimates[name] = (force_out, torque_out)

    warnings = [*log.notes, *phases.warnings, *contradictions(scales, preset)]
    if not runs:
        warnings.append("no airborne phase: nothing was estimated (the log is on the ground, disarmed or lacks data)")
    report = {
        "log": log.path, "kind": log.kind, "px4_version": log.version, "duration_s": log.duration,
        "vehicle": preset.name, "mass_kg": preset.mass, "rate_hz": rate, "observers": list(observers),
        "measurement_sources": {k: s.source for k, s in signals.items()},
        "inputs": {"choice": inputs, "used": used_inputs, "source": commands.source,
                   "thrust_curve": model.curve, "thr_mdl_fac": model.thr_mdl_fac},
        "thrust_scale": {"used": model.scale, "from": scale_from, "candidates": scales},
        "phase_source": phases.source, "interpolation": "sample-and-hold (latest sample at or before t)",
        "settle_s": settle, "estimated_s": float(estimated.sum() / rate), "warnings": warnings,
    }
    return ObserveResult(log, preset, grid, phases, estimated, settled, thrust, torque, estimates, report)


def _disturbance_observers() -> list[str]:
    from fawtgym.observers import observer_names
    from fawtgym.observers.base import observer_class

    return [n for n in observer_names() if observer_class(n).channels]
