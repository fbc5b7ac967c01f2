"""Wang et al. (2024), Sec. 6 simulation setup: vehicle, trajectories (Table 1), disturbances, noise (Table 2), plant.

Source: Sec. 6.  Everything is batch-first over N simulated vehicles.

* vehicle m = 4.34 kg, J = diag(0.0820, 0.0845, 0.1377) kg m^2 (Pounds et al.), no actuator dynamics or
  saturation;
* dynamics eq. (38) in world NED / body FRD, integrated with Heun's method (Simulink ODE2), h = 1 ms, the
  rotation advanced on SO(3) by the exponential map (R exp(h/2 (Omega_1 + Omega_2)));
* Table 1 trajectories HV, SS, FS, HP; disturbances phi_D(t), tau_D(t) with steps at 10 s and 20 s;
* Table 2 noise: white noise of power spectral density P sampled at h has per-sample standard deviation
  sqrt(P / h) (the Simulink band-limited white-noise convention); attitude noise enters as R exp(Delta^).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.so3 import cross, exp_so3

MASS = 4.34
INERTIA = np.diag([0.0820, 0.0845, 0.1377])
STEP = 1e-3
DURATION = 30.0
_E3 = np.array([0.0, 0.0, 1.0])

#: Table 1: b_d = [ax sin(wx t), ay cos(wy t), -3] (HP uses both).  name -> (ax, wx, ay, wy)
TRAJECTORIES: dict[str, tuple[float, float, float, float]] = {
    "HV": (0.0, 0.0, 0.0, 0.0),
    "SS": (10.0, 0.1 * np.pi, 0.0, 0.0),
    "FS": (5.0, 0.5 * np.pi, 0.0, 0.0),
    "HP": (10.0, 0.5 * np.pi, 10.0, 0.5 * np.pi),
}
ALTITUDE = -3.0

#: Table 2 power spectral densities for b, v, R, Omega
NOISE_PSD: dict[str, float] = {"position": 3e-8, "velocity": 3e-7, "attitude": 3e-8, "angular_velocity": 3e-7}

#: initial state of Sec. 6
B0 = np.array([0.01, 0.0, 0.0])
V0 = np.array([5.0 * np.pi, 0.0, 0.0])


def noise_sigma(psd: float, step: float = STEP) -> float:
    """Per-sample standard deviation sqrt(P / h) of white noise with PSD P sampled every h seconds."""
    if not (psd >= 0 and step > 0):
        raise ValueError(f"need psd >= 0 and step > 0, got psd={shown(psd)}, step={shown(step)}")
    return float(np.sqrt(psd / step))


@dataclasses.dataclass(frozen=True)
class Reference:
    """Table 1 references for a batch of trajectory names (analytic b_d, v_d, a_d)."""

    names: tuple[str, ...]

    def __post_init__(self) -> None:
        bad = [n for n in self.names if n not in TRAJECTORIES]
        if bad:
            raise ValueError(f"unknown trajectories {bad}; valid: {list(TRAJECTORIES)}")

    @property
    def _par(self) -> NDArray[np.float64]:
        return np.array([TRAJECTORIES[n] for n in self.names])

    def __call__(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        ax, wx, ay, wy = self._par.T
        n = len(self.names)
        b = np.zeros((n, 3))
        v = np.zeros((n, 3))
        a = np.zeros((n, 3))
        b[:, 0], v[:, 0], a[:, 0] = ax * np.sin(wx * t), ax * wx * np.cos(wx * t), -ax * wx**2 * np.sin(wx * t)
        b[:, 1], v[:, 1], a[:, 1] = ay * np.cos(wy * t), -ay * wy * np.sin(wy * t), -ay * wy**2 * np.cos(wy * t)
        b[:, 2] = ALTITUDE
        return b, v, a

    def acceleration(self, t: float) -> NDArray[np.float64]:
        return self(t)[2]


def disturbance_force(t: float) -> NDArray[np.float64]:
    """phi_D(t) of Sec. 6, world NED [N], shape (3,)."""
    base = np.array([3.0, 4.0, -5.0]) if t < 10.0 else np.array([5.0, -3.0, 4.0])
    return base + np.sin(np.pi * t / 6.0) * np.array([1.5, -1.0, -1.0])


def disturbance_torque(t: float) -> NDArray[np.float64]:
    """tau_D(t) of Sec. 6, body FRD [N m], shape (3,)."""
    base = np.array([-0.3, 0.2, 0.2]) if t < 20.0 else np.array([0.2, -0.3, -0.2])
    return base + 0.01 * np.sin(np.pi * t / 2.0) * np.array([1.0, 2.0, -5.0])


@dataclasses.dataclass
class PlantState:
    b: NDArray[np.float64]
    v: NDArray[np.float64]
    R: NDArray[np.float64]
    w: NDArray[np.float64]


def initial_state(n: int) -> PlantState:
    """b(0) = [0.01, 0, 0], v(0) = [5 pi, 0, 0], R(0) = I, Omega(0) = 0 for n vehicles."""
    return PlantState(np.tile(B0, (n, 1)), np.tile(V0, (n, 1)), np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)))


def _accels(s: PlantState, f: NDArray[np.float64], tau: NDArray[np.float64], t: float
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    a = GRAVITY * _E3 - (f / MASS)[:, None] * s.R[:, :, 2] + disturbance_force(t) / MASS
    jw = s.w @ INERTIA.T
    wdot = (cross(jw, s.w) + tau + disturbance_torque(t)) @ np.linalg.inv(INERTIA).T
    return a, wdot


def heun_step(s: PlantState, f: ArrayLike, tau: ArrayLike, t: float, h: float = STEP) -> PlantState:
    """One Heun (ODE2) step of eq. (38) with thrust/torque held over [t, t + h]."""
    f = np.asarray(f, dtype=float)
    tau = np.asarray(tau, dtype=float)
    a1, wd1 = _accels(s, f, tau, t)
    pred = PlantState(s.b + h * s.v, s.v + h * a1, s.R @ exp_so3(h * s.w), s.w + h * wd1)
    a2, wd2 = _accels(pred, f, tau, t + h)
    return PlantState(s.b + 0.5 * h * (s.v + pred.v), s.v + 0.5 * h * (a1 + a2),
                      s.R @ exp_so3(0.5 * h * (s.w + pred.w)), s.w + 0.5 * h * (wd1 + wd2))


def measure(s: PlantState, noisy: NDArray[np.bool_], rng: np.random.Generator, h: float = STEP
            ) -> dict[str, NDArray[np.float64]]:
    """Measurement eq. (39) with Table 2 noise on the rows where ``noisy`` is True."""
    n = s.b.shape[0]
    mask = np.asarray(noisy, dtype=float)[:, None]
    sb, sv, sr, sw = (noise_sigma(NOISE_PSD[k], h) for k in ("position", "velocity", "attitude", "angular_velocity"))
    z = rng.standard_normal((4, n, 3)) * mask
    return {"position": s.b + sb * z[0], "velocity": s.v + sv * z[1], "attitude": s.R @ exp_so3(sr * z[2]),
            "angular_velocity": s.w + sw * z[3]}
