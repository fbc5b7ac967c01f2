"""The linear UAV model in momentum form of Cayero et al. (2019) Sec. 3-4.

State ``x = (p, d_v)`` with the world-frame lumped momentum ``p = (m v, R J Omega)`` (eq. 35) and the
disturbance with its derivatives ``d_v = (d, d', ..., d^(r-1))`` (eq. 42)::

    p'   = m g' + R' w_a + H d_v          (eqs. 36, 47)     u = m g' + R' w_a   (eq. 52)
    d_v' = F d_v + G eta1                 (eq. 43, d^(r) = eta1, eq. 41)
    y    = (m v, R J Omega, f_ext) + eta2 = C x + W2 eta2     (eqs. 54-57)

The model is exact (not linearized): in the world frame the momentum equations of a rigid body are
linear once the attitude and the actuator wrench are known inputs.  ``d`` = (force, torque), both
in the WORLD frame (NED); the torque in body FRD is ``R^T d_tau``.

Dimensions (corrected typos of the paper): ``d_v`` has 6 r entries, so ``F`` is 6r x 6r (eq. 44
prints 6(r-1)), ``A`` is 6(r+1) x 6(r+1) (eq. 49 prints a 6(r+1) x 6 zero block below the first
six rows, which would give 6(r+2)), and ``C = (I_9, 0_{9 x (6r-3)})`` (eq. 56 prints 6r+3).
Eq. 54 has two sign/frame typos: the first block is ``m ^w v`` (world velocity, eq. 35) and the
external force is ``R (m a - f_a)`` (from eq. 53), not ``R (m a + f_a)``.

The design data do NOT depend on m and J (A, B, C, W1, W2, E1 are pure selection/shift matrices);
only the noise ellipsoid Q2 (eq. 58, identified for the AscTec Hummingbird of Sec. 4 with its
sensors) does.  :func:`scaled_q2` rescales Q2 to another vehicle's mass and inertia.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import shown
from fawtgym.core.kernel_types import NO_REFCOUNT

from .qb_design import QBProblem

#: Sec. 4 vehicle (AscTec Hummingbird): m [kg] and body inertia [kg m^2]
HUMMINGBIRD_MASS = 1.023
HUMMINGBIRD_INERTIA = np.diag([9.5e-3, 9.5e-3, 18.6e-3])
#: eq. 58 upper triangle, rows of the symmetric 9x9 measurement-noise ellipsoid Q2 on
#: eta2 = (noise of m v [kg m/s], of R J Omega [kg m^2/s], of f_ext [N])
_Q2_UPPER = (
    (1.5, -0.3, 0.3, 8.3, -3.2, -3.1, -0.2, -0.02, -0.1),
    (0.7, -0.1, -10.5, 9.3, -6.2, 0.04, -0.03, -0.01),
    (0.9, 3.30, 3.7, -3.9, 0.02, -0.02, -0.09),
    (2903, 111.7, -277.8, -2.4, -0.6, -0.2),
    (4281, 242.1, 0.6, 2.5, -1.5),
    (951.2, -1.6, 1.6, 1.05),
    (0.2, -0.01, -0.01),
    (0.1, -0.01),
    (0.1,),
)
Q1_SCALE = 1.0e6  #: Q1 = 1e6 I_6 (Sec. 4)
PAPER_ORDER = 3  #: r = 3 (Sec. 4)


def paper_q2() -> NDArray[np.float64]:
    """Q2 of Cayero et al. (2019) eq. 58 as a full symmetric matrix (the paper prints the upper triangle)."""
    q = np.zeros((9, 9))
    for i, row in enumerate(_Q2_UPPER):
        q[i, i:] = row
    return q + np.triu(q, 1).T


def scaled_q2(mass: float, inertia: ArrayLike) -> NDArray[np.float64]:
    """Q2 for another vehicle, assuming the same velocity, rate and accelerometer errors as Sec. 4.

    The noise on (m v, R J Omega, f_ext) scales as D = diag(m/m_h I3, J_ii/J_h,ii, m/m_h I3), so the
    ellipsoid becomes D^{-1} Q2 D^{-1}.  Returns eq. 58 unchanged for the Hummingbird.
    """
    j = np.asarray(inertia, dtype=float)
    j = np.diag(j) if j.shape == (3,) else j
    if not (np.isfinite(mass) and mass > 0):
        raise ValueError(f"mass must be a finite positive number, got {shown(mass)}")
    if j.shape != (3, 3) or np.any(np.diag(j) <= 0):
        raise ValueError(f"inertia must be 3 positive diagonal entries or a 3x3 matrix, got {shown(inertia)}")
    d = np.concatenate([np.full(3, mass / HUMMINGBIRD_MASS), np.diag(j) / np.diag(HUMMINGBIRD_INERTIA),
                        np.full(3, mass / HUMMINGBIRD_MASS)])
    dinv = np.diag(1.0 / d)
    return dinv @ paper_q2() @ dinv


def disturbance_model(r: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(F, G, H) of eqs. 43-46 for the r-th order disturbance model d^(r) = eta1 (eq. 41)."""
    if not (isinstance(r, (int, np.integer)) and r >= 1):
        raise ValueError(f"disturbance order r must be an integer >= 1, got {shown(r)}")
    nd = 6 * r
    F = np.zeros((nd, nd))
    F[: nd - 6, 6:] = np.eye(nd - 6)  # eq. 44
    G = np.zeros((nd, 6))
    G[nd - 6:, :] = np.eye(6)  # eq. 45
    H = np.zeros((6, nd))
    H[:, :6] = np.eye(6)  # eq. 46
    return F, G, H


