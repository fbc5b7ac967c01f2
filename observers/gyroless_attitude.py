"""Gyroless attitude and angular-velocity estimation: QUEST + the (modified) super-twisting observer.

Source: Sec. 4-5.

* Gibbs-vector kinematics and dynamics (eqs. 45-55): attitude matrix D(g) (45), Gamma(g) (48),
  g' = 1/2 Gamma(g) omega (47), rigid body omega' = J^-1 (J omega x omega + u + d) (49),
  g'' (52) = 1/2 [Gamma'(g) omega + Gamma(g) omega'], Gamma' = g g'^T + g' g^T + [g' x].
* The multivariable modified super-twisting sliding-mode observer (STSMO, eqs. 75-77) and the
  conventional STSMO (eqs. 81-82), driven by the QUEST Gibbs vector g_Q (eq. 79), with angular
  velocity by certainty equivalence omega_hat = 2 Gamma(g_hat)^-1 g_hat' (eq. 80), where
  Gamma(g)^-1 = (I - [g x]) / (1 + g^T g).
* Early switching for noisy measurements (eqs. 43-44) via ``t_switch``.

Frames.  The paper's S^g (z along the local vertical) and S^b (z normal to the rotor plane) are taken
as world NED and body FRD (its local field m_g = [13.7, -4.6, -10.9] uT has the NED shape of the
field at its authors' site).  Its D^{b/g} maps world to body components, so D = R^T with the
project's R (body -> world): :func:`gibbs_to_rot` returns R = D(g)^T and :func:`rot_to_gibbs` the
g of D = R^T.  The paper's accelerometer reference is a_g = g e3 (eq. 50), the gravity direction;
the project's ``specific_force`` is R^T (a - g e3), so the env estimator uses -g e3 as the
accelerometer's reference vector (the same direction pairing, the sensor's sign).

Known inputs.  Eq. 76 evaluates Gamma' omega and J omega x omega at the *true* angular velocity
(the paper's simulation passes the forcing omega(t) of eq. 78 to the observer).  A gyroless
estimator has no true omega: :class:`GibbsSTSMO` takes it when given (``omega=...``, the paper's
setting) and otherwise uses its own estimate omega_hat of eq. 80 (certainty equivalence), which is
what the env estimator :class:`PdtStaAttitudeObserver` does.

Discretization.  The time-varying term eta/(t_c - t) x1_tilde of eq. 77 is integrated exactly over a
step with the measurement held (the transition of eq. 7, :func:`fawtgym.observers.pdt_sta.exact_linear_step`),
so the step stays stable up to t_s for any dt; everything else is forward Euler as in the paper
(Sec. 5, T_s = 1e-4 s).  ``integrator="euler"`` uses forward Euler for that term too (the paper).

Single vehicle.  For N = 1 the same equations run on plain Python floats
(:func:`~fawtgym.observers.quest.quest_floats`, :meth:`GibbsSTSMO.advance_floats`,
:meth:`PdtStaAttitudeObserver._update_single`): a 1-element numpy operation costs ~1 us and the batched update
takes well over a hundred of them.  The batched numpy path is the reference; the two agree to ~1e-14
(tests/test_obs2_pdt_fastpath.py), differing only in the rounding order of a few sums.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.measurement import EARTH_FIELD_NED, MAGNETOMETER, SPECIFIC_FORCE
from fawtgym.core.rows import check_row_mask, write_rows
from fawtgym.core.so3 import hat, matmul33_floats, vee

from ._obs_common import single_inputs
from .base import Observer, ObserverEstimate, register_observer
from .pdt_sta import check_params, switch_and_gain_times
from .quest import _cross as _cross_any
from .quest import _quest_unit_batch, quest_floats, quest_unit

_EYE = np.eye(3)


# --------------------------------------------------------------------------------------------------
# Gibbs-vector kinematics, eqs. 45-55 and 80
# --------------------------------------------------------------------------------------------------
def gibbs_matrix(g: ArrayLike) -> NDArray[np.float64]:
    """D(g) of eq. 45 (world -> body components), (..., 3) -> (..., 3, 3)."""
    g = np.asarray(g, dtype=float)
    gg = np.sum(g * g, axis=-1)[..., None, None]
    return ((1.0 - gg) * _EYE + 2.0 * g[..., :, None] * g[..., None, :] - 2.0 * hat(g)) / (1.0 + gg)


# hat(g) flattened row-major = g @ _HAT_FLAT (entries 0, +-1: exact)
_HAT_FLAT = np.zeros((3, 9))
_HAT_FLAT[[2, 1, 2, 0, 1, 0], [1, 2, 3, 5, 6, 7]] = [-1.0, 1.0, 1.0, -1.0, -1.0, 1.0]
_EYE_FLAT = _EYE.reshape(9)


def gibbs_to_rot(g: ArrayLike) -> NDArray[np.float64]:
    """R = D(g)^T = ((1 - g.g) I + 2 g g^T + 2 [g x]) / (1 + g.g), body -> world (NED/FRD)."""
    g = np.asarray(g, dtype=float)
    gg = (g * g).sum(axis=-1)[..., None]
    outer = (g[..., :, None] * g[..., None, :]).reshape(g.shape[:-1] + (9,))
    R = ((1.0 - gg) * _EYE_FLAT + 2.0 * outer + 2.0 * (g @ _HAT_FLAT)) / (1.0 + gg)
    return R.reshape(g.shape[:-1] + (3, 3))


def rot_to_gibbs(R: ArrayLike) -> NDArray[np.float64]:
    """Gibbs vector g of D = R^T: g = tan(theta/2) a for R = exp(theta a^); raises at a half turn."""
    R = np.asarray(R, dtype=float)
    den = 1.0 + np.trace(R, axis1=-2, axis2=-1)
    if np.any(den <= 1e-9):
        raise ValueError("rotation is (near) a half turn: its Gibbs vector is infinite")
    return 2.0 * vee(R) / den[..., None]


def gamma(g: ArrayLike) -> NDArray[np.float64]:
    """Gamma(g) = g g^T + [g x] + I (eq. 48)."""
    g = np.asarray(g, dtype=float)
    return g[..., :, None] * g[..., None, :] + hat(g) + _EYE


def gamma_inv(g: ArrayLike) -> NDArray[np.float64]:
    """Gamma(g)^-1 = (I - [g x]) / (1 + g^T g) (Gamma is invertible for every finite g)."""
    g = np.asarray(g, dtype=float)
    return (_EYE - hat(g)) / (1.0 + np.sum(g * g, axis=-1))[..., None, None]


def gibbs_rate(g: ArrayLike, omega: ArrayLike) -> NDArray[np.float64]:
    """g' = 1/2 Gamma(g) omega (eq. 47), omega body FRD [rad/s]."""
    return 0.5 * np.einsum("...ij,...j->...i", gamma(g), np.asarray(omega, dtype=float))


