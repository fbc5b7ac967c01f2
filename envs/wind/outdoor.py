"""Outdoor winds: MIL-spec low-altitude Dryden turbulence and the discrete 1-cosine gust.

Low-altitude Dryden (MIL-F-8785C Sec. 3.7 / MIL-HDBK-1797; altitude h in feet, h <= 1000 ft)::

    sigma_w = 0.1 W20,   sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4
    MIL-F-8785C:   L_u = L_v = h / (0.177 + 0.000823 h)^1.2,   L_w = h
    MIL-HDBK-1797: L_u = h / (0.177 + 0.000823 h)^1.2,  L_v = L_u / 2,  L_w = h / 2

with W20 (wind speed at 20 ft) = 15 kt light, 30 kt moderate, 45 kt severe.  Below 10 ft the
formulas degenerate (L_w -> 0); we hold them at their 10 ft values.  Above 1000 ft the spec switches
to the medium/high-altitude model (not implemented: ValueError).  The altitude is a parameter (the
scales do not follow the vehicle's height, which in a hover episode barely changes).

Mean wind (option ``mean_wind``): ``False`` (default: turbulence only, as MATLAB's Dryden block),
``True`` (the MIL-F-8785C log profile ``W(h) = W20 ln(h / z0) / ln(20 / z0)``, ``z0 = 0.15 ft``,
flight phase C), or a speed [m/s].  It blows horizontally toward ``direction_deg`` (NED heading,
0 = toward north).  Gust axes: ``u`` along that direction, ``v`` 90 deg to its right, ``w`` down.
Frozen-turbulence speed ``V = |W_adv - v_vehicle|`` floored at ``dryden.V_FLOOR``, where ``W_adv`` is the
mean wind, or, with ``mean_wind=False``, the log-profile wind the spec's intensity belongs to (so a
hovering vehicle sees gusts evolving on ``L / W(h)``, not frozen at the 1 m/s floor).

Discrete gust (MIL-F-8785C Sec. 3.7.5): ``v(x) = V_m (1 - cos(pi x / d_m)) / 2`` for
``0 <= x <= d_m`` and ``V_m`` beyond (``shape="rise"``), or back to 0 at ``x = 2 d_m``
(``shape="full"``, the classic 1-cosine).  ``x`` is the distance the gust front has travelled past
each point since ``start_time``, advected at ``speed`` relative to the vehicle, so points further
downstream meet it later (differential wind across the vehicle).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.checks import check_flag, check_number, shown

from .base import WindModel, check_n, check_points, check_step, raise_not_finite, row_inputs_finite
from .dryden import FORMS, V_FLOOR, DrydenParams, check_length_scale
from .dryden_process import DrydenProcess, GustWind, Seed, bin_filled, gust_row_step, step_bin

FT = 0.3048  #: [m] per foot
KNOT = 0.514444  #: [m/s] per knot
W20_KNOTS = {"light": 15.0, "moderate": 30.0, "severe": 45.0}
LOW_ALTITUDE_MAX = 1000.0 * FT  #: [m]
#: the strongest mean wind [m/s] (a category-5 hurricane is ~70 m/s); beyond it a value is a typo
MAX_MEAN_WIND = 100.0
#: the strongest 1-cosine gust amplitude [m/s] and front speed [m/s], its longest length [m], latest start [s]
MAX_GUST_AMPLITUDE = 100.0
GUST_SPEED_RANGE = (1e-3, 1000.0)
GUST_LENGTH_RANGE = (1e-3, 1e5)
MAX_START_TIME = 1e9
Z0_FT = 0.15  #: roughness height of the MIL-F-8785C log wind profile (flight phase C) [ft]


def low_altitude_params(intensity: str, altitude: float, form: str = "8785c") -> DrydenParams:
    """MIL-spec low-altitude Dryden intensities and scales (SI) for ``intensity`` at ``altitude`` [m]."""
    if intensity not in W20_KNOTS:
        raise ValueError(f"turbulence intensity must be one of {list(W20_KNOTS)}, got {shown(intensity)}")
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, got {shown(form)}")
    altitude = check_number(altitude, "altitude", minimum=0.0, maximum=LOW_ALTITUDE_MAX,
                            note="m (the low-altitude model, up to 1000 ft)")
    h = max(altitude / FT, 10.0)
    k = 0.177 + 0.000823 * h
    sig_w = 0.1 * W20_KNOTS[intensity] * KNOT
    sig_u = sig_w / k**0.4
    l_u = h / k**1.2 * FT
    l_w = h * FT
    length = (l_u, l_u, l_w) if form == "8785c" else (l_u, 0.5 * l_u, 0.5 * l_w)
    return DrydenParams(sigma=(sig_u, sig_u, sig_w), length=length, form=form)


def log_profile_speed(intensity: str, altitude: float) -> float:
    """MIL-F-8785C mean wind [m/s] at ``altitude`` [m] from W20: ``W20 ln(h / z0) / ln(20 / z0)``."""
    h = max(altitude / FT, 10.0)
    return W20_KNOTS[intensity] * KNOT * math.log(h / Z0_FT) / math.log(20.0 / Z0_FT)


def _direction(direction_deg: float) -> NDArray[np.float64]:
    """The horizontal NED unit vector toward the heading ``direction_deg`` (degrees in [-360, 360], clockwise from
    north)."""
    a = math.radians(check_number(direction_deg, "direction_deg", minimum=-360.0, maximum=360.0,
                                  inclusive_minimum=True, note="degrees (a heading)"))
    return np.array([math.cos(a), math.sin(a), 0.0])


@njit(cache=True)
def dryden_wind_rows(points: NDArray[np.float64], velocity: NDArray[np.float64], mean: NDArray[np.float64],
                     advection: NDArray[np.float64], axes: NDArray[np.float64], rates: bool, dt: float,
                     x: NDArray[np.float64], noise: NDArray[np.float64], cursor: NDArray[np.int64],
                     table: NDArray[np.float64], k0: int, out: NDArray[np.float64]) -> int:
    """The outdoor Dryden wind (N, K, 3) NED at ``points`` into ``out`` (module docstring), every row.

    Each row's gust field (state ``x``, its next normals ``noise[cursor[i], i]``) steps at ``V = |W_adv - v|``; the
    gust ``[u, v, w]`` along ``axes`` (rows: u, v, w in NED), plus with ``rates`` the gradients across the vehicle.
    Returns -1; or, before changing anything, -2 if a point or velocity is not finite, or a table bin to fill.
    """
    n, n_pts = points.shape[0], points.shape[1]
    ns = x.shape[1]
    bins = np.empty(n, dtype=np.int64)
    for i in range(n):  # pass 1: inputs finite, each row's Dryden bin filled
        if not row_inputs_finite(points, velocity, i):
            return -2
        speed = 0.0  # frozen-turbulence speed |W_adv - v|
        for c in range(3):
            speed += (advection[c] - velocity[i, c]) ** 2
        speed = math.sqrt(speed)
        b = step_bin((speed if speed > V_FLOOR else V_FLOOR) * dt, k0)
        if not bin_filled(table, b):
            return b
        bins[i] = b
    scratch = np.empty(table.shape[2])  # [x+, y+]: the row's gust y+ = [u, v, w](, p, q, r) is scratch[ns:]
    for i in range(n):
        gust_row_step(x, noise, cursor[i], table, bins[i], i, scratch)
        cursor[i] += 1
        for p in range(n_pts):
            g_u, g_v, g_w = scratch[ns], scratch[ns + 1], scratch[ns + 2]
            if rates:  # offsets from the CoM along the gust axes u, v
                d_u = d_v = 0.0
                for c in range(3):
                    offset = points[i, p, c] - points[i, 0, c]
                    d_u += axes[0, c] * offset
                    d_v += axes[1, c] * offset
                g_v = g_v - d_u * scratch[ns + 5]
                g_w = g_w - d_u * scratch[ns + 4] + d_v * scratch[ns + 3]
            for c in range(3):  # mean + [g_u, g_v, g_w] @ axes (NED)
                out[i, p, c] = mean[c] + (g_u * axes[0, c] + g_v * axes[1, c] + g_w * axes[2, c])
    return -1


class DrydenWind(GustWind):
    """MIL-spec Dryden turbulence at low altitude (module docstring); ``intensity`` light/moderate/severe.

    Options: ``altitude`` [m] (default 10), ``form`` ("8785c" | "1797"), ``mean_wind`` (False | True |
    speed [m/s]), ``direction_deg``, ``length_scale`` [m] (overrides L_u; L_v, L_w follow the form's
    isotropic ratios), ``rates`` (gust gradients across the vehicle), ``span`` [m], ``discretization``.
    """

    def __init__(self, intensity: str = "light", *, altitude: float = 10.0, form: str = "8785c",
                 mean_wind: bool | float = False, direction_deg: float = 0.0, length_scale: float | None = None,
                 rates: bool = False, span: float = 0.5, discretization: str = "exact") -> None:
        params = low_altitude_params(intensity, altitude, form)
        if length_scale is not None:
            length_scale = check_length_scale("length_scale", length_scale)
            lat = length_scale if form == "8785c" else 0.5 * length_scale
            params = DrydenParams(sigma=params.sigma, length=(length_scale, lat, lat), form=form, span=span)
        else:
            params = DrydenParams(sigma=params.sigma, length=params.length, form=form, span=span)
        self.params = params
        self.intensity = intensity
        self.altitude = float(altitude)
        if isinstance(mean_wind, (bool, np.bool_)):  # numpy booleans too, as check_flag accepts them
            speed = log_profile_speed(intensity, altitude) if mean_wind else 0.0
        elif mean_wind is None:
            speed = 0.0
        else:
            speed = check_number(mean_wind, "mean_wind", minimum=0.0, maximum=MAX_MEAN_WIND, inclusive_minimum=True,
                                 note="m/s, True (the log-profile speed) or False (none)")
        d = _direction(direction_deg)
        self.mean = speed * d  # NED
        # the air mass carrying the turbulence moves at the mean wind; without a mean-wind output it still
        # moves at the spec's log-profile speed (the W20 that sets the intensity), so gusts evolve on L / W(h)
        self.advection = (speed if speed > 0 else log_profile_speed(intensity, altitude)) * d
        # gust axes (rows: u, v, w) in NED
        self.axes = np.array([d, [-d[1], d[0], 0.0], [0.0, 0.0, 1.0]])
        self.rates = check_flag(rates, "rates")
        self.process = DrydenProcess(params, rates=self.rates, discretization=discretization)
        self.n = 0

    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        check_step(t, dt)
        points, velocity = check_points(points_ned, vehicle_velocity_ned, self.n, finite=False)
        return self.step_trusted(float(t), float(dt), points, velocity)

    def step_trusted(self, t: float, dt: float, points: NDArray[np.float64],
                     velocity: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`step` without the input checks (:meth:`WindModel.step_trusted`); the kernel finds non-finite ones."""
        proc = self.process
        if proc.refill_in <= 0:
            proc.ready()
        table = proc.table
        out = np.empty(points.shape)
        while (status := dryden_wind_rows(points, velocity, self.mean, self.advection, self.axes, self.rates,
                                          dt, proc.x, proc.noise, proc.cursor, table.matrices, table.k0,
                                          out)) != -1:
            if status == -2:
                raise_not_finite(points, velocity)
            table.fill(status)
        proc.refill_in -= 1  # proc.stepped()
        return out


