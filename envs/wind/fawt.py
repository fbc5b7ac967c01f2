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
from numba import njit
from numpy.typing import NDArray

from fawtgym.core.checks import check_flag, check_number, shown
from fawtgym.core.frames import FAWT_ORIGIN_NED, R_FAWT_TO_NED

from .base import check_points, check_step, raise_not_finite, row_inputs_finite
from .dryden import FORMS, V_FLOOR, DrydenParams, check_length_scale
from .dryden_process import DrydenProcess, GustWind, Seed, bin_filled, gust_row_step, step_bin
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
    """A duty fraction in [0, 1] as a float (ValueError naming it otherwise)."""
    return check_number(duty, "FAWT duty", minimum=0.0, maximum=1.0, inclusive_minimum=True,
                        note="(a fraction; Table 3 covers 0.3-0.7)")


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


_OX, _OY, _OZ = (float(c) for c in FAWT_ORIGIN_NED)
assert np.array_equal(R_FAWT_TO_NED, np.diag([1.0, -1.0, -1.0]))  # the kernels write FAWT = (x, -y, -z) from the origin


def _reference(x_ref: float) -> tuple[float, float]:
    """The normalizers of :func:`profile_rows` for the reference station ``x_ref``: ``F(x_ref, 0, 0)`` and
    ``1 + kappa x_ref`` (so that ``U_c(x) / U_c(x_ref) = (1 + kappa x_ref) / (1 + kappa x)``)."""
    s = GOERTLER_SIGMA / x_ref
    return 0.25 * (1 + math.erf(HALF_SPAN * s)) * (1 + math.erf(HALF_HEIGHT * s)), 1.0 + DECAY_KAPPA * x_ref


_F_REF, _CORE_REF = _reference(HOTWIRE_X)


@njit(cache=True)
def _goertler(eta: float) -> float:
    """``(1 + erf(eta)) / 2``; exactly 0 or 1 beyond |eta| = 6, where ``erf`` rounds to -1 or 1 (saves the call)."""
    if eta >= 6.0:
        return 1.0
    if eta <= -6.0:
        return 0.0
    return 0.5 + 0.5 * math.erf(eta)


@njit(cache=True, inline="always")
def _profile_args(xf: float, yf: float, zf: float, core_ref: float) -> tuple[float, float, float]:
    """``(eta_y, eta_z, U_c(x) / U_c(x_ref))`` at a FAWT-frame point (:func:`profile_rows`)."""
    xs = xf if xf > 1e-3 else 1e-3
    s = GOERTLER_SIGMA / xs
    return (HALF_SPAN - abs(yf)) * s, (HALF_HEIGHT - abs(zf)) * s, core_ref / (1.0 + DECAY_KAPPA * xs)


@njit(cache=True, inline="always")
def _profile_values(xf: float, eta_y: float, eta_z: float, f_y: float, f_z: float, core: float,
                    f_ref: float) -> tuple[float, float]:
    """``(F / F_ref, shear weight)`` from :func:`_profile_args` and the Goertler profiles ``f_y``, ``f_z``
    (:func:`profile_rows`)."""
    if not xf > 0.0:
        return 0.0, 0.0
    # max(exp(-eta_y^2) f_z, exp(-eta_z^2) f_y): where 0 <= eta_a <= eta_b, term a is the larger in both factors
    if 0.0 <= eta_y <= eta_z:
        g = math.exp(-eta_y * eta_y) * f_z
    elif 0.0 <= eta_z <= eta_y:
        g = math.exp(-eta_z * eta_z) * f_y
    else:
        g_y, g_z = math.exp(-eta_y * eta_y) * f_z, math.exp(-eta_z * eta_z) * f_y
        g = g_y if g_y > g_z else g_z
    return f_y * f_z * core / f_ref, g * (core * core)


