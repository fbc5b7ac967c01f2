"""Geometric tracking controller on SE(3) (Lee, Leok, McClamroch, CDC 2010), batch-first.

Model: Wang et al. (2024) eq. (38), world NED, body FRD, thrust along
-b3 -- the same sign convention as Lee et al. 2010 (``m v' = m g e3 - f R e3``).  Control law
(Lee et al. 2010, eqs. 11-16)::

    A    = -kx e_x - kv e_v - m g e3 + m a_d (+ phi_hat)     e_x = b - b_d, e_v = v - v_d
    b3d  = -A / |A|,  b2d = b3d x b1d / |b3d x b1d|,  R_d = [b2d x b3d, b2d, b3d]
    f    = -A . R e3
    e_R  = vee(R_d^T R - R^T R_d) / 2,   e_W = W - R^T R_d W_d
    tau  = -kR e_R - kW e_W + W x J W - J (W^ R^T R_d W_d - R^T R_d W_d') (- tau_hat)

``phi_hat``/``tau_hat`` are optional disturbance feedforward terms (Wang et al. (2024) Sec. 7.2: F = F0 - phi_hat,
tau = tau0 - tau_hat; the sign here follows from the model where phi_D enters with a + sign).  The
desired angular velocity W_d and acceleration W_d' are inputs; :class:`DesiredRateFilter` estimates
them from the sequence of R_d by filtered differences.

Default gains are Lee et al. 2010's for the same vehicle (m = 4.34 kg, J = diag(0.082, 0.0845, 0.1377)):
kx = 16 m, kv = 5.6 m, kR = 8.81, kW = 2.54.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.so3 import cross, hat, log_so3, vee

_E3 = np.array([0.0, 0.0, 1.0])


def _b(x: ArrayLike, shape: tuple[int, ...], label: str) -> NDArray[np.float64]:
    a = np.asarray(x, dtype=float)
    if a.shape == shape[1:]:
        a = np.broadcast_to(a, shape)
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise ValueError(f"{label} must be finite with shape {shape[1:]} or {shape}, got {a.shape}")
    return a


def desired_attitude(a_cmd: NDArray[np.float64], b1d: NDArray[np.float64]) -> NDArray[np.float64]:
    """R_d from A (force command, (N, 3)) and heading b1d (N, 3) (Lee et al. 2010, eq. 12 and Sec. III)."""
    norm = np.linalg.norm(a_cmd, axis=-1, keepdims=True)
    if np.any(norm < 1e-9):
        raise ValueError("commanded force A = -kx e_x - kv e_v - m g e3 + m a_d is zero: the desired thrust "
                         "direction is undefined (reference acceleration cancels gravity)")
    b3 = -a_cmd / norm
    b2 = cross(b3, b1d)
    n2 = np.linalg.norm(b2, axis=-1, keepdims=True)
    if np.any(n2 < 1e-9):
        raise ValueError("heading b1d is parallel to the desired thrust axis b3d; choose another b1d")
    b2 = b2 / n2
    b1 = cross(b2, b3)
    return np.stack([b1, b2, b3], axis=-1)


@dataclasses.dataclass
class LeeSE3Controller:
    """Batch geometric SE(3) tracking controller; ``control`` returns (thrust (N,), torque (N, 3), R_d)."""

    mass: float
    inertia: NDArray[np.float64]
    gravity: float = GRAVITY
    kx: float | None = None
    kv: float | None = None
    kr: float = 8.81
    kw: float = 2.54

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError(f"mass must be finite and positive, got {shown(self.mass)}")
        j = np.asarray(self.inertia, dtype=float)
        self.inertia = np.diag(j) if j.shape == (3,) else j
        if self.inertia.shape != (3, 3) or np.linalg.eigvalsh(self.inertia).min() <= 0:
            raise ValueError(f"inertia must be positive definite 3x3 or 3 diagonal entries, got {self.inertia}")
        self.kx = 16.0 * self.mass if self.kx is None else self.kx
        self.kv = 5.6 * self.mass if self.kv is None else self.kv
        for k in ("kx", "kv", "kr", "kw"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"gain {k} must be finite and positive, got {shown(v)}")

    def control(self, position: ArrayLike, velocity: ArrayLike, attitude: ArrayLike, angular_velocity: ArrayLike,
                b_d: ArrayLike, v_d: ArrayLike, a_d: ArrayLike, b1d: ArrayLike = (1.0, 0.0, 0.0),
                w_d: ArrayLike = (0.0, 0.0, 0.0), w_d_dot: ArrayLike = (0.0, 0.0, 0.0),
                force_ff: ArrayLike | None = None, torque_ff: ArrayLike | None = None
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Thrust f (N,), body torque (N, 3) and R_d (N, 3, 3) for N vehicles."""
        b = np.asarray(position, dtype=float)
        b = b[None] if b.ndim == 1 else b
        n = b.shape[0]
        v = _b(velocity, (n, 3), "velocity")
        r = _b(attitude, (n, 3, 3), "attitude")
        w = _b(angular_velocity, (n, 3), "angular_velocity")
        ex = b - _b(b_d, (n, 3), "b_d")
        ev = v - _b(v_d, (n, 3), "v_d")
        kx, kv = self.kx, self.kv
        assert kx is not None and kv is not None  # set by __post_init__
        a_cmd = -kx * ex - kv * ev - self.mass * self.gravity * _E3 + self.mass * _b(a_d, (n, 3), "a_d")
        if force_ff is not None:
            a_cmd = a_cmd - _b(force_ff, (n, 3), "force_ff")
        rd = desired_attitude(a_cmd, _b(b1d, (n, 3), "b1d"))
        f = -np.einsum("ni,ni->n", a_cmd, r[:, :, 2])
        rt_rd = np.swapaxes(r, -1, -2) @ rd
        e_r = 0.5 * vee(np.swapaxes(rd, -1, -2) @ r - rt_rd)
        wd_b = np.einsum("nij,nj->ni", rt_rd, _b(w_d, (n, 3), "w_d"))
        wdd_b = np.einsum("nij,nj->ni", rt_rd, _b(w_d_dot, (n, 3), "w_d_dot"))
        e_w = w - wd_b
        j = self.inertia
        tau = (-self.kr * e_r - self.kw * e_w + cross(w, w @ j.T)
               - (np.einsum("nij,nj->ni", hat(w), wd_b) - wdd_b) @ j.T)
        if torque_ff is not None:
            tau = tau - _b(torque_ff, (n, 3), "torque_ff")
        return f, tau, rd