def omega_from_gibbs(g: ArrayLike, g_dot: ArrayLike) -> NDArray[np.float64]:
    """omega = 2 Gamma(g)^-1 g' (eq. 80)."""
    return 2.0 * np.einsum("...ij,...j->...i", gamma_inv(g), np.asarray(g_dot, dtype=float))


def gibbs_accel(g: ArrayLike, g_dot: ArrayLike, omega: ArrayLike, inertia: ArrayLike, torque: ArrayLike,
                disturbance: ArrayLike | None = None) -> NDArray[np.float64]:
    """g'' of eq. 52 / 54: 1/2 [Gamma'(g) omega + Gamma(g) J^-1 (J omega x omega + u + d)]."""
    g = np.asarray(g, dtype=float)
    g_dot = np.asarray(g_dot, dtype=float)
    omega = np.asarray(omega, dtype=float)
    J = np.asarray(inertia, dtype=float)
    tau = np.asarray(torque, dtype=float) + (0.0 if disturbance is None else np.asarray(disturbance, dtype=float))
    gamma_dot = g[..., :, None] * g_dot[..., None, :] + g_dot[..., :, None] * g[..., None, :] + hat(g_dot)
    omega_dot = rigid_body_rhs(omega, J, tau)
    return 0.5 * (np.einsum("...ij,...j->...i", gamma_dot, omega) + np.einsum("...ij,...j->...i", gamma(g), omega_dot))


def rigid_body_rhs(omega: ArrayLike, inertia: ArrayLike, torque: ArrayLike) -> NDArray[np.float64]:
    """omega' = J^-1 (J omega x omega + tau) (eq. 49; Wang et al. (2024) eq. 38 in FRD)."""
    J = np.asarray(inertia, dtype=float)
    w = np.asarray(omega, dtype=float)
    return np.einsum("ij,...j->...i", np.linalg.inv(J), np.cross(np.einsum("ij,...j->...i", J, w), w)
                     + np.asarray(torque, dtype=float))