@njit(cache=True)
def profile_rows(p: NDArray[np.float64], f_ref: float, core_ref: float, factor: NDArray[np.float64],
                 weight: NDArray[np.float64]) -> None:
    """Mean-speed factor ``F / F_ref`` and shear-layer variance weight at each FAWT-frame point of ``p`` (M, 3) into
    ``factor``, ``weight`` (M,) (module docstring).

    ``eta = sigma_G (h - |q|) / x`` per edge, ``f = (1 + erf(eta)) / 2`` (Goertler profile), ``g = exp(-eta^2)``;
    factor ``f_y f_z U_c(x) / (U_c(x_ref) F_ref)``, weight ``max(g_y f_z, g_z f_y) (U_c(x) / U_c(x_ref))^2``:
    each edge's Gaussian shear-layer shape restricted to the other direction's extent of the jet.  Both are 0
    behind the array (x <= 0).  Computed in three loops over the points (the arithmetic, the ``erf`` calls, the
    ``exp`` calls and the products): a loop of library calls alone runs them back to back (~15 % less time than
    point by point)."""
    m = p.shape[0]
    work = np.empty((m, 5))  # eta_y, eta_z, core, f_y, f_z
    for i in range(m):
        work[i, 0], work[i, 1], work[i, 2] = _profile_args(p[i, 0], p[i, 1], p[i, 2], core_ref)
    for i in range(m):
        work[i, 3], work[i, 4] = _goertler(work[i, 0]), _goertler(work[i, 1])
    for i in range(m):
        factor[i], weight[i] = _profile_values(p[i, 0], work[i, 0], work[i, 1], work[i, 3], work[i, 4], work[i, 2],
                                               f_ref)


def fawt_profile(p_fawt: NDArray[np.float64], x_ref: float = HOTWIRE_X) -> tuple[NDArray, NDArray]:
    """Mean-speed factor ``F / F_ref`` and shear-layer variance weight (:func:`profile_rows`) at FAWT points
    (..., 3); ``F / F_ref`` is 1 at ``(x_ref, 0, 0)``."""
    p = np.ascontiguousarray(p_fawt, dtype=float)
    flat = p.reshape(-1, 3)
    factor, weight = np.empty(flat.shape[0]), np.empty(flat.shape[0])
    profile_rows(flat, *_reference(float(x_ref)), factor, weight)
    return factor.reshape(p.shape[:-1]), weight.reshape(p.shape[:-1])


@njit(cache=True, nogil=True)
def fawt_wind_rows(points: NDArray[np.float64], velocity: NDArray[np.float64], scale: float, ti: float,
                   turbulent: bool, rates: bool, dt: float, x: NDArray[np.float64], noise: NDArray[np.float64],
                   cursor: NDArray[np.int64], table: NDArray[np.float64], k0: int, out: NDArray[np.float64]) -> int:
    """The FAWT wind (N, K, 3) NED at ``points`` (N, K, 3) into ``out``, every row (module docstring).

    ``scale = U_ref s(t)`` (mean speed at the hot wire times the fan level); with ``turbulent`` each row's Dryden
    field (state ``x``, its next normals ``noise[cursor[i], i]``, step matrices ``table``) is advanced by ``dt`` at
    its frozen-turbulence speed ``V = |U(CoM) e_x - v|``.  Returns -1; or, before changing anything, -2 if a point
    or velocity is not finite, or the index of a table bin that must be filled first.
    """
    n, n_pts = points.shape[0], points.shape[1]
    ns = x.shape[1]
    # (F / F_ref, shear weight) at every point, computed over all points at once (profile_rows: its erf/exp calls
    # run back to back); the CoM's sets each row's Dryden step, the last pass uses them all
    fawt_points = np.empty((n * n_pts, 3))
    for i in range(n):  # pass 1: inputs finite, the points in the FAWT frame
        if not row_inputs_finite(points, velocity, i):
            return -2
        for p in range(n_pts):
            k = i * n_pts + p
            fawt_points[k, 0], fawt_points[k, 1] = points[i, p, 0] - _OX, _OY - points[i, p, 1]
            fawt_points[k, 2] = _OZ - points[i, p, 2]
    factors, weights = np.empty(n * n_pts), np.empty(n * n_pts)
    profile_rows(fawt_points, _F_REF, _CORE_REF, factors, weights)  # pass 2: the profile at every point
    bins = np.empty(n, dtype=np.int64)
    for i in range(n):  # pass 3: each row's Dryden bin filled
        if turbulent:
            rel_x = scale * factors[i * n_pts] - velocity[i, 0]  # air velocity relative to the vehicle at the CoM
            speed = math.sqrt(rel_x * rel_x + velocity[i, 1] * velocity[i, 1] + velocity[i, 2] * velocity[i, 2])
            b = step_bin((speed if speed > V_FLOOR else V_FLOOR) * dt, k0)
            if not bin_filled(table, b):
                return b
            bins[i] = b
    scratch = np.empty(table.shape[2])  # [x+, y+]: the row's gust y+ = [u, v, w](, p, q, r) is scratch[ns:]
    shear_scale2 = (SHEAR_TI * scale) ** 2  # peak mixing-layer variance (TI_sl U_c)^2
    for i in range(n):
        if turbulent:
            gust_row_step(x, noise, cursor[i], table, bins[i], i, scratch)  # one gust per row
            cursor[i] += 1
        x0, y0 = points[i, 0, 0] - _OX, _OY - points[i, 0, 1]  # CoM, FAWT frame
        for p in range(n_pts):
            xf, yf = points[i, p, 0] - _OX, _OY - points[i, p, 1]
            factor, shear = factors[i * n_pts + p], weights[i * n_pts + p]
            u_mean = scale * factor  # stream-wise mean, FAWT x = NED north
            if not turbulent:
                out[i, p, 0], out[i, p, 1], out[i, p, 2] = u_mean, 0.0, 0.0
                continue
            sigma = math.sqrt((ti * u_mean) ** 2 + shear_scale2 * shear)  # local r.m.s. gust
            g_u, g_v, g_w = scratch[ns], scratch[ns + 1], scratch[ns + 2]
            if rates:  # gust gradients: linear variation across the vehicle (offsets from the CoM, FAWT frame)
                g_v = g_v - (xf - x0) * scratch[ns + 5]
                g_w = g_w - (xf - x0) * scratch[ns + 4] + (yf - y0) * scratch[ns + 3]
            # FAWT (x, y, z) -> NED (x, -y, -z)
            out[i, p, 0] = u_mean + sigma * g_u
            out[i, p, 1] = -(sigma * g_v)
            out[i, p, 2] = -(sigma * g_w)
    return -1