def uav_model(r: int = PAPER_ORDER, q1_scale: float = Q1_SCALE, q2: ArrayLike | None = None) -> QBProblem:
    """The QB design problem of Sec. 4: eqs. 48-51 (A, B, W1), 55-57 (C, W2), 59 (Q), 60 (E1), D = 0.

    ``q2`` defaults to eq. 58 (Hummingbird); ``q1_scale`` is the 1e6 of Q1 = 1e6 I_6.
    """
    if not (np.isfinite(q1_scale) and q1_scale > 0):
        raise ValueError(f"q1_scale must be a finite positive number, got {shown(q1_scale)}")
    q2m = paper_q2() if q2 is None else np.asarray(q2, dtype=float)
    if q2m.shape != (9, 9):
        raise ValueError(f"q2 must be 9x9, got shape {q2m.shape}")
    F, G, H = disturbance_model(r)
    n = 6 + 6 * r
    A = np.zeros((n, n))
    A[:6, 6:] = H  # eq. 49
    A[6:, 6:] = F
    B = np.zeros((n, 6))
    B[:6] = np.eye(6)  # eq. 50
    W1 = np.zeros((n, 6))
    W1[6:] = G  # eq. 51
    C = np.zeros((9, n))
    C[:, :9] = np.eye(9)  # eq. 56 (m v, spin momentum, external force)
    D = np.zeros((9, 6))
    W2 = np.eye(9)  # eq. 57
    Q = 0.5 * np.block([[q1_scale * np.eye(6), np.zeros((6, 9))], [np.zeros((9, 6)), q2m]])  # eq. 59
    E1 = np.hstack([np.zeros((6, 6)), H])  # eq. 60
    return QBProblem(A=A, B=B, C=C, D=D, W1=W1, W2=W2, Q=Q, E1=E1)


# ------------------------------------------------- mapping to the env's signals (batch-first) ----
@njit(cache=True, **NO_REFCOUNT)
def momentum_input_row(mass, gravity, R, thrust, torque, u):
    """u = m g' + R' w_a (eq. 52) of one row into ``u`` (6,): world force m g e3 - f R e3, world torque R tau_a."""
    for k in range(3):
        u[k] = -thrust * R[k, 2]
        u[3 + k] = R[k, 0] * torque[0] + R[k, 1] * torque[1] + R[k, 2] * torque[2]
    u[2] += mass * gravity


@njit(cache=True, **NO_REFCOUNT)
def momentum_output_row(mass, J, R, velocity, omega, specific_force, thrust, y):
    """y of eq. 54 (typos corrected) of one row into ``y`` (9,): (m v, R J Omega, f_ext = R (m a_sf + f e3)).

    The accelerometer measures ``a_sf = (f_a + R^T f_ext) / m`` (eq. 53) with ``f_a = -f e3``."""
    s0 = J[0, 0] * omega[0] + J[0, 1] * omega[1] + J[0, 2] * omega[2]
    s1 = J[1, 0] * omega[0] + J[1, 1] * omega[1] + J[1, 2] * omega[2]
    s2 = J[2, 0] * omega[0] + J[2, 1] * omega[1] + J[2, 2] * omega[2]
    b0, b1, b2 = mass * specific_force[0], mass * specific_force[1], mass * specific_force[2] + thrust
    for k in range(3):
        y[k] = mass * velocity[k]
        y[3 + k] = R[k, 0] * s0 + R[k, 1] * s1 + R[k, 2] * s2
        y[6 + k] = R[k, 0] * b0 + R[k, 1] * b1 + R[k, 2] * b2


@njit(cache=True)
def _momentum_input_rows(mass, gravity, R, thrust, torque, u):
    for i in range(R.shape[0]):
        momentum_input_row(mass, gravity, R[i], thrust[i], torque[i], u[i])


@njit(cache=True)
def _momentum_output_rows(mass, J, R, velocity, omega, specific_force, thrust, y):
    for i in range(R.shape[0]):
        momentum_output_row(mass, J, R[i], velocity[i], omega[i], specific_force[i], thrust[i], y[i])


def _c(a: ArrayLike) -> NDArray[np.float64]:
    return np.ascontiguousarray(a, dtype=float)


def momentum_input(mass: float, gravity: float, R: NDArray[np.float64], thrust: NDArray[np.float64],
                   torque: NDArray[np.float64]) -> NDArray[np.float64]:
    """u of eq. 52 (:func:`momentum_input_row` over the rows), (N, 6).

    ``R`` (N,3,3) body FRD -> world NED, ``thrust`` (N,) collective [N] along -e3 body, ``torque`` (N,3)
    body FRD rotor torque.
    """
    u = np.empty((R.shape[0], 6))
    _momentum_input_rows(float(mass), float(gravity), _c(R), _c(thrust), _c(torque), u)
    return u


def momentum_output(mass: float, inertia: NDArray[np.float64], R: NDArray[np.float64],
                    velocity: NDArray[np.float64], omega: NDArray[np.float64],
                    specific_force: NDArray[np.float64], thrust: NDArray[np.float64]) -> NDArray[np.float64]:
    """y of eq. 54 (:func:`momentum_output_row` over the rows), (N, 9)."""
    y = np.empty((R.shape[0], 9))
    _momentum_output_rows(float(mass), _c(inertia), _c(R), _c(velocity), _c(omega), _c(specific_force), _c(thrust),
                          y)
    return y