# --------------------------------------------------------------------------------------------------
# the observer core, eqs. 75-77 (modified) and 81-82 (conventional)
# --------------------------------------------------------------------------------------------------
def _units(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(x / ||x||, x / ||x||^(1/2)) row-wise, 0 at x = 0 (the set-valued sign's zero selection)."""
    n = np.sqrt(_sum3(x * x))[:, None]
    pos = n > 0
    if pos.all():
        return x / n, x / np.sqrt(n)
    safe = np.where(pos, n, 1.0)
    return np.where(pos, x / safe, 0.0), np.where(pos, x / np.sqrt(safe), 0.0)


_cross = _cross_any  # row-wise a x b for (N, 3) arrays


def _sum3(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """p[..., 0] + p[..., 1] + p[..., 2] (the order of a length-3 sum; faster than .sum(-1) for large N)."""
    return p[..., 0] + p[..., 1] + p[..., 2]


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    return _sum3(a * b)[:, None]


def _omega_fast(g: NDArray[np.float64], g_dot: NDArray[np.float64]) -> NDArray[np.float64]:
    """Eq. 80 for (N, 3) rows: 2 (g' - g x g') / (1 + g.g)."""
    return 2.0 * (g_dot - _cross(g, g_dot)) / (1.0 + _dot(g, g))


class GibbsSTSMO:
    """Batch super-twisting observer of (g, g') from a Gibbs-vector measurement (eqs. 75-77 / 81-82).

    ``mode="predefined"``: sigma = eta/(t_d - t) x1_tilde for t < t_s, kappa1 x1_tilde/||x1_tilde||^(1/2)
    afterwards, t_s = ``t_switch`` (eq. 44's t_e) or ``t_c`` (eq. 77); t_d = t_c, or t_s with
    ``early_form="eq44"`` (eq. 44 as printed; see :mod:`fawtgym.observers.pdt_sta`).  ``mode="conventional"``: the
    STA term from the start (eq. 81).  Eq. 76/82: x2_hat' = 1/2 [Gamma'(x1_hat) omega + Gamma(x1_hat)
    J^-1 (J omega x omega + u + kappa2 x1_tilde/||x1_tilde||)].  Time t counts from :meth:`reset`.
    Parameters follow the paper's Table 1 / Sec. 5 by default (t_c = 1.5 s, eta = 5, kappa1 = 1,
    kappa2 = 1.5).
    """

    def __init__(self, inertia: ArrayLike, t_c: float = 1.5, eta: float = 5.0, kappa1: float = 1.0,
                 kappa2: float = 1.5, mode: str = "predefined", t_switch: float | None = None,
                 integrator: str = "exact", early_form: str = "tc") -> None:
        if mode not in ("predefined", "conventional"):
            raise ValueError(f"mode must be 'predefined' or 'conventional', got {mode!r}")
        if integrator not in ("exact", "euler"):
            raise ValueError(f"integrator must be 'exact' or 'euler', got {integrator!r}")
        check_params(t_c, eta, kappa2, kappa1)
        if t_switch is not None and not (0.0 < float(t_switch) <= t_c):
            raise ValueError(f"t_switch must lie in (0, t_c] = (0, {t_c}], got {t_switch!r}")
        J = np.asarray(inertia, dtype=float)
        J = np.diag(J) if J.shape == (3,) else J
        if J.shape != (3, 3) or np.linalg.eigvalsh((J + J.T) / 2).min() <= 0:
            raise ValueError(f"inertia must be positive definite 3x3 or 3 diagonal entries, got {inertia!r}")
        self.J = J
        self.J_inv = np.linalg.inv(J)
        self._J_flat, self._J_inv_flat = tuple(J.ravel().tolist()), tuple(self.J_inv.ravel().tolist())
        self.t_c, self.eta, self.kappa1, self.kappa2 = float(t_c), float(eta), float(kappa1), float(kappa2)
        self.mode, self.integrator = mode, integrator
        t_s, t_d = switch_and_gain_times(float(t_c), t_switch, early_form)
        self.t_s = t_s if mode == "predefined" else 0.0
        self.t_d = t_d
        self._x1: NDArray[np.float64] = np.zeros((1, 3))
        self._x2: NDArray[np.float64] = np.zeros((1, 3))
        self._t: NDArray[np.float64] = np.zeros(1)
        #: N = 1 state as Python floats (x1, x2, t) after a float step, written to the arrays when they are read
        self._floats: tuple[list[float], list[float], float] | None = None

    # the state (N, 3), (N, 3), (N,): arrays, materialized from the N = 1 float state on access
    def _sync(self) -> None:
        if self._floats is not None:
            x1, x2, t = self._floats
            self._x1, self._x2, self._t, self._floats = np.array([x1]), np.array([x2]), np.array([t]), None

    @property
    def x1(self) -> NDArray[np.float64]:
        """g_hat (N, 3)."""
        self._sync()
        return self._x1

    @x1.setter
    def x1(self, value: NDArray[np.float64]) -> None:
        self._sync()
        self._x1 = value

    @property
    def x2(self) -> NDArray[np.float64]:
        """g_hat' (N, 3)."""
        self._sync()
        return self._x2

    @x2.setter
    def x2(self, value: NDArray[np.float64]) -> None:
        self._sync()
        self._x2 = value

    @property
    def t(self) -> NDArray[np.float64]:
        """Time since :meth:`reset` (N,) [s]."""
        self._sync()
        return self._t

    @t.setter
    def t(self, value: NDArray[np.float64]) -> None:
        self._sync()
        self._t = value

    @property
    def n(self) -> int:
        """Batch size N (set by :meth:`reset`)."""
        return self._x1.shape[0]

    def state_floats(self) -> tuple[list[float], list[float], float]:
        """(x1, x2, t) of an N = 1 observer as Python floats."""
        if self._floats is not None:
            return self._floats
        return self._x1[0].tolist(), self._x2[0].tolist(), float(self._t[0])

    def reset(self, x1: ArrayLike, x2: ArrayLike | None = None, rows: ArrayLike | None = None) -> None:
        """Initial estimates g_hat(0) (N, 3) and g_hat'(0) (default 0); t = 0.

        ``rows``: None resets every row (N := the rows of ``x1``); a bool mask (N,) of the current batch resets
        the rows where it is True, ``x1`` / ``x2`` then giving one row per True entry (a masked write, the
        other rows keep their state and clock)."""
        x1 = np.atleast_2d(np.asarray(x1, dtype=float))
        x2 = np.zeros_like(x1) if x2 is None else np.broadcast_to(np.asarray(x2, dtype=float), x1.shape).copy()
        if x1.shape[-1] != 3 or not (np.all(np.isfinite(x1)) and np.all(np.isfinite(x2))):
            raise ValueError(f"initial estimates must be finite with shape (N, 3), got {x1.shape}")
        if rows is not None:
            rows = check_row_mask(rows, self.n, "GibbsSTSMO")
            if x1.shape[0] != int(rows.sum()):
                raise ValueError(f"GibbsSTSMO: reset(rows=mask) needs one initial estimate per True row of the "
                                 f"mask ({int(rows.sum())}), got {x1.shape[0]}")
        self.x1, self.x2 = write_rows(self.x1, x1.copy(), rows), write_rows(self.x2, x2, rows)
        self.t = write_rows(self.t, np.zeros(x1.shape[0]), rows)

    @property
    def omega(self) -> NDArray[np.float64]:
        """omega_hat = 2 Gamma(x1_hat)^-1 x2_hat (eq. 80)."""
        return _omega_fast(self.x1, self.x2)

    def step(self, y: ArrayLike, torque: ArrayLike, dt: float, omega: ArrayLike | None = None) -> None:
        """Advance by dt with the Gibbs measurement y = g_Q (eq. 79) and applied torque u held."""
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite positive number of seconds, got {dt!r}")
        y = np.asarray(y, dtype=float)
        u = np.asarray(torque, dtype=float)
        shape = (self.n, 3)
        if u.shape != shape:
            u = np.broadcast_to(u, shape)
        if shape[0] == 1 and omega is None and y.shape == shape:
            self._step_single(y[0].tolist(), u[0].tolist(), float(dt))
            return
        x1, x2, t = self.x1, self.x2, self.t
        e1 = y - x1  # eq. 79
        w = self.omega if omega is None else np.broadcast_to(np.asarray(omega, dtype=float), x1.shape)
        unit1, sta = _units(e1)
        # eq. 76 / 82 with Gamma'(g) w = g (g'.w) + g' (g.w) + g' x w and Gamma(g) v = g (g.v) + g x v + v
        gamma_dot_w = x1 * _dot(x2, w) + x2 * _dot(x1, w) + _cross(x2, w)
        v = _matvec(self.J_inv, _cross(_matvec(self.J, w), w) + u + self.kappa2 * unit1)
        x2_dot = 0.5 * (gamma_dot_w + x1 * _dot(x1, v) + _cross(x1, v) + v)
        # eq. 75 / 77 / 81
        sta = self.kappa1 * sta
        if self.mode == "conventional":
            x1_new = x1 + dt * (x2 + sta)
        elif self.integrator == "euler":
            tv = (self.t_s - t) > 1e-6 * dt  # a clock within rounding of t_s counts as switched
            gain = np.where(tv, self.eta / np.where(tv, self.t_d - t, 1.0), 0.0)[:, None]
            x1_new = x1 + dt * (x2 + np.where(tv[:, None], gain * e1, sta))
        else:
            h1 = np.clip(self.t_s - t, 0.0, dt)
            h2 = (dt - h1)[:, None]
            if (h1 > 0).any():
                tau0 = np.maximum(self.t_d - t, 1e-300)
                r = ((tau0 - h1) / tau0)[:, None]
                phi = r**self.eta  # eq. 7 transition (see pdt_sta.exact_linear_step)
                psi = (tau0 - h1)[:, None] * (1.0 - r ** (self.eta - 1.0)) / (self.eta - 1.0)
                x1_new = np.where(h1[:, None] > 0, y - phi * e1 + psi * x2, x1)
            else:
                x1_new = x1
            x1_new = x1_new + h2 * (x2 + sta)
        self.x1 = x1_new
        self.x2 = x2 + dt * x2_dot
        self.t = t + dt
        if not (np.isfinite(self.x1).all() and np.isfinite(self.x2).all()):
            raise ValueError("observer state became non-finite (step too large for the gains?)")

    def _step_single(self, y: list[float], u: list[float], dt: float) -> None:
        """:meth:`step` for N = 1 with omega_hat (eq. 80) on plain floats (see :meth:`advance_floats`)."""
        x1, x2, t = self.state_floats()
        x1, x2 = self.advance_floats(x1, x2, t, y, u, dt)
        self._floats = (x1, x2, t + dt)

    def advance_floats(self, x1: list[float], x2: list[float], t: float, y: list[float], u: list[float],
                       dt: float) -> tuple[list[float], list[float]]:
        """One step of eqs. 75-77 (or 81-82) for one vehicle on plain floats, omega = omega_hat of eq. 80: the
        state (x1, x2) at time t, the Gibbs measurement y (eq. 79) and torque u held over dt -> the new
        (x1, x2).  The same formulas in the same order as the batched :meth:`step` (1-element numpy arrays
        cost ~1 us per operation); raises ValueError if the new state is not finite.  Does not touch the
        stored state."""
        a0, a1, a2 = x1
        b0, b1, b2 = x2
        y0, y1, y2 = y
        e0, e1, e2 = y0 - a0, y1 - a1, y2 - a2  # eq. 79
        # eq. 80: omega_hat = 2 (g' - g x g') / (1 + g.g)
        den = 1.0 + (a0 * a0 + a1 * a1 + a2 * a2)
        w0 = 2.0 * (b0 - (a1 * b2 - a2 * b1)) / den
        w1 = 2.0 * (b1 - (a2 * b0 - a0 * b2)) / den
        w2 = 2.0 * (b2 - (a0 * b1 - a1 * b0)) / den
        n = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if n > 0:  # x1_tilde / ||x1_tilde|| and x1_tilde / ||x1_tilde||^(1/2) (0 at 0, see _units)
            sn = math.sqrt(n)
            n0, n1, n2, s0, s1, s2 = e0 / n, e1 / n, e2 / n, e0 / sn, e1 / sn, e2 / sn
        else:
            n0 = n1 = n2 = s0 = s1 = s2 = 0.0
        # eq. 76 / 82 with Gamma'(g) w = g (g'.w) + g' (g.w) + g' x w and Gamma(g) v = g (g.v) + g x v + v
        d2w = b0 * w0 + b1 * w1 + b2 * w2
        d1w = a0 * w0 + a1 * w1 + a2 * w2
        gd0 = a0 * d2w + b0 * d1w + (b1 * w2 - b2 * w1)
        gd1 = a1 * d2w + b1 * d1w + (b2 * w0 - b0 * w2)
        gd2 = a2 * d2w + b2 * d1w + (b0 * w1 - b1 * w0)
        j00, j01, j02, j10, j11, j12, j20, j21, j22 = self._J_flat
        jw0 = j00 * w0 + j01 * w1 + j02 * w2
        jw1 = j10 * w0 + j11 * w1 + j12 * w2
        jw2 = j20 * w0 + j21 * w1 + j22 * w2
        k2 = self.kappa2
        u0, u1, u2 = u
        q0 = (jw1 * w2 - jw2 * w1) + u0 + k2 * n0
        q1 = (jw2 * w0 - jw0 * w2) + u1 + k2 * n1
        q2 = (jw0 * w1 - jw1 * w0) + u2 + k2 * n2
        i00, i01, i02, i10, i11, i12, i20, i21, i22 = self._J_inv_flat
        v0 = i00 * q0 + i01 * q1 + i02 * q2
        v1 = i10 * q0 + i11 * q1 + i12 * q2
        v2 = i20 * q0 + i21 * q1 + i22 * q2
        d1v = a0 * v0 + a1 * v1 + a2 * v2
        xd0 = 0.5 * (gd0 + a0 * d1v + (a1 * v2 - a2 * v1) + v0)
        xd1 = 0.5 * (gd1 + a1 * d1v + (a2 * v0 - a0 * v2) + v1)
        xd2 = 0.5 * (gd2 + a2 * d1v + (a0 * v1 - a1 * v0) + v2)
        # eq. 75 / 77 / 81
        k1 = self.kappa1
        s0, s1, s2 = k1 * s0, k1 * s1, k1 * s2
        if self.mode == "conventional":
            c0, c1, c2 = a0 + dt * (b0 + s0), a1 + dt * (b1 + s1), a2 + dt * (b2 + s2)
        elif self.integrator == "euler":
            if (self.t_s - t) > 1e-6 * dt:  # a clock within rounding of t_s counts as switched
                gain = self.eta / (self.t_d - t)
                s0, s1, s2 = gain * e0, gain * e1, gain * e2
            c0, c1, c2 = a0 + dt * (b0 + s0), a1 + dt * (b1 + s1), a2 + dt * (b2 + s2)
        else:
            h1 = self.t_s - t  # clip(t_s - t, 0, dt)
            h1 = (h1 if h1 < dt else dt) if h1 > 0.0 else 0.0
            h2 = dt - h1
            if h1 > 0:  # the exact transition of eq. 7 (see pdt_sta.exact_linear_step) up to t_s
                tau0 = max(self.t_d - t, 1e-300)
                r = (tau0 - h1) / tau0
                phi = float(np.power(r, self.eta))  # numpy's pow, as the batched path (libm's differs by 1 ulp)
                psi = (tau0 - h1) * (1.0 - float(np.power(r, self.eta - 1.0))) / (self.eta - 1.0)
                a0, a1, a2 = y0 - phi * e0 + psi * b0, y1 - phi * e1 + psi * b1, y2 - phi * e2 + psi * b2
            c0, c1, c2 = a0 + h2 * (b0 + s0), a1 + h2 * (b1 + s1), a2 + h2 * (b2 + s2)
        b0, b1, b2 = b0 + dt * xd0, b1 + dt * xd1, b2 + dt * xd2
        if not math.isfinite(c0 + c1 + c2 + b0 + b1 + b2):
            raise ValueError("observer state became non-finite (step too large for the gains?)")
        return [c0, c1, c2], [b0, b1, b2]


def _matvec(A: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows A x for (N, 3) x, as explicit products and sums (no BLAS: the rounding of the plain-float N = 1 path)."""
    return x[:, 0:1] * A[:, 0] + x[:, 1:2] * A[:, 1] + x[:, 2:3] * A[:, 2]


# --------------------------------------------------------------------------------------------------
# the env estimator
# --------------------------------------------------------------------------------------------------
@register_observer("pdt_sta")
class PdtStaAttitudeObserver(Observer):
    """Gyroless attitude/rate estimator: QUEST (accelerometer + magnetometer) + predefined-time STSMO.

    Reads ``specific_force`` and ``magnetometer`` only (no gyro, no attitude), uses the applied body
    torque u and J (eq. 76), and reports ``states["attitude"]`` R_hat (N, 3, 3), ``states["angular_velocity"]``
    omega_hat (N, 3) (eq. 80), ``states["attitude_quest"]`` (the static QUEST attitude),
    ``states["gibbs"]`` and ``states["quest_valid"]`` (N,) (False where the vectors gave no attitude and
    the step ran without correction, see :meth:`_quest`).  It estimates no disturbance: force and
    torque are zeros, ``channels`` is empty.

    Defaults: t_c = 1.5 s and eta = 5 (paper Sec. 5); ``noise_bound`` ell = 0 (t_e = t_c; with ell > 0
    the switch is eq. 43's t_e = t_c - eta ell).  The gains are NOT the paper's (kappa1, kappa2) =
    (1, 1.5): those were tuned for J = diag(0.05, 0.05, 0.02) at T_s = 1e-4 s, and at env rates
    (100-500 Hz) the STA phase after t_c falls into a large limit cycle (0.1 rad attitude, 2-5 rad/s
    rate error measured with J = diag(0.03, 0.03, 0.06)).  Here the effective injection
    1/2 kappa2 J^-1 of eq. 76 is sized instead: ``kappa2=None`` means kappa2 = 6 lambda_min(J) (largest
    entry of 1/2 kappa2 J^-1 = 3 rad/s^2 =: L) and kappa1 = 2.5 ~ 1.5 sqrt(L) (the usual STA rule
    k1 = 1.5 sqrt(L), k2 = 1.1 L).  Pass kappa1=1, kappa2=1.5 for the paper's values.
    ``mode="predefined"`` ("conventional" gives eqs. 81-82), QUEST weights (accelerometer,
    magnetometer) = (1, 1) (the paper uses the inverse noise levels), field ``EARTH_FIELD_NED``.
    Assumes small linear acceleration (the paper's v' = 0 of eq. 50): the accelerometer stands in
    for the gravity direction.

    The Gibbs vector is singular at a half turn, so the observer works relative to an anchor
    attitude R_a (the QUEST attitude at reset): it estimates g of (R_a^T R)^T and re-anchors a row to
    its current estimate (keeping omega_hat) whenever ||g_hat|| exceeds ``reanchor`` (default 1, 90 deg).
    """

    channels = frozenset()

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = 9.80665, t_c: float = 1.5,
                 eta: float = 5.0, kappa1: float = 2.5, kappa2: float | None = None, noise_bound: float = 0.0,
                 mode: str = "predefined", weights: tuple[float, float] = (1.0, 1.0),
                 magnetic_field: ArrayLike = EARTH_FIELD_NED, reanchor: float = 1.0) -> None:
        super().__init__(mass, inertia, gravity)
        from .pdt_sta import early_switch_time

        t_switch = early_switch_time(t_c, eta, noise_bound) if noise_bound > 0 else None
        if kappa2 is None:
            kappa2 = 6.0 * float(np.linalg.eigvalsh(self.inertia).min())
        self.core = GibbsSTSMO(self.inertia, t_c, eta, kappa1, kappa2, mode, t_switch)
        w = np.asarray(weights, dtype=float)
        if w.shape != (2,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise ValueError(f"weights must be two positive numbers (accelerometer, magnetometer), got {weights!r}")
        self.weights = w
        m = np.asarray(magnetic_field, dtype=float)
        if m.shape != (3,) or not np.all(np.isfinite(m)) or np.linalg.norm(np.cross(m, [0, 0, 1.0])) < 1e-6:
            raise ValueError("magnetic_field must be a finite 3-vector not parallel to gravity, "
                             f"got {magnetic_field!r}")
        if not (np.isfinite(reanchor) and 0 < reanchor <= 10):
            raise ValueError(f"reanchor must lie in (0, 10] (a Gibbs-vector norm), got {reanchor!r}")
        self.reanchor = float(reanchor)
        self.references = np.stack([np.array([0.0, 0.0, -self.gravity]), m])  # specific force at rest, field
        self._ref_unit = (self.references / np.sqrt((self.references**2).sum(axis=-1, keepdims=True)))[None]
        self._weights_row = w[None]
        self._min_field = 0.1 * float(np.linalg.norm(m))
        self.anchor = np.eye(3)[None]
        # plain-float copies for the N = 1 path (the anchor's, refreshed when self.anchor is replaced)
        self._ref_list, self._weights_list = self._ref_unit[0].tolist(), w.tolist()
        self._anchor_src: NDArray[np.float64] | None = None
        self._anchor_list: list[float] = []

    def _quest(self, meas: Mapping[str, NDArray[np.float64]],
               predict: Callable[[], NDArray[np.float64]] | None = None
               ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """QUEST attitude and a validity mask.  A row whose accelerometer reads < 0.2 g (free fall, a
        hard manoeuvre), whose magnetometer reads < 10 % of the reference field, or whose two vectors are
        within 1 deg of parallel gives no usable attitude: with ``predict`` (returning the current
        estimate) that row's vectors are replaced by the predicted ones (no correction this step);
        without it (reset) ValueError is raised.  The checks here are QUEST's preconditions, so
        :func:`quest_unit` runs without repeating :func:`~fawtgym.observers.quest.quest`'s validation."""
        for key in (SPECIFIC_FORCE, MAGNETOMETER):
            if key not in meas:
                raise ValueError(f"pdt_sta needs measurement[{key!r}] (accelerometer + magnetometer)")
        sf, mag = meas[SPECIFIC_FORCE], meas[MAGNETOMETER]
        body = np.empty(np.broadcast_shapes(sf.shape, mag.shape)[:1] + (2, 3))
        body[:, 0] = sf
        body[:, 1] = mag
        if not np.isfinite(body).all():
            raise ValueError("specific_force/magnetometer contain non-finite values")
        norms = np.sqrt((body * body).sum(axis=-1))
        na, nm = norms[:, 0], norms[:, 1]
        c = _cross(body[:, 0], body[:, 1])
        sin = np.sqrt((c * c).sum(axis=-1)) / np.maximum(na * nm, 1e-300)
        valid = (na > 0.2 * self.gravity) & (nm > self._min_field) & (sin > 0.0175)
        if not valid.all():
            if predict is None:
                raise ValueError("cannot initialize pdt_sta: accelerometer/magnetometer give no attitude "
                                 f"(rows {np.nonzero(~valid)[0].tolist()}: |a| < 0.2 g, weak field or parallel)")
            body[~valid] = np.einsum("nji,kj->nki", predict()[~valid], self.references)
            norms = np.sqrt((body * body).sum(axis=-1))
        body /= norms[:, :, None]
        return quest_unit(body, self._ref_unit, self._weights_row).R, valid

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None) -> int:
        """Anchor R_a := the QUEST attitude, g_hat = g_hat' = 0, clock t = 0 (force/torque guesses unused).

        State: ``anchor`` (N, 3, 3) and the core's x1, x2 (N, 3) and t (N,) (:meth:`GibbsSTSMO.reset`, which
        syncs its N = 1 float state first); a new ``anchor`` array refreshes the N = 1 path's float copy of it."""
        from fawtgym.core.measurement import batch_measurement

        R_q, _ = self._quest(batch_measurement(measurement))
        self.core.reset(np.zeros((R_q.shape[0], 3)), rows=rows)
        self.anchor = write_rows(self.anchor, R_q, rows)
        return R_q.shape[0]

    def update(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
               dt: float) -> ObserverEstimate:
        if self.core._x1.shape[0] == 1:
            est = self._update_single(measurement, thrust, torque, dt)
            if est is not None:
                return est
        meas, _, tau = self._inputs(measurement, thrust, torque, dt)
        n = self.core.x1.shape[0]
        if meas[SPECIFIC_FORCE].shape[0] != n:
            raise ValueError(f"batch size changed from {n} to {meas[SPECIFIC_FORCE].shape[0]}; call reset first")
        R_q, valid = self._quest(meas, predict=lambda: self.anchor @ gibbs_to_rot(self.core.x1))
        rel = np.swapaxes(self.anchor, -1, -2) @ R_q
        y = _safe_gibbs(rel)
        if not valid.all():
            # no attitude from the vectors: feed the prediction back exactly, so e1 = 0 and no correction is
            # applied (the rounding noise of a predicted measurement would otherwise be amplified by the
            # discontinuous kappa2 e1/|e1| term into a full-size kick)
            y[~valid] = self.core.x1[~valid]
        self.core.step(y, tau if tau.shape == (n, 3) else np.broadcast_to(tau, (n, 3)), dt)
        self._maybe_reanchor()
        R_hat = self.anchor @ gibbs_to_rot(self.core.x1)
        zeros = np.zeros((n, 3))
        return ObserverEstimate(force=zeros, torque=zeros.copy(), states={
            "attitude": R_hat, "angular_velocity": self.core.omega, "attitude_quest": R_q,
            "gibbs": self.core.x1.copy(), "quest_valid": valid})

    def _update_single(self, measurement: Mapping[str, ArrayLike], thrust: ArrayLike, torque: ArrayLike,
                       dt: float) -> ObserverEstimate | None:
        """N = 1 fast path of :meth:`update` on plain Python floats: the validity test of :meth:`_quest`, QUEST
        (eqs. 57-66, :func:`~fawtgym.observers.quest.quest_floats`), the Gibbs measurement relative to the
        anchor (eq. 79, :func:`_safe_gibbs`), the STSMO step (eqs. 75-77 / 81-82, :meth:`GibbsSTSMO.advance_floats`),
        the re-anchoring (:meth:`_maybe_reanchor`) and the outputs R_hat = R_a D(g_hat)^T (eq. 45) and omega_hat
        (eq. 80), in the same order as the batched path (small numpy operations cost ~1 us each).

        Returns None, touching nothing, unless the step is a well-formed, finite single-vehicle step whose
        vectors give an attitude (the batched path then runs: it raises the usual errors and handles a row
        without a vector attitude); also the rare QUEST eigenvector branch (eq. 64) is taken from the batched
        QUEST.
        """
        inputs = single_inputs(measurement, _QUEST_KEYS, thrust, torque, dt)
        if inputs is None:
            return None
        (sf, mag), _, u = inputs
        f0, f1, f2 = sf
        m0, m1, m2 = mag
        # _quest's validity test: |a| >= 0.2 g, |m| >= 10 % of the field, the vectors >= 1 deg from parallel
        na = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        nm = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        c0, c1, c2 = f1 * m2 - f2 * m1, f2 * m0 - f0 * m2, f0 * m1 - f1 * m0
        nn = na * nm
        sin = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / (nn if nn > 1e-300 else 1e-300)
        if not (na > 0.2 * self.gravity and nm > self._min_field and sin > 0.0175):
            return None
        body = [[f0 / na, f1 / na, f2 / na], [m0 / nm, m1 / nm, m2 / nm]]
        res = quest_floats(body, self._ref_list, self._weights_list)
        if res is None:  # near a half turn from NED: the eigenvector of K (eq. 64), batched
            rq = _quest_unit_batch(np.array([body]), self._ref_unit, self._weights_row).R[0].ravel().tolist()
        else:
            rq = res[0]
        if self._anchor_src is not self.anchor:
            self._anchor_src, self._anchor_list = self.anchor, self.anchor[0].ravel().tolist()
        A = self._anchor_list
        # y = Gibbs vector of D = rel^T, rel = R_a^T R_q (eq. 79), as _safe_gibbs: 2 vee(rel) / (1 + tr rel)
        a00, a01, a02, a10, a11, a12, a20, a21, a22 = A
        q00, q01, q02, q10, q11, q12, q20, q21, q22 = rq
        den = 1.0 + ((a00 * q00 + a10 * q10 + a20 * q20) + (a01 * q01 + a11 * q11 + a21 * q21)
                     + (a02 * q02 + a12 * q12 + a22 * q22))
        den = den if den > 1e-6 else 1e-6
        y = [2.0 * (0.5 * ((a02 * q01 + a12 * q11 + a22 * q21) - (a01 * q02 + a11 * q12 + a21 * q22))) / den,
             2.0 * (0.5 * ((a00 * q02 + a10 * q12 + a20 * q22) - (a02 * q00 + a12 * q10 + a22 * q20))) / den,
             2.0 * (0.5 * ((a01 * q00 + a11 * q10 + a21 * q20) - (a00 * q01 + a10 * q11 + a20 * q21))) / den]
        yy = y[0] * y[0] + y[1] * y[1] + y[2] * y[2]
        if yy > 1e5:
            ny = math.sqrt(yy)
            if ny > 1e3:
                y = [yi * 1e3 / ny for yi in y]
        core = self.core
        x1, x2, t = core._floats or core.state_floats()
        x1, x2 = core.advance_floats(x1, x2, t, y, u, dt)
        g0, g1, g2 = x1
        if math.sqrt(g0 * g0 + g1 * g1 + g2 * g2) > self.reanchor:  # _maybe_reanchor
            w = _omega_floats(x1, x2)
            A = matmul33_floats(A, _gibbs_to_rot_floats(x1))
            self.anchor = np.array(A).reshape(1, 3, 3)
            self._anchor_src, self._anchor_list = self.anchor, A
            x1, x2 = [0.0, 0.0, 0.0], [0.5 * w[0], 0.5 * w[1], 0.5 * w[2]]  # g' = 1/2 Gamma(0) omega (eq. 47)
            a00, a01, a02, a10, a11, a12, a20, a21, a22 = A
            g0 = g1 = g2 = 0.0
        core._floats = (x1, x2, t + dt)  # the new state, as GibbsSTSMO._step_single stores it
        b0, b1, b2 = x2
        # R_hat = R_a D(g_hat)^T (eq. 45, as gibbs_to_rot) and omega_hat (eq. 80)
        gg = g0 * g0 + g1 * g1 + g2 * g2
        d, m = 1.0 - gg, 1.0 + gg
        d00, d01, d02 = (d + 2.0 * (g0 * g0)) / m, (2.0 * (g0 * g1) - 2.0 * g2) / m, (2.0 * (g0 * g2) + 2.0 * g1) / m
        d10, d11, d12 = (2.0 * (g1 * g0) + 2.0 * g2) / m, (d + 2.0 * (g1 * g1)) / m, (2.0 * (g1 * g2) - 2.0 * g0) / m
        d20, d21, d22 = (2.0 * (g2 * g0) - 2.0 * g1) / m, (2.0 * (g2 * g1) + 2.0 * g0) / m, (d + 2.0 * (g2 * g2)) / m
        # one buffer, rows: R_hat (3), omega_hat, R_q (3), g_hat, zero force, zero torque
        out = np.fromiter([
            a00 * d00 + a01 * d10 + a02 * d20, a00 * d01 + a01 * d11 + a02 * d21, a00 * d02 + a01 * d12 + a02 * d22,
            a10 * d00 + a11 * d10 + a12 * d20, a10 * d01 + a11 * d11 + a12 * d21, a10 * d02 + a11 * d12 + a12 * d22,
            a20 * d00 + a21 * d10 + a22 * d20, a20 * d01 + a21 * d11 + a22 * d21, a20 * d02 + a21 * d12 + a22 * d22,
            2.0 * (b0 - (g1 * b2 - g2 * b1)) / m, 2.0 * (b1 - (g2 * b0 - g0 * b2)) / m,
            2.0 * (b2 - (g0 * b1 - g1 * b0)) / m, q00, q01, q02, q10, q11, q12, q20, q21, q22,
            g0, g1, g2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], float, 30).reshape(10, 3)
        return ObserverEstimate(force=out[8:9], torque=out[9:10], states={
            "attitude": out[None, 0:3], "angular_velocity": out[3:4], "attitude_quest": out[None, 4:7],
            "gibbs": out[7:8], "quest_valid": np.array([True])})

    def _maybe_reanchor(self) -> None:
        x1 = self.core.x1
        far = np.sqrt((x1 * x1).sum(axis=-1)) > self.reanchor
        if not far.any():
            return
        omega = self.core.omega[far]
        self.anchor = self.anchor.copy()
        self.anchor[far] = self.anchor[far] @ gibbs_to_rot(self.core.x1[far])
        self.core.x1[far] = 0.0
        self.core.x2[far] = 0.5 * omega  # g' = 1/2 Gamma(0) omega (eq. 47)

    def params(self) -> dict[str, Any]:
        c = self.core
        return dict(t_c=c.t_c, eta=c.eta, kappa1=c.kappa1, kappa2=c.kappa2, t_switch=c.t_s, mode=c.mode)


_QUEST_KEYS = (SPECIFIC_FORCE, MAGNETOMETER)


def _gibbs_to_rot_floats(g: list[float]) -> list[float]:
    """:func:`gibbs_to_rot` for one Gibbs vector (row-major 9): R = D(g)^T, eq. 45."""
    g0, g1, g2 = g
    gg = g0 * g0 + g1 * g1 + g2 * g2
    d, m = 1.0 - gg, 1.0 + gg
    return [(d + 2.0 * (g0 * g0)) / m, (2.0 * (g0 * g1) - 2.0 * g2) / m, (2.0 * (g0 * g2) + 2.0 * g1) / m,
            (2.0 * (g1 * g0) + 2.0 * g2) / m, (d + 2.0 * (g1 * g1)) / m, (2.0 * (g1 * g2) - 2.0 * g0) / m,
            (2.0 * (g2 * g0) - 2.0 * g1) / m, (2.0 * (g2 * g1) + 2.0 * g0) / m, (d + 2.0 * (g2 * g2)) / m]


def _omega_floats(g: list[float], gd: list[float]) -> list[float]:
    """omega = 2 (g' - g x g') / (1 + g.g) (eq. 80) for one vehicle."""
    a0, a1, a2 = g
    b0, b1, b2 = gd
    den = 1.0 + (a0 * a0 + a1 * a1 + a2 * a2)
    return [2.0 * (b0 - (a1 * b2 - a2 * b1)) / den, 2.0 * (b1 - (a2 * b0 - a0 * b2)) / den,
            2.0 * (b2 - (a0 * b1 - a1 * b0)) / den]


def _safe_gibbs(R: NDArray[np.float64]) -> NDArray[np.float64]:
    """Gibbs vector of D = R^T, clipped to norm 1e3 at a half turn (a measurement far from the anchor)."""
    den = 1.0 + (R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2])
    Rf = R.reshape(R.shape[:-2] + (9,))
    g = 2.0 * (0.5 * (Rf.take(_VEE_P, -1) - Rf.take(_VEE_M, -1))) / np.maximum(den, 1e-6)[..., None]
    if not ((g * g).sum(axis=-1) > 1e5).any():  # |g| <= 316 < 1e3: no clipping
        return g
    n = np.linalg.norm(g, axis=-1, keepdims=True)
    return np.where(n > 1e3, g * 1e3 / np.maximum(n, 1e-300), g)


_VEE_P = np.array([7, 2, 3])  # vee(R) = 1/2 (R21 - R12, R02 - R20, R10 - R01) (lie.vee)
_VEE_M = np.array([5, 6, 1])