class FawtWind(GustWind):
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
        length_scale = check_length_scale("length_scale", length_scale)
        if not isinstance(form, str) or form not in FORMS:
            raise ValueError(f"form must be one of {FORMS}, got {shown(form)}")
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

    def reset(self, n: int, seed: Seed = None) -> None:
        super().reset(n, seed)
        self.level = self.schedule.initial_level()

    def step(self, t: float, dt: float, points_ned: NDArray[np.float64],
             vehicle_velocity_ned: NDArray[np.float64]) -> NDArray[np.float64]:
        """Wind (N, K, 3) NED at ``points_ned`` (N, K, 3) at time ``t`` (advanced by ``dt``); point 0 is the CoM."""
        check_step(t, dt)
        points, velocity = check_points(points_ned, vehicle_velocity_ned, self.n, finite=False)
        return self.step_trusted(float(t), float(dt), points, velocity)

    def step_trusted(self, t: float, dt: float, points: NDArray[np.float64],
                     velocity: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`step` without the input checks (:meth:`WindModel.step_trusted`); the kernel finds non-finite ones."""
        level = self.level if self.schedule.steady else self.schedule.advance(t - dt, t, self.level)
        turbulent = self.turbulence and level > 0.0
        proc = self.process
        if turbulent and proc.refill_in <= 0:
            proc.ready()
        table = proc.table
        out = np.empty(points.shape)
        while (status := fawt_wind_rows(points, velocity, self.mean_speed * level, self.ti, turbulent, self.rates,
                                        dt, proc.x, proc.noise, proc.cursor, table.matrices, table.k0, out)) != -1:
            if status == -2:
                raise_not_finite(points, velocity)
            table.fill(status)
        if turbulent:
            proc.refill_in -= 1  # proc.stepped()
        self.level = level
        return out

    def mean_wind_at(self, points_ned: Sequence[float] | NDArray[np.float64]) -> NDArray[np.float64]:
        """Mean wind (..., 3) NED at points (..., 3) for the current fan level (no turbulence)."""
        pts = np.asarray(points_ned, dtype=float)
        factor, _ = fawt_profile((pts - FAWT_ORIGIN_NED) @ R_FAWT_TO_NED)
        out = np.zeros(pts.shape)
        out[..., 0] = self.mean_speed * self.level * factor
        return out
