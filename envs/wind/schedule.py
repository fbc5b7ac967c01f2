"""Fan on/off schedule with first-order spin-up and spin-down of the fan array.

The fan-speed level ``s`` (0 = off, 1 = running at the commanded duty) follows
``ds/dt = (target(t) - s) / tau``, with ``tau = spin_tau`` while spinning up and ``spin_down_tau``
while spinning down, and ``target = 1`` between ``on_time`` and ``off_time``.  The FAWT's mean
speed and turbulence intensity both scale with ``s`` (the fan law: flow speed proportional to fan
speed; Table 3 of Wang et al. (2024), has TI nearly constant across duty).

Default ``spin_tau = 1.0 s`` (95 % in 3 tau = 3.0 s): an assumption, the paper gives no number.  It
is of the order of the spin-up of small axial fans (80 mm class, the 1.44 m x 0.72 m / 162 fans
array has an 80 mm pitch) plus the convection time from the array to the hover point
(1.5 m / 8 m/s ~ 0.2 s).  Fans coast down more slowly than they spin up (no active braking); we
use the same tau for both by default, settable via ``spin_down_tau``.

The level is advanced exactly (piecewise-constant target, closed-form exponential), so it does not
depend on the step.
"""

from __future__ import annotations

import math

from fawtgym.core.checks import check_number, shown

DEFAULT_SPIN_TAU = 1.0  #: [s] first-order fan spin-up time constant (assumption, see module docstring)
#: the latest on/off time [s] (about 32 years, the env's longest episode)
MAX_TIME = 1e9
#: fan spin-up/-down time constants [s]: from a bare motor's 0.1 ms to hours
SPIN_TAU_RANGE = (1e-4, 1e4)


def _check_time(name: str, value: float | None) -> float | None:
    """A switch time in [0, :data:`MAX_TIME`] s as a float, or None (no such switch)."""
    if value is None:
        return None
    return check_number(value, name, minimum=0.0, maximum=MAX_TIME, inclusive_minimum=True, note="s or None")


def _check_tau(name: str, value: float) -> float:
    """A fan time constant in :data:`SPIN_TAU_RANGE` [s] as a float."""
    return check_number(value, name, minimum=SPIN_TAU_RANGE[0], maximum=SPIN_TAU_RANGE[1], inclusive_minimum=True,
                        note="s")


class FanSchedule:
    """On/off schedule of the fan array with first-order spin-up/down.

    With neither ``on_time`` nor ``off_time`` the fans run from before t = 0 (level 1 at t = 0:
    steady state).  With ``on_time`` the fans are off before it (level 0) and spin up after it;
    with ``off_time`` they spin down after it.  Both: on in ``[on_time, off_time)``.
    """

    def __init__(self, on_time: float | None = None, off_time: float | None = None,
                 spin_tau: float = DEFAULT_SPIN_TAU, spin_down_tau: float | None = None) -> None:
        self.on_time = _check_time("on_time", on_time)
        self.off_time = _check_time("off_time", off_time)
        self.spin_tau = _check_tau("spin_tau", spin_tau)
        # None: the spin-up time constant
        self.spin_down_tau = self.spin_tau if spin_down_tau is None else _check_tau("spin_down_tau", spin_down_tau)
        if self.on_time is not None and self.off_time is not None and self.off_time <= self.on_time:
            raise ValueError(f"off_time ({self.off_time}) must be after on_time ({self.on_time})")
        self.steady = self.on_time is None and self.off_time is None

    def target(self, t: float) -> float:
        """Commanded level (0 or 1) at time ``t``."""
        if self.on_time is not None and t < self.on_time:
            return 0.0
        if self.off_time is not None and t >= self.off_time:
            return 0.0
        return 1.0

    def initial_level(self) -> float:
        """Level at t = 0: 1 when running (already spun up), 0 when the fans are switched on later."""
        return 0.0 if self.on_time is not None and self.on_time > 0 else self.target(0.0)

    def advance(self, t0: float, t1: float, level: float) -> float:
        """Exact level at ``t1`` from ``level`` at ``t0`` (``t1 >= t0``)."""
        if self.steady:
            return level
        edges = sorted(e for e in (self.on_time, self.off_time) if e is not None and t0 < e < t1)
        t = t0
        for e in (*edges, t1):
            tgt = self.target(t)
            tau = self.spin_tau if tgt > level else self.spin_down_tau
            level = tgt + (level - tgt) * math.exp(-(e - t) / tau)
            t = e
        return level

    def time_to_fraction(self, fraction: float = 0.95) -> float:
        """Time after switch-on to reach ``fraction`` of full speed: ``-tau ln(1 - fraction)``."""
        if not (0.0 < fraction < 1.0):
            raise ValueError(f"fraction must be in (0, 1), got {shown(fraction)}")
        return -self.spin_tau * math.log(1.0 - fraction)