class OneCosineGust(WindModel):
    """Discrete (1 - cosine) gust, MIL-F-8785C Sec. 3.7.5 (module docstring).

    ``amplitude`` [m/s]: a float (horizontal, toward ``direction_deg``) or an NED 3-vector (e.g. a
    vertical gust); the front always travels horizontally toward ``direction_deg``;
    ``length`` d_m [m]; ``speed`` [m/s] the front's advection speed; ``start_time`` [s]; ``shape``
    "rise" | "full".
    """

    def __init__(self, amplitude: float | tuple[float, float, float] = 3.0, *, length: float = 10.0,
                 speed: float = 5.0, start_time: float = 1.0, direction_deg: float = 0.0,
                 shape: str = "rise") -> None:
        d = _direction(direction_deg)
        raw = np.asarray(amplitude)
        amp = raw.astype(float) if raw.dtype.kind in "fiu" else np.full(1, np.nan)  # (strings, bools, objects: bad)
        if amp.shape == () and math.isfinite(float(amp)):
            amp = float(amp) * d
        if amp.shape != (3,) or not np.all(np.isfinite(amp)) or math.hypot(*amp) > MAX_GUST_AMPLITUDE:
            raise ValueError(f"amplitude must be a finite speed or NED 3-vector of magnitude at most "
                             f"{MAX_GUST_AMPLITUDE:g} m/s, got {shown(amplitude)}")
        length = check_number(length, "length", minimum=GUST_LENGTH_RANGE[0], maximum=GUST_LENGTH_RANGE[1],
                              inclusive_minimum=True, note="m")
        speed = check_number(speed, "speed", minimum=GUST_SPEED_RANGE[0], maximum=GUST_SPEED_RANGE[1],
                             inclusive_minimum=True, note="m/s")
        start_time = check_number(start_time, "start_time", minimum=0.0, maximum=MAX_START_TIME,
                                  inclusive_minimum=True, note="s")
        if not isinstance(shape, str) or shape not in ("rise", "full"):
            raise ValueError(f"shape must be 'rise' or 'full', got {shown(shape)}")
        self.amplitude = amp
        self.length = float(length)
        self.speed = float(speed)
        self.start_time = float(start_time)
        self.direction = d  # the front travels horizontally toward direction_deg whatever the amplitude's direction
        self.shape = shape
        self.n = 0

    def reset(self, n: int, seed: Seed = None) -> None:
        self.n = check_n(n)
        self.x = np.zeros(self.n)  # distance the front has moved past the CoM

    def profile(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Gust fraction of the amplitude at penetration distance ``x`` [m]."""
        xm = np.clip(x, 0.0, self.length if self.shape == "rise" else 2.0 * self.length)
        return np.where(x > 0, 0.5 * (1.0 - np.cos(math.pi * xm / self.length)), 0.0)

    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        check_step(t, dt)
        points_ned, vehicle_velocity_ned = check_points(points_ned, vehicle_velocity_ned, self.n)
        active = min(max(t - self.start_time, 0.0), dt)  # part of this step after the gust started
        if active > 0:
            rel = self.speed * self.direction - vehicle_velocity_ned
            self.x = self.x + np.maximum(np.sqrt((rel * rel).sum(axis=1)), V_FLOOR) * active
        if t <= self.start_time:
            return np.zeros(points_ned.shape)
        lag = (points_ned - points_ned[:, :1, :]) @ self.direction  # (N, K) downstream offset
        frac = self.profile(self.x[:, None] - lag)
        return frac[..., None] * self.amplitude
