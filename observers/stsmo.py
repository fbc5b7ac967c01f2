"""The multivariable (modified) super-twisting sliding-mode observer of a Gibbs vector and its rate.

Source: Silva and Santos (2023), Sec. 4-5: the modified STSMO (eqs. 75-77) and the conventional STSMO
(eqs. 81-82), driven by the QUEST Gibbs vector g_Q (eq. 79), with angular velocity by certainty equivalence
omega_hat = 2 Gamma(g_hat)^-1 g_hat' (eq. 80, :func:`fawtgym.observers.gibbs.omega_row`); early switching for
noisy measurements (eqs. 43-44) via ``t_switch`` (see :mod:`fawtgym.observers.predefined_sta`).

Known inputs.  Eq. 76 evaluates Gamma' omega and J omega x omega at the *true* angular velocity (the paper's
simulation passes the forcing omega(t) of eq. 78 to the observer).  A gyroless estimator has no true omega:
:class:`GibbsSTSMO` takes it when given (``omega=...``, the paper's setting) and otherwise uses its own estimate
omega_hat of eq. 80 (certainty equivalence), which is what the env estimator ``pdt_sta`` does.

Discretization.  The time-varying term eta/(t_c - t) x1_tilde of eq. 77 is integrated exactly over a step with
the measurement held (the transition of eq. 7, :func:`fawtgym.observers.predefined_sta.exact_linear_step`), so
the step stays stable up to t_s for any dt; everything else is forward Euler as in the paper (Sec. 5,
T_s = 1e-4 s).  ``integrator="euler"`` uses forward Euler for that term too (the paper).

The step is one row function, :func:`stsmo_row` (numba), looped over the rows by :meth:`GibbsSTSMO.step` and
called by the ``pdt_sta`` observer's kernel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.kernel_types import NO_REFCOUNT
from fawtgym.core.rows import check_row_mask, write_rows
from fawtgym.core.so3_kernels import cross_entries, gyroscopic_entries, mat_vec_entries

from .gibbs import omega_row
from .predefined_sta import check_params, switch_and_gain_times


@njit(cache=True, **NO_REFCOUNT)
def stsmo_row(x1, x2, t, y, u, w, J, J_inv, p, dt, x1_out, x2_out):
    """One step of eqs. 75-77 (or 81-82) of one row: state g_hat = ``x1`` (3,), g_hat' = ``x2`` (3,) at time ``t``,
    the Gibbs measurement ``y`` (eq. 79) and torque ``u`` held over ``dt``, the angular velocity ``w`` of eq. 76
    -> the new state in ``x1_out``, ``x2_out`` (may be ``x1``, ``x2``).  ``p`` = :attr:`GibbsSTSMO.params`
    (kappa1, kappa2, eta, t_s, t_d, conventional, euler).  Returns True if the new state is finite."""
    kappa1, kappa2, eta, t_s, t_d = p[0], p[1], p[2], p[3], p[4]
    conventional, euler = p[5] != 0.0, p[6] != 0.0
    a0, a1, a2 = x1[0], x1[1], x1[2]
    b0, b1, b2 = x2[0], x2[1], x2[2]
    w0, w1, w2 = w[0], w[1], w[2]
    e0, e1, e2 = y[0] - a0, y[1] - a1, y[2] - a2  # x1_tilde, eq. 79
    n = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    if n > 0.0:  # x1_tilde / ||x1_tilde|| and x1_tilde / ||x1_tilde||^(1/2) (0 at 0: the sign's zero selection)
        sn = math.sqrt(n)
        n0, n1, n2, s0, s1, s2 = e0 / n, e1 / n, e2 / n, e0 / sn, e1 / sn, e2 / sn
    else:
        n0 = n1 = n2 = s0 = s1 = s2 = 0.0
    # eq. 76 / 82: x2' = 1/2 [Gamma'(g) w + Gamma(g) v], v = J^-1 (J w x w + u + kappa2 x1_tilde/||x1_tilde||),
    # with Gamma'(g) w = g (g'.w) + g' (g.w) + g' x w and Gamma(g) v = g (g.v) + g x v + v (eq. 48)
    d2w = b0 * w0 + b1 * w1 + b2 * w2
    d1w = a0 * w0 + a1 * w1 + a2 * w2
    x0, x1, x2 = cross_entries(b0, b1, b2, w0, w1, w2)  # g' x w
    gd0 = a0 * d2w + b0 * d1w + x0
    gd1 = a1 * d2w + b1 * d1w + x1
    gd2 = a2 * d2w + b2 * d1w + x2
    # J w x w + u + kappa2 x1_tilde/||x1_tilde|| (summed in this order: not known_angular_acceleration_entries of the
    # sum of the two torques, whose rounding differs), then J^-1
    y0, y1, y2 = gyroscopic_entries(J, w0, w1, w2)
    v0, v1, v2 = mat_vec_entries(J_inv, y0 + u[0] + kappa2 * n0, y1 + u[1] + kappa2 * n1, y2 + u[2] + kappa2 * n2)
    d1v = a0 * v0 + a1 * v1 + a2 * v2
    x0, x1, x2 = cross_entries(a0, a1, a2, v0, v1, v2)  # g x v
    xd0 = 0.5 * (gd0 + a0 * d1v + x0 + v0)
    xd1 = 0.5 * (gd1 + a1 * d1v + x1 + v1)
    xd2 = 0.5 * (gd2 + a2 * d1v + x2 + v2)
    # eq. 75 / 77 / 81: x1' = x2 + sigma, sigma = eta/(t_d - t) x1_tilde before t_s, the STA term after
    s0, s1, s2 = kappa1 * s0, kappa1 * s1, kappa1 * s2
    if conventional:
        c0, c1, c2 = a0 + dt * (b0 + s0), a1 + dt * (b1 + s1), a2 + dt * (b2 + s2)
    elif euler:
        if (t_s - t) > 1e-6 * dt:  # a clock within rounding of t_s counts as switched
            gain = eta / (t_d - t)
            s0, s1, s2 = gain * e0, gain * e1, gain * e2
        c0, c1, c2 = a0 + dt * (b0 + s0), a1 + dt * (b1 + s1), a2 + dt * (b2 + s2)
    else:
        h1 = min(max(t_s - t, 0.0), dt)  # the part of the step before t_s
        h2 = dt - h1
        if h1 > 0.0:  # the exact transition of eq. 7 (predefined_sta.exact_linear_step) up to t_s
            tau0 = max(t_d - t, 1e-300)
            r = (tau0 - h1) / tau0
            phi = r**eta
            psi = (tau0 - h1) * (1.0 - r ** (eta - 1.0)) / (eta - 1.0)
            a0, a1, a2 = y[0] - phi * e0 + psi * b0, y[1] - phi * e1 + psi * b1, y[2] - phi * e2 + psi * b2
        c0, c1, c2 = a0 + h2 * (b0 + s0), a1 + h2 * (b1 + s1), a2 + h2 * (b2 + s2)
    b0, b1, b2 = b0 + dt * xd0, b1 + dt * xd1, b2 + dt * xd2
    x1_out[0], x1_out[1], x1_out[2] = c0, c1, c2
    x2_out[0], x2_out[1], x2_out[2] = b0, b1, b2
    return math.isfinite(c0 + c1 + c2 + b0 + b1 + b2)


@njit(cache=True)
def _stsmo_rows(x1, x2, t, y, u, w, use_w, J, J_inv, p, dt, x1_out, x2_out):
    """:func:`stsmo_row` over the rows; ``w`` the given omega (``use_w``) or omega_hat of eq. 80.  Returns the
    first row whose new state is not finite, or -1."""
    bad = -1
    wi = np.empty(3)
    for i in range(x1.shape[0]):
        if use_w:
            wi[0], wi[1], wi[2] = w[i, 0], w[i, 1], w[i, 2]
        else:
            wi[0], wi[1], wi[2] = omega_row(x1[i, 0], x1[i, 1], x1[i, 2], x2[i, 0], x2[i, 1], x2[i, 2])
        ok = stsmo_row(x1[i], x2[i], t[i], y[i], u[i], wi, J, J_inv, p, dt, x1_out[i], x2_out[i])
        if not ok and bad < 0:
            bad = i
    return bad


class GibbsSTSMO:
    """Batch super-twisting observer of (g, g') from a Gibbs-vector measurement (eqs. 75-77 / 81-82).

    ``mode="predefined"``: sigma = eta/(t_d - t) x1_tilde for t < t_s, kappa1 x1_tilde/||x1_tilde||^(1/2)
    afterwards, t_s = ``t_switch`` (eq. 44's t_e) or ``t_c`` (eq. 77); t_d = t_c, or t_s with
    ``early_form="eq44"`` (eq. 44 as printed; see :mod:`fawtgym.observers.predefined_sta`).  ``mode="conventional"``:
    the STA term from the start (eq. 81).  Eq. 76/82: x2_hat' = 1/2 [Gamma'(x1_hat) omega + Gamma(x1_hat)
    J^-1 (J omega x omega + u + kappa2 x1_tilde/||x1_tilde||)].  Time t counts from :meth:`reset`.
    Parameters follow the paper's Table 1 / Sec. 5 by default (t_c = 1.5 s, eta = 5, kappa1 = 1, kappa2 = 1.5).

    State (arrays with a leading row axis): ``x1`` = g_hat (N, 3), ``x2`` = g_hat' (N, 3), ``t`` (N,) [s].
    """

    def __init__(self, inertia: ArrayLike, t_c: float = 1.5, eta: float = 5.0, kappa1: float = 1.0,
                 kappa2: float = 1.5, mode: str = "predefined", t_switch: float | None = None,
                 integrator: str = "exact", early_form: str = "tc") -> None:
        if mode not in ("predefined", "conventional"):
            raise ValueError(f"mode must be 'predefined' or 'conventional', got {shown(mode)}")
        if integrator not in ("exact", "euler"):
            raise ValueError(f"integrator must be 'exact' or 'euler', got {shown(integrator)}")
        check_params(t_c, eta, kappa2, kappa1)
        if t_switch is not None and not (0.0 < float(t_switch) <= t_c):
            raise ValueError(f"t_switch must lie in (0, t_c] = (0, {t_c}], got {shown(t_switch)}")
        J = np.asarray(inertia, dtype=float)
        J = np.diag(J) if J.shape == (3,) else J
        if J.shape != (3, 3) or not np.all(np.isfinite(J)) or np.linalg.eigvalsh((J + J.T) / 2).min() <= 0:
            raise ValueError(f"inertia must be positive definite 3x3 or 3 diagonal entries, got {shown(inertia)}")
        self.J = np.ascontiguousarray(J)
        self.J_inv = np.ascontiguousarray(np.linalg.inv(J))
        self.t_c, self.eta, self.kappa1, self.kappa2 = float(t_c), float(eta), float(kappa1), float(kappa2)
        self.mode, self.integrator = mode, integrator
        t_s, t_d = switch_and_gain_times(float(t_c), t_switch, early_form)
        self.t_s = t_s if mode == "predefined" else 0.0
        self.t_d = t_d
        self._p = self.params
        self.x1: NDArray[np.float64] = np.zeros((1, 3))
        self.x2: NDArray[np.float64] = np.zeros((1, 3))
        self.t: NDArray[np.float64] = np.zeros(1)

    @property
    def n(self) -> int:
        """Batch size N (set by :meth:`reset`)."""
        return self.x1.shape[0]

    @property
    def params(self) -> NDArray[np.float64]:
        """The constants ``p`` of :func:`stsmo_row`: (kappa1, kappa2, eta, t_s, t_d, conventional, euler)."""
        return np.array([self.kappa1, self.kappa2, self.eta, self.t_s, self.t_d, self.mode == "conventional",
                         self.integrator == "euler"], dtype=float)

    def reset(self, x1: ArrayLike, x2: ArrayLike | None = None, rows: ArrayLike | None = None) -> None:
        """Initial estimates g_hat(0) (N, 3) and g_hat'(0) (default 0); t = 0.

        ``rows``: None resets every row (N := the rows of ``x1``); a bool mask (N,) of the current batch resets
        the rows where it is True, ``x1`` / ``x2`` then giving one row per True entry (a masked write, the
        other rows keep their state and clock)."""
        x1 = np.atleast_2d(np.asarray(x1, dtype=float))
        x2 = np.zeros_like(x1) if x2 is None else np.broadcast_to(np.asarray(x2, dtype=float), x1.shape).copy()
        if x1.ndim != 2 or x1.shape[-1] != 3 or not (np.all(np.isfinite(x1)) and np.all(np.isfinite(x2))):
            raise ValueError(f"initial estimates must be finite with shape (N, 3), got {x1.shape}")
        if rows is not None:
            rows = check_row_mask(rows, self.n, "GibbsSTSMO")
            if x1.shape[0] != int(rows.sum()):
                raise ValueError(f"GibbsSTSMO: reset(rows=mask) needs one initial estimate per True row of the "
                                 f"mask ({int(rows.sum())}), got {x1.shape[0]}")
        self.x1 = np.ascontiguousarray(write_rows(self.x1, x1.copy(), rows))
        self.x2 = np.ascontiguousarray(write_rows(self.x2, x2, rows))
        self.t = np.ascontiguousarray(write_rows(self.t, np.zeros(x1.shape[0]), rows))

    @property
    def omega(self) -> NDArray[np.float64]:
        """omega_hat = 2 Gamma(x1_hat)^-1 x2_hat (eq. 80), (N, 3)."""
        from .gibbs import omega_from_gibbs

        return omega_from_gibbs(self.x1, self.x2)

    def step(self, y: ArrayLike, torque: ArrayLike, dt: float, omega: ArrayLike | None = None) -> None:
        """Advance by dt with the Gibbs measurement y = g_Q (eq. 79) (N, 3) and applied torque u (3,) or (N, 3)
        held; ``omega`` (N, 3) the angular velocity of eq. 76 (default omega_hat, eq. 80).

        Raises ValueError for a bad dt or input shape, FloatingPointError (the state unchanged) if the new state
        is not finite."""
        if isinstance(dt, bool) or not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite positive number of seconds, got {shown(dt)}")
        shape = (self.n, 3)
        args = []
        for label, value in (("y", y), ("torque", torque), ("omega", omega)):
            if value is None:
                args.append(self.x1)
                continue
            a = np.asarray(value, dtype=float)
            if a.shape != shape:
                if a.shape not in ((3,), (1, 3)):
                    raise ValueError(f"GibbsSTSMO: {label} must have shape (3,) or {shape}, got {a.shape}")
                a = np.broadcast_to(a.reshape(3), shape)
            if not np.isfinite(a).all():
                raise ValueError(f"GibbsSTSMO: {label} contains non-finite values")
            args.append(np.ascontiguousarray(a))
        x1_new, x2_new = np.empty(shape), np.empty(shape)
        bad = _stsmo_rows(self.x1, self.x2, self.t, args[0], args[1], args[2], omega is not None, self.J, self.J_inv,
                          self._p, float(dt), x1_new, x2_new)
        if bad >= 0:
            raise FloatingPointError(f"GibbsSTSMO: the Gibbs-vector estimate became non-finite in row {bad} "
                                     f"(dt = {dt} too large for the gains?)")
        self.x1, self.x2, self.t = x1_new, x2_new, self.t + dt
