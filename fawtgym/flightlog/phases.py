"""Flight phases and flight modes on the time grid, from the log's own state topics.

Airborne is decided by the flight controller itself: armed (``vehicle_status.arming_state == 2``, ARMED
in every PX4 version) and neither landed nor in ground contact by PX4's land detector
(``vehicle_land_detected.landed``, and its earlier stages ``ground_contact`` / ``maybe_landed`` where the
log has them).  PX4 declares take-off when it commands it, so the spool-up before lift-off is flagged
airborne; the ground's push shows there (and at touch-down until ``ground_contact``) as an upward force.  A log
without the land detector (PX4 before v1.6, or a tlog without EXTENDED_SYS_STATE) falls back to: armed and
more than :data:`FALLBACK_HEIGHT` above the position where it was armed -- a warning says so.

Airborne points are labelled by the vertical and horizontal velocity (world NED, m/s)::

    climb    -vz >  VZ_HOVER           descend  vz > VZ_HOVER
    hover   |vz| <= VZ_HOVER and |v_xy| <= VXY_HOVER            move     otherwise

and every other point is ``ground`` (disarmed, or armed and landed): the observers' model (rigid body
in free flight, seed-000 eq. 38) does not hold there, so it is shown and not estimated.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from .logdata import FlightLog
from .timebase import hold
from .topics import require

VZ_HOVER = 0.3  #: |vz| below which an airborne point is not climbing/descending [m/s]
VXY_HOVER = 1.0  #: horizontal speed below which an airborne point is hovering [m/s]
FALLBACK_HEIGHT = 0.5  #: height above the arming point that counts as airborne without a land detector [m]
ARMED = 2  #: vehicle_status.arming_state ARMED (PX4 v1.5 ... main)

PHASES: tuple[str, ...] = ("ground", "climb", "hover", "descend", "move")

#: PX4 vehicle_status.nav_state names (NAVIGATION_STATE_*; 6, 7, 11, 16 were renamed over versions)
NAV_STATES: dict[int, str] = {
    0: "Manual", 1: "Altitude", 2: "Position", 3: "Mission", 4: "Hold", 5: "Return", 6: "RC recovery",
    7: "Return (GS)", 8: "Land (engine fail)", 9: "Land (GPS fail)", 10: "Acro", 11: "Unused", 12: "Descend",
    13: "Termination", 14: "Offboard", 15: "Stabilized", 16: "Rattitude", 17: "Takeoff", 18: "Land",
    19: "Follow target", 20: "Precision land", 21: "Orbit", 22: "VTOL takeoff",
}


@dataclasses.dataclass
class Phases:
    """Per grid point: ``armed``, ``airborne`` (bool (M,)), ``label`` (index into :data:`PHASES`, (M,)),
    ``modes`` ((t_start, t_end, name) segments of the flight mode), ``source`` and ``warnings``."""

    armed: NDArray[np.bool_]
    airborne: NDArray[np.bool_]
    label: NDArray[np.int8]
    modes: list[tuple[float, float, str]]
    source: str
    warnings: list[str]

    def names(self) -> NDArray[np.str_]:
        return np.asarray(PHASES)[self.label]


def detect_phases(log: FlightLog, grid: NDArray[np.float64], position: NDArray[np.float64],
                  velocity: NDArray[np.float64]) -> Phases:
    """Label the grid (position, velocity (M, 3) already on the grid, NED)."""
    require(log, "vehicle_status", "the arming state (only armed, airborne phases are estimated)")
    vs = log.topics["vehicle_status"]
    armed_held, valid = hold(vs.t, np.asarray(vs.fields["arming_state"]) == ARMED, grid)
    armed = armed_held & valid
    warnings: list[str] = []
    if log.has("vehicle_land_detected"):
        ld = log.topics["vehicle_land_detected"]
        flags = [f for f in ("landed", "ground_contact", "maybe_landed") if f in ld.fields]
        down = np.any([np.asarray(ld.fields[f]) != 0 for f in flags], axis=0)
        landed, lvalid = hold(ld.t, down, grid)
        airborne = armed & lvalid & ~landed
        source = "vehicle_status.arming_state + vehicle_land_detected." + "/".join(flags)
    else:
        height = np.zeros(grid.size)
        starts = np.flatnonzero(np.diff(np.concatenate([[False], armed])) > 0)
        for s in starts:  # height above where each arming happened (NED: up is -z)
            end = s + np.argmax(~armed[s:]) if not armed[s:].all() else grid.size
            height[s:end] = position[s, 2] - position[s:end, 2]
        airborne = armed & (height > FALLBACK_HEIGHT)
        source = f"vehicle_status.arming_state + height above the arming point > {FALLBACK_HEIGHT} m"
        warnings.append("log has no vehicle_land_detected (PX4 v1.6+); airborne = armed and "
                        f"> {FALLBACK_HEIGHT} m above the arming point")
    vz = velocity[:, 2]
    vxy = np.hypot(velocity[:, 0], velocity[:, 1])
    label = np.full(grid.size, PHASES.index("move"), dtype=np.int8)
    label[(np.abs(vz) <= VZ_HOVER) & (vxy <= VXY_HOVER)] = PHASES.index("hover")
    label[-vz > VZ_HOVER] = PHASES.index("climb")
    label[vz > VZ_HOVER] = PHASES.index("descend")
    label[~airborne] = PHASES.index("ground")
    return Phases(armed, airborne, label, flight_modes(log, grid), source, warnings)


def flight_modes(log: FlightLog, grid: NDArray[np.float64]) -> list[tuple[float, float, str]]:
    """Contiguous flight-mode segments (t_start, t_end, name) over the grid from ``vehicle_status.nav_state``."""
    if not log.has("vehicle_status") or grid.size == 0:
        return []
    vs = log.topics["vehicle_status"]
    nav, valid = hold(vs.t, np.asarray(vs.fields["nav_state"], dtype=np.int64), grid)
    nav = np.where(valid, nav, -1)
    edges = np.flatnonzero(np.diff(nav)) + 1
    bounds = np.concatenate([[0], edges, [grid.size]])
    out = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        code = int(nav[a])
        name = "unknown" if code < 0 else NAV_STATES.get(code, f"nav_state {code}")
        out.append((float(grid[a]), float(grid[min(b, grid.size - 1)]), name))
    return out


def segments(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Half-open index ranges [start, stop) of the runs of True in ``mask``."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))