class DesiredRateFilter:
    """W_d and W_d' of R_d(t) by dirty derivatives (first-order low-pass of the finite difference), batch-first.

    W_raw = log(R_d,prev^T R_d) / dt (body rate of R_d), W_d += dt/T_f (W_raw - W_d); W_d' likewise from
    W_d.  Lee et al. 2010 differentiate R_d analytically, which needs the jerk and snap of the vehicle;
    with noisy measurements the filtered derivative is the practical substitute.  ``time_constant`` T_f [s].
    """

    def __init__(self, time_constant: float = 0.02) -> None:
        if not (np.isfinite(time_constant) and time_constant > 0):
            raise ValueError(f"time_constant must be a positive number of seconds, got {shown(time_constant)}")
        self.time_constant = float(time_constant)
        self._rd: NDArray[np.float64] | None = None
        self._w = self._wdot = np.zeros((1, 3))

    def reset(self) -> None:
        self._rd = None

    def __call__(self, rd: NDArray[np.float64], dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Feed R_d (N, 3, 3) of this step; returns (W_d, W_d') (N, 3) for the *next* control call."""
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be positive, got {shown(dt)}")
        if self._rd is None or self._rd.shape != rd.shape:
            self._rd = rd.copy()
            self._w = np.zeros(rd.shape[:-2] + (3,))
            self._wdot = np.zeros_like(self._w)
            return self._w.copy(), self._wdot.copy()
        a = min(dt / self.time_constant, 1.0)
        w_raw = log_so3(np.swapaxes(self._rd, -1, -2) @ rd) / dt
        w_new = self._w + a * (w_raw - self._w)
        self._wdot = self._wdot + a * ((w_new - self._w) / dt - self._wdot)
        self._w = w_new
        self._rd = rd.copy()
        return self._w.copy(), self._wdot.copy()
