"""The fan-array wind tunnel (FAWT) of Wang et al. (2024) Sec. 7.

The tunnel: 162 fans in a 1.44 m x 0.72 m array (18 x 9, 80 mm pitch), up to 12 m/s, run in
steady uniform mode at 30-70 % duty; hot-wire statistics at x = 1.2 m on the axis (Table 3); the
vehicle hovers at x = 1.5 m, y = z = 0 (FAWT frame: x stream-wise, y span-wise, z up, origin at the
array centre, mapped to NED by :func:`fawtgym.core.frames.fawt_to_ned`).

Model (all parameters are constructor options)
---------------------------------------------
*Statistics.*  ``U(duty)`` and ``var(duty)`` of Table 3, piecewise-linear between the five rows,
so each preset reproduces its row exactly at the hot-wire point.  Outside [0.3, 0.7]: below 0.3 the
speed is proportional to duty (fan law, ``U = U_30 duty / 0.3``, 0 at duty 0); above 0.7 it is
linear from ``U_70`` to the paper's stated maximum 12 m/s at duty 1; TI is held at the end row's
value (``var = (TI U)^2``).  Duty below 0 or above 1 raises ValueError.

*Integral length scale* ``L`` (default per duty, about 15-23 mm).  For isotropic turbulence the
dissipation is ``eps = 15 nu u'^2 / lambda^2`` (Taylor microscale ``lambda``) and also
``eps = C_eps u'^3 / L`` with ``C_eps ~ 0.5`` (the normalized dissipation rate at Re_lambda >~ 100;
Sreenivasan 1998; Pope, Turbulent Flows, 2000, Ch. 6), so
``L = C_eps Re_lambda lambda / 15 = C_eps Re_lambda^2 nu / (15 u')`` with ``Re_lambda = u' lambda / nu``
from Table 3 and ``nu = 1.5e-5 m^2/s``.  Check against the geometry:
grid/fan-array turbulence at ``x / M = 1.2 / 0.08 = 15`` mesh lengths has ``L`` of roughly
0.1-0.5 ``M`` = 8-40 mm; the Re_lambda estimate falls inside that bracket (tested).  The gust
spectrum is Dryden with this ``L`` for ``u`` and, as isotropic turbulence, the same ``L``
(8785C form; ``L/2`` in the MIL-HDBK-1797 form) for ``v``, ``w``; ``sigma_v = sigma_w = sigma_u``
(single hot wire: only ``u`` was measured; isotropy is the documented assumption).  Note the
short ``L / U ~ 2 ms``: the turbulence is broadband up to ~100 Hz.  The model samples the field at
points and does not average over the rotor discs.

*Geometry.*  Mean stream-wise speed ``U(x, y, z) = U_ref s(t) F(x, y, z) / F(x_ref, 0, 0)`` with
``F = f(y; a, x) f(z; b, x) / (1 + kappa x)``, ``f(q; h, x) = (1 + erf(sigma_G (h - |q|) / x)) / 2``:
the Goertler error-function profile of a plane mixing layer (``sigma_G = 13.5``; Rajaratnam,
Turbulent Jets, 1976) at each edge of the ``2a x 2b = 1.44 m x 0.72 m`` section, so a uniform core
with shear layers whose width grows linearly with ``x``; ``kappa = 0.02 /m`` gives a slow decay of
the core (0.6 % between the hot wire and the hover point; the paper treats them as equal).  Mean
speed is zero behind the array plane (x < 0).  Turbulence: ``sigma^2 = (TI U)^2 + (TI_sl U_c(x))^2 g``
with ``g = max_edges exp(-(sigma_G (|q| - h) / x)^2)`` peaking in the shear layers, where the
peak r.m.s. fluctuation of a mixing layer is ``TI_sl = 0.17`` of the velocity difference (e.g. Bell &
Mehta 1990; Pope 2000 Ch. 5).  One Dryden realization per field is scaled by the local ``sigma`` at each
point (points share the gust; with ``rates=True`` the Dryden gust gradients add a linear spatial
variation across the vehicle).  ``s(t)`` is the fan level of :class:`FanSchedule`.

Frozen-turbulence speed: ``V = |U(CoM) e_x - v_vehicle|`` floored at ``dryden.V_FLOOR``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import scipy.special
from numpy.typing import NDArray

from fawtgym.core.checks import check_flag
from fawtgym.core.frames import FAWT_ORIGIN_NED, R_FAWT_TO_NED

from .base import WindModel
from .dryden import FORMS, DrydenParams, DrydenProcess
from .schedule import DEFAULT_SPIN_TAU, FanSchedule

#: Wang et al. (2024) Table 3: duty -> (U [m/s], variance [(m/s)^2], Re_lambda, TI), hot wire at x = 1.2 m.
TABLE3: dict[float, tuple[float, float, float, float]] = {
    0.3: (5.472, 0.061, 98.0, 0.0451),
    0.4: (6.876, 0.082, 102.0, 0.0417),
    0.5: (8.213, 0.116, 100.0, 0.0415),
    0.6: (9.590, 0.168, 127.0, 0.0427),
    0.7: (10.920, 0.237, 148.0, 0.0446),
}
FAWT_MAX_SPEED = 12.0  #: [m/s] "capable of generating wind speeds up to 12 m/s" (Wang et al. (2024) Sec. 7.1)
HALF_SPAN = 0.72  #: a [m], half of the 1.44 m array width (FAWT y)
HALF_HEIGHT = 0.36  #: b [m], half of the 0.72 m array height (FAWT z)
FAN_PITCH = 0.08  #: M [m], 1.44 m / 18 fans = 0.72 m / 9 fans
HOTWIRE_X = 1.2  #: [m] hot-wire station of Table 3
GOERTLER_SIGMA = 13.5  #: spreading parameter of the erf mixing-layer profile
DECAY_KAPPA = 0.02  #: [1/m] slow stream-wise decay of the core speed
SHEAR_TI = 0.17  #: peak r.m.s. u' / delta U in a plane mixing layer
NU_AIR = 1.5e-5  #: [m^2/s] kinematic viscosity of air at ~20 C
C_EPS = 0.5  #: normalized dissipation rate eps L / u'^3 (Sreenivasan 1998; Pope 2000 Ch. 6)
_DUTIES = np.array(sorted(TABLE3))


def length_scale_from_table3(duty_row: float) -> float:
    """Integral length scale [m] of a Table 3 row: ``L = C_eps Re_lambda^2 nu / (15 u')`` (module docstring)."""
    _, var, re_l, _ = TABLE3[duty_row]
    return C_EPS * re_l**2 * NU_AIR / (15.0 * math.sqrt(var))


def check_duty(duty: float) -> float:
    """Validate a duty fraction: finite and in [0, 1] (ValueError naming it otherwise)."""
    if isinstance(duty, bool) or not isinstance(duty, (int, float, np.floating, np.integer)) \
            or not math.isfinite(duty) or not 0.0 <= duty <= 1.0:
        raise ValueError(f"FAWT duty must be a fraction in [0, 1] (Table 3 covers 0.3-0.7), got {duty!r}")
    return float(duty)


def fawt_statistics(duty: float) -> dict[str, float]:
    """Mean speed, variance, TI and default integral length scale at ``duty`` (fraction), hot-wire point.

    Piecewise-linear in Table 3 inside [0.3, 0.7]; the documented policy outside (module docstring).
    """
    duty = check_duty(duty)
    rows = [TABLE3[d] for d in _DUTIES]
    u_tab = np.array([r[0] for r in rows])
    var_tab = np.array([r[1] for r in rows])
    len_tab = np.array([length_scale_from_table3(d) for d in _DUTIES])
    ti_tab = np.sqrt(var_tab) / u_tab
    if duty < _DUTIES[0]:
        u = u_tab[0] * duty / _DUTIES[0]
        var = (ti_tab[0] * u) ** 2
        length = len_tab[0]
    elif duty > _DUTIES[-1]:
        u = u_tab[-1] + (FAWT_MAX_SPEED - u_tab[-1]) * (duty - _DUTIES[-1]) / (1.0 - _DUTIES[-1])
        var = (ti_tab[-1] * u) ** 2
        length = len_tab[-1]
    else:
        u = float(np.interp(duty, _DUTIES, u_tab))
        var = float(np.interp(duty, _DUTIES, var_tab))
        length = float(np.interp(duty, _DUTIES, len_tab))
    ti = math.sqrt(var) / u if u > 0 else float(ti_tab[0])
    return {"mean": float(u), "variance": float(var), "ti": float(ti), "length_scale": float(length)}


_HALVES = np.array([HALF_SPAN, HALF_HEIGHT])
_SREF = GOERTLER_SIGMA / HOTWIRE_X


def fawt_profile(p_fawt: NDArray[np.float64], x_ref: float = HOTWIRE_X) -> tuple[NDArray, NDArray]:
    """Mean-speed factor ``F / F_ref`` and shear-layer variance weight at FAWT points (..., 3).

    ``F / F_ref`` is 1 at ``(x_ref, 0, 0)``.  The weight is ``max(g_y f_z, g_z f_y) (U_c(x) / U_c(x_ref))^2``
    with ``g = exp(-eta^2)``, ``eta = sigma_G (h - |q|) / x``: each edge's Gaussian shear-layer shape
    restricted to the other direction's extent of the jet.  Both are 0 behind the array (x <= 0).
    """
    x = p_fawt[..., 0]
    xs = np.maximum(x, 1e-3)
    eta = (_HALVES - np.abs(p_fawt[..., 1:])) * (GOERTLER_SIGMA / xs)[..., None]
    f = 0.5 + 0.5 * scipy.special.erf(eta)
    g = np.exp(-eta * eta)
    sref = GOERTLER_SIGMA / x_ref
    f_ref = 0.25 * (1 + math.erf(HALF_SPAN * sref)) * (1 + math.erf(HALF_HEIGHT * sref))
    core = (1.0 + DECAY_KAPPA * x_ref) / (1.0 + DECAY_KAPPA * xs) * (x > 0)  # U_c(x) / U_c(x_ref), 0 behind
    fy, fz = f[..., 0], f[..., 1]
    factor = fy * fz * core / f_ref
    weight = np.maximum(g[..., 0] * fz, g[..., 1] * fy) * (core * core)
    return factor, weight


_ORIGIN = tuple(FAWT_ORIGIN_NED.tolist())
_F_REF = 0.25 * (1 + math.erf(HALF_SPAN * _SREF)) * (1 + math.erf(HALF_HEIGHT * _SREF))
_CORE_REF = 1.0 + DECAY_KAPPA * HOTWIRE_X
assert np.allclose(R_FAWT_TO_NED, np.diag([1.0, -1.0, -1.0]))  # used by the float path below


def _profile_point_floats(x: float, y: float, z: float, weight: bool = True) -> tuple[float, float]:
    """:func:`fawt_profile` at one NED point in float arithmetic: ``(F * U_c / U_c(x_ref), shear weight)`` with
    ``F`` not yet divided by ``F_ref`` (the caller folds it into its gain); the weight only if ``weight``."""
    x -= _ORIGIN[0]  # FAWT x = NED x - origin; |y|, |z| are sign-free, so the FAWT axis flips do not matter
    if x <= 0.0:
        return 0.0, 0.0
    if x < 1e-3:
        x = 1e-3
    s = GOERTLER_SIGMA / x
    dy, dz = y - _ORIGIN[1], z - _ORIGIN[2]
    ey = (HALF_SPAN - (dy if dy >= 0.0 else -dy)) * s  # (|.| inline: a builtin call costs more than the branch)
    ez = (HALF_HEIGHT - (dz if dz >= 0.0 else -dz)) * s
    fy = 0.5 + 0.5 * math.erf(ey)
    fz = 0.5 + 0.5 * math.erf(ez)
    core = _CORE_REF / (1.0 + DECAY_KAPPA * x)
    if not weight:
        return fy * fz * core, 0.0
    # max(exp(-ey^2) fz, exp(-ez^2) fy): one exp where one term dominates in both factors
    if 0.0 <= ey <= ez:
        g = math.exp(-ey * ey) * fz
    elif 0.0 <= ez <= ey:
        g = math.exp(-ez * ez) * fy
    else:
        gy, gz = math.exp(-ey * ey) * fz, math.exp(-ez * ez) * fy
        g = gy if gy > gz else gz
    return fy * fz * core, g * core * core


def check_points(points_ned: NDArray[np.float64], velocity_ned: NDArray[np.float64], n: int) -> None:
    """ValueError naming the bad value if points (N, K, 3) or velocities (N, 3) are malformed or not finite."""
    if points_ned.ndim != 3 or points_ned.shape[0] != n or points_ned.shape[2] != 3:
        raise ValueError(f"points_ned must have shape ({n}, K, 3), got {points_ned.shape}")
    if velocity_ned.shape != (n, 3):
        raise ValueError(f"vehicle_velocity_ned must have shape ({n}, 3), got {velocity_ned.shape}")
    if not math.isfinite(float(points_ned.sum()) + float(velocity_ned.sum())):
        bad_p = ~np.isfinite(points_ned)
        if bad_p.any():
            raise ValueError(f"points_ned must be finite, got {points_ned[np.nonzero(bad_p.any(axis=-1))][0]}")
        row = np.nonzero(~np.isfinite(velocity_ned))[0][0]
        raise ValueError(f"vehicle_velocity_ned must be finite, got {velocity_ned[row]}")


class FawtWind(WindModel):
    """Turbulent FAWT wind at ``duty`` (fraction of maximum), Wang et al. (2024) Sec. 7 / Table 3.

    Options: ``on_time``/``off_time``/``spin_tau``/``spin_down_tau`` (fan schedule; none: running and
    spun up at t = 0), ``length_scale`` [m] (default from Table 3 Re_lambda), ``form`` (``"8785c"`` |
    ``"1797"``), ``rates`` (Dryden gust gradients across the vehicle), ``span`` [m] (for ``rates``),
    ``turbulence`` (False: mean flow only), ``discretization`` (``"exact"`` | ``"zoh"``).
    """

    def __init__(self, duty: float = 0.5, *, on_time: float | None = None, off_time: float | None = None,
                 spin_tau: float = DEFAULT_SPIN_TAU, spin_down_tau: float | None = None,
                 length_scale: float | None = None, form: str = "8785c", rates: bool = False, span: float = 0.5,
                 turbulence: bool = True, discretization: str = "exact") -> None:
        self.duty = check_duty(duty)
        stats = fawt_statistics(self.duty)
        self.mean_speed = stats["mean"]  # at the hot-wire point, fans spun up
        self.variance = stats["variance"]
        self.ti = stats["ti"]
        if length_scale is None:
            length_scale = stats["length_scale"]
        if isinstance(length_scale, bool) or not isinstance(length_scale, (int, float)) \
                or not math.isfinite(length_scale) or length_scale <= 0:
            raise ValueError(f"length_scale must be a finite positive length [m], got {length_scale!r}")
        if form not in FORMS:
            raise ValueError(f"form must be one of {FORMS}, got {form!r}")
        self.length_scale = float(length_scale)
        self.form = form
        self.schedule = FanSchedule(on_time, off_time, spin_tau, spin_down_tau)
        lat = self.length_scale if form == "8785c" else 0.5 * self.length_scale
        self.params = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(self.length_scale, lat, lat), form=form, span=span)
        self.turbulence = check_flag(turbulence, "turbulence")
        self.rates = check_flag(rates, "rates")
        self.process = DrydenProcess(self.params, rates=self.rates, discretization=discretization)
        self.n = 0
        self.level = self.schedule.initial_level()

    def reset(self, n: int, seed: int | np.random.SeedSequence | None = None) -> None:
        self.process.reset(n, seed)
        self.n = int(n)
        self.level = self.schedule.initial_level()
        self._t = 0.0

    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        """Wind (N, K, 3) NED at ``points_ned`` (N, K, 3) at time ``t`` (advanced by ``dt``); point 0 is the CoM."""
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a finite positive step [s], got {dt!r}")
        if self.n == 1 and not self.rates:
            return self._step_single(t, dt, points_ned, vehicle_velocity_ned)
        check_points(points_ned, vehicle_velocity_ned, self.n)
        self.level = self.schedule.advance(t - dt, t, self.level)
        self._t = t
        p = (points_ned - FAWT_ORIGIN_NED) @ R_FAWT_TO_NED  # FAWT frame
        factor, shear = fawt_profile(p)
        u_mean = (self.mean_speed * self.level) * factor  # (N, K) stream-wise
        out = np.zeros(points_ned.shape)
        out[..., 0] = u_mean  # FAWT x is NED north
        if self.turbulence and self.level > 0.0:
            sig = np.sqrt((self.ti * u_mean) ** 2 + (SHEAR_TI * self.mean_speed * self.level) ** 2 * shear)
            if self.n == 1:
                rx = u_mean[0, 0] - vehicle_velocity_ned[0, 0]
                speed = math.sqrt(rx * rx + vehicle_velocity_ned[0, 1] ** 2 + vehicle_velocity_ned[0, 2] ** 2)
            else:
                rel = -vehicle_velocity_ned
                rel[:, 0] += u_mean[:, 0]
                speed = np.sqrt((rel * rel).sum(axis=1))
            y = self.process.step(dt, speed)
            g = y[:, :3]
            if self.rates:
                d = p - p[:, :1, :]  # offsets from the CoM in the FAWT frame
                gv = g[:, None, 1] - d[..., 0] * y[:, None, 5]
                gw = g[:, None, 2] - d[..., 0] * y[:, None, 4] + d[..., 1] * y[:, None, 3]
                gust = np.stack([np.broadcast_to(g[:, None, 0], gv.shape), gv, gw], axis=-1)
            else:
                gust = g[:, None, :]
            # FAWT (x, y, z) -> NED (x, -y, -z)
            out[..., 0] += sig * gust[..., 0]
            out[..., 1] -= sig * gust[..., 1]
            out[..., 2] -= sig * gust[..., 2]
        return out

    def _step_single(self, t: float, dt: float, points_ned: NDArray[np.float64],
                     vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        """N = 1 :meth:`step` through the float path :meth:`step_floats` (tested equal to the vectorized path)."""
        if points_ned.ndim != 3 or points_ned.shape[0] != 1 or points_ned.shape[2] != 3 \
                or vehicle_velocity_ned.shape != (1, 3):
            check_points(points_ned, vehicle_velocity_ned, 1)
        flat, vel = points_ned.ravel().tolist(), vehicle_velocity_ned[0].tolist()
        if not math.isfinite(sum(flat) + sum(vel)):
            check_points(points_ned, vehicle_velocity_ned, 1)
        return np.array(self.step_floats(t, dt, flat, vel)).reshape(1, -1, 3)

    def step_floats(self, t: float, dt: float, points_ned: list[float], vehicle_velocity_ned: list[float]
                    ) -> list[float]:
        """One vehicle, plain float arithmetic: the same model as the vectorized :meth:`step`."""
        flat = points_ned
        vx, vy, vz = vehicle_velocity_ned
        if self.n != 1 or self.rates or not (dt > 0 and math.isfinite(dt)):
            return super().step_floats(t, dt, flat, vehicle_velocity_ned)  # step(): vectorized path or dt error
        if len(flat) % 3 or not math.isfinite(sum(flat) + vx + vy + vz):
            raise ValueError(f"points_ned must be 3 K finite coordinates and vehicle_velocity_ned 3 finite values, "
                             f"got {flat} and {vehicle_velocity_ned}")
        self.level = level = self.schedule.advance(t - dt, t, self.level)
        self._t = t
        scale = self.mean_speed * level
        turbulent = self.turbulence and level > 0.0
        gain = scale / _F_REF
        n = len(flat)
        out = [0.0] * n
        gu = gv = gw = 0.0
        ti2, sh = self.ti * self.ti, (SHEAR_TI * scale) ** 2
        for k in range(0, n, 3):
            u, g = _profile_point_floats(flat[k], flat[k + 1], flat[k + 2], turbulent)
            if k == 0 and turbulent:  # the CoM's mean sets the frozen-turbulence airspeed of the one gust
                rx = gain * u - vx
                gu, gv, gw = self.process.step1(dt, math.sqrt(rx * rx + vy * vy + vz * vz))[:3]
            u *= gain
            if turbulent:
                s = math.sqrt(ti2 * u * u + sh * g) if g > 0.0 else self.ti * u
                out[k], out[k + 1], out[k + 2] = u + s * gu, -s * gv, -s * gw
            else:
                out[k] = u
        return out

    def mean_wind_at(self, points_ned: Sequence[float] | NDArray[np.float64]) -> NDArray[np.float64]:
        """Mean wind (..., 3) NED at points (..., 3) for the current fan level (no turbulence)."""
        pts = np.asarray(points_ned, dtype=float)
        factor, _ = fawt_profile((pts - FAWT_ORIGIN_NED) @ R_FAWT_TO_NED)
        out = np.zeros(pts.shape)
        out[..., 0] = self.mean_speed * self.level * factor
        return out
