"""``pdt_sta``: gyroless attitude and angular-velocity estimator, QUEST + the predefined-time STSMO.

Source: Silva and Santos (2023), Secs. 4-5: QUEST attitude from the accelerometer and the magnetometer
(eqs. 56-66, :mod:`.quest`), its Gibbs vector g_Q (eq. 79) driving the modified super-twisting observer
(eqs. 75-77, or the conventional one of eqs. 81-82, :mod:`.stsmo`) of (g, g'), the attitude R = D(g)^T
(eq. 45, :mod:`.gibbs`) and the rate by certainty equivalence omega_hat = 2 Gamma(g_hat)^-1 g_hat' (eq. 80).

Frames.  The paper's S^g (z along the local vertical) and S^b (z normal to the rotor plane) are world NED and
body FRD (its local field m_g = [13.7, -4.6, -10.9] uT has the NED shape of the field at its authors' site).
The paper's accelerometer reference is a_g = g e3 (eq. 50), the gravity direction; the project's
``specific_force`` is R^T (a - g e3), so this estimator uses -g e3 as the accelerometer's reference vector (the
same direction pairing, the sensor's sign).

One update of every row is one kernel (:func:`_pdt_sta_rows`, numba) called alike for N = 1 and N = 1024.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from fawtgym.core.checks import check_number, check_positive, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.kernel_types import NO_REFCOUNT
from fawtgym.core.measurement import EARTH_FIELD_NED, MAGNETOMETER, SPECIFIC_FORCE, batch_measurement
from fawtgym.core.rows import write_rows
from fawtgym.core.so3_kernels import cross_row, mat_copy_row, mat_mul_row, quat_to_rot_row

from ._obs_common import real_vector
from .base import BufferStates, Observer, ObserverEstimate, register_observer
from .gibbs import gibbs_to_rot_row, omega_row, rot_to_gibbs_row
from .predefined_sta import check_params, early_switch_time
from .quest import quest_row
from .stsmo import GibbsSTSMO, stsmo_row

#: a measured Gibbs vector relative to the anchor is clipped to this norm (a half turn has none)
_Y_MAX = 1e3
#: the scratch floats of :func:`_pdt_sta_rows`: QUEST's body vectors (2, 3), quaternion and Gibbs scratch, the
#: relative and Gibbs rotations (3, 3) each, y and omega
N_WORK = 37


@njit(cache=True, **NO_REFCOUNT)
def measured_attitude_row(sf, mag, ref, weights, gravity, min_field, body, q, g, R):
    """QUEST attitude (eqs. 56-66) of one row from the accelerometer ``sf`` and the magnetometer ``mag`` against
    the unit references ``ref`` (2, 3) into ``R`` (3, 3) (scratch ``body`` (2, 3), ``q`` (4,), ``g`` (3,)).

    Returns False, leaving ``R`` untouched, where the vectors give no usable attitude: the accelerometer reads
    < 0.2 g (free fall, a hard manoeuvre), the magnetometer < ``min_field``, or the two are within 1 deg of
    parallel; these are QUEST's preconditions, so :func:`quest_row` runs without further checks."""
    na = math.sqrt(sf[0] * sf[0] + sf[1] * sf[1] + sf[2] * sf[2])
    nm = math.sqrt(mag[0] * mag[0] + mag[1] * mag[1] + mag[2] * mag[2])
    cross_row(sf, mag, g)                  # sf x mag (g is scratch: quest_row overwrites it below)
    sin = math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) / max(na * nm, 1e-300)
    if not (na > 0.2 * gravity and nm > min_field and sin > 0.0175):
        return False
    for k in range(3):
        body[0, k] = sf[k] / na
        body[1, k] = mag[k] / nm
    quest_row(body, ref, weights, q, g)
    quat_to_rot_row(q, R)
    return True


@njit(cache=True, **NO_REFCOUNT)
def _mat_t_mul_row(A, B, out):
    """out = A^T B (3 x 3; core.so3_kernels has A B only)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[0, i] * B[0, j] + A[1, i] * B[1, j] + A[2, i] * B[2, j]


@njit(cache=True)
def _measured_attitude_rows(sf, mag, ref, weights, gravity, min_field, R, valid):
    body, q, g = np.empty((2, 3)), np.empty(4), np.empty(3)
    for i in range(sf.shape[0]):
        valid[i] = measured_attitude_row(sf[i], mag[i], ref, weights, gravity, min_field, body, q, g, R[i])


@njit(cache=True, **NO_REFCOUNT)
def _pdt_sta_rows(sf, mag, tau, dt, k, anchor, x1, x2, t, state, est, valid, work):
    """One update of every row into ``state`` (N, 16): anchor R_a (9) | g_hat | g_hat' | t, and ``est`` (N, 30):
    force (0) | torque (0) | R_hat (9) | omega_hat | R_q (9) | g_hat, and ``valid`` (N,) (the inputs are not
    written).

    Per row: the QUEST attitude R_q (:func:`measured_attitude_row`); the Gibbs measurement relative to the anchor
    attitude R_a, y = g of (R_a^T R_q)^T (eq. 79), or, where the vectors give no attitude, the prediction itself
    (y = g_hat: e1 = 0, no correction this step, and R_q reported as the prediction R_a D(g_hat)^T); one STSMO
    step (eqs. 75-77 / 81-82) with omega_hat of eq. 80; the re-anchoring R_a := R_a D(g_hat)^T, g_hat := 0,
    g_hat' := 1/2 Gamma(0) omega_hat (eq. 47) where ||g_hat|| > ``reanchor``; the outputs R_hat = R_a D(g_hat)^T
    (eq. 45) and omega_hat (eq. 80).  ``k``: the constants in one array (see ``PdtStaAttitudeObserver._k``):
    gravity, min_field, reanchor, the unit references (2, 3), the QUEST weights (2), J, J^-1 and the STSMO's ``p``.
    ``work`` (:data:`N_WORK`,) is scratch: the kernel allocates nothing (it and its row laws are
    :data:`~fawtgym.core.kernel_types.NO_REFCOUNT`)."""
    gravity, min_field, reanchor = k[0], k[1], k[2]
    ref, weights = k[3:9].reshape(2, 3), k[9:11]
    J, J_inv, p = k[11:20].reshape(3, 3), k[20:29].reshape(3, 3), k[29:]
    body, q, g = work[0:6].reshape(2, 3), work[6:10], work[10:13]
    rel, D = work[13:22].reshape(3, 3), work[22:31].reshape(3, 3)
    y, w = work[31:34], work[34:37]
    for i in range(x1.shape[0]):
        A = anchor[i]
        s, e = state[i], est[i]
        A_new, g_new, gd_new = s[0:9].reshape(3, 3), s[9:12], s[12:15]
        R_hat, omega_hat, R_q = e[6:15].reshape(3, 3), e[15:18], e[18:27].reshape(3, 3)
        valid[i] = measured_attitude_row(sf[i], mag[i], ref, weights, gravity, min_field, body, q, g, R_q)
        if valid[i]:
            _mat_t_mul_row(A, R_q, rel)
            y[0], y[1], y[2] = rot_to_gibbs_row(rel, 1e-6, _Y_MAX)  # eq. 79
        else:
            gibbs_to_rot_row(x1[i, 0], x1[i, 1], x1[i, 2], D)
            mat_mul_row(A, D, R_q)
            y[0], y[1], y[2] = x1[i, 0], x1[i, 1], x1[i, 2]
        w[0], w[1], w[2] = omega_row(x1[i, 0], x1[i, 1], x1[i, 2], x2[i, 0], x2[i, 1], x2[i, 2])  # eq. 80
        stsmo_row(x1[i], x2[i], t[i], y, tau[i], w, J, J_inv, p, dt, g_new, gd_new)  # a non-finite state
        s[15] = t[i] + dt
        g0, g1, g2 = g_new[0], g_new[1], g_new[2]
        if math.sqrt(g0 * g0 + g1 * g1 + g2 * g2) > reanchor:  # (a non-finite one is caught by Observer.update)
            w0, w1, w2 = omega_row(g0, g1, g2, gd_new[0], gd_new[1], gd_new[2])
            gibbs_to_rot_row(g0, g1, g2, D)
            mat_mul_row(A, D, A_new)
            g_new[0] = g_new[1] = g_new[2] = 0.0
            gd_new[0], gd_new[1], gd_new[2] = 0.5 * w0, 0.5 * w1, 0.5 * w2  # g' = 1/2 Gamma(0) omega (eq. 47)
        else:
            mat_copy_row(A, A_new)
        gibbs_to_rot_row(g_new[0], g_new[1], g_new[2], D)
        mat_mul_row(A_new, D, R_hat)  # eq. 45
        omega_hat[0], omega_hat[1], omega_hat[2] = omega_row(g_new[0], g_new[1], g_new[2], gd_new[0], gd_new[1],
                                                             gd_new[2])
        for j in range(6):
            e[j] = 0.0  # no disturbance estimate
        e[27], e[28], e[29] = g_new[0], g_new[1], g_new[2]


#: the estimate's states: columns of the estimate buffer (N, 30) and trailing shapes
_STATES = {"attitude": (6, 15, (3, 3)), "angular_velocity": (15, 18, (3,)), "attitude_quest": (18, 27, (3, 3)),
           "gibbs": (27, 30, (3,))}


@register_observer("pdt_sta")
class PdtStaAttitudeObserver(Observer):
    """Gyroless attitude/rate estimator: QUEST (accelerometer + magnetometer) + predefined-time STSMO.

    Reads ``specific_force`` and ``magnetometer`` only (no gyro, no attitude), uses the applied body
    torque u and J (eq. 76), and reports ``states["attitude"]`` R_hat (N, 3, 3), ``states["angular_velocity"]``
    omega_hat (N, 3) (eq. 80), ``states["attitude_quest"]`` (the static QUEST attitude), ``states["gibbs"]``
    (g_hat relative to the row's anchor); the attribute ``quest_valid`` (N,) bool is False where the last update's
    vectors gave no attitude (no correction that step; it is not an estimate, so not in ``states``).  It estimates
    no disturbance (``channels`` is empty; force and torque are zeros).

    Options: ``t_c`` [1.5 s], ``eta`` [5], ``kappa1`` [2.5], ``kappa2`` [6 lambda_min(J)]: the STSMO gains
    (eqs. 75-77; kappa2 bounds the unknown angular acceleration times J); ``noise_bound`` [0]: > 0 switches early
    at t_e = t_c - eta * noise_bound (eq. 43); ``mode`` ["predefined"] or "conventional" (eqs. 81-82);
    ``weights`` [(1, 1)]: QUEST weights of the accelerometer and the magnetometer; ``magnetic_field``
    [``EARTH_FIELD_NED``]; ``reanchor`` [1].  Assumes small linear acceleration (the paper's v' = 0 of eq. 50):
    the accelerometer stands in for the gravity direction.

    The Gibbs vector is singular at a half turn, so the observer works relative to an anchor attitude R_a (the
    QUEST attitude at reset): it estimates g of (R_a^T R)^T and re-anchors a row to its current estimate (keeping
    omega_hat) whenever ||g_hat|| exceeds ``reanchor`` (default 1, 90 deg).
    """

    channels = frozenset()
    required_keys = (SPECIFIC_FORCE, MAGNETOMETER)
    #: the STA phase (eq. 77 after t_c) is forward Euler, whose discrete chattering band grows with dt (like
    #: kappa1 dt^(1/2) in g_hat): on a 0.22 rad/s rotation with exact vectors (tests/test_pdt_sta_observer.py's
    #: slow rotation, default gains) the rate error after t_c is 0.03 rad/s at 5 ms, 0.13 at 20 ms (0.6 of the
    #: signal) and 0.31 at 50 ms (worse than omega_hat = 0); 20 ms (50 Hz) is the bound
    max_dt = 0.02

    def __init__(self, mass: float, inertia: ArrayLike, gravity: float = GRAVITY, t_c: float = 1.5,
                 eta: float = 5.0, kappa1: float = 2.5, kappa2: float | None = None, noise_bound: float = 0.0,
                 mode: str = "predefined", weights: tuple[float, float] = (1.0, 1.0),
                 magnetic_field: ArrayLike = EARTH_FIELD_NED, reanchor: float = 1.0) -> None:
        super().__init__(mass, inertia, gravity)
        kappa1 = check_positive(kappa1, "pdt_sta: gain kappa1", note="(kappa1 > 0, eqs. 16-22)")
        noise_bound = check_number(noise_bound, "pdt_sta: noise_bound", minimum=0.0, inclusive_minimum=True,
                                   note="(ell of eq. 42)")
        t_switch = None
        if noise_bound > 0:
            check_params(t_c, eta)      # (its own messages, naming t_c / eta) before t_c / eta is formed
            # the early switch t_e = t_c - eta ell (eq. 43) must come after t0 = 0: ell < t_c / eta
            check_number(noise_bound, "pdt_sta: noise_bound", minimum=0.0, inclusive_minimum=True,
                         maximum=float(t_c) / float(eta), inclusive_maximum=False,
                         note="(ell of eq. 42; below t_c / eta, so that the early switch t_e = t_c - eta ell of eq. 43 "
                              "is after t = 0)")
            t_switch = early_switch_time(t_c, eta, noise_bound)
        if kappa2 is None:
            kappa2 = 6.0 * float(np.linalg.eigvalsh(self.inertia).min())
        self.core = GibbsSTSMO(self.inertia, t_c, eta, kappa1, kappa2, mode, t_switch)
        w = real_vector(weights, 2)
        if w is None or np.any(w <= 0):
            raise ValueError(f"pdt_sta: weights must be two finite real numbers > 0 (accelerometer, magnetometer), "
                             f"got {shown(weights)}")
        self.weights = w
        m = real_vector(magnetic_field, 3)
        if m is None or np.linalg.norm(np.cross(m, [0, 0, 1.0])) < 1e-6:
            raise ValueError("pdt_sta: magnetic_field must be 3 finite real numbers (NED) not parallel to gravity, "
                             f"got {shown(magnetic_field)}")
        self.reanchor = check_positive(reanchor, "pdt_sta: reanchor", maximum=10.0, note="(a Gibbs-vector norm)")
        self.references = np.stack([np.array([0.0, 0.0, -self.gravity]), m])  # specific force at rest, field
        self._ref_unit = np.ascontiguousarray(self.references / np.linalg.norm(self.references, axis=1)[:, None])
        self._min_field = 0.1 * float(np.linalg.norm(m))
        self._k = np.concatenate([[self.gravity, self._min_field, self.reanchor], self._ref_unit.ravel(),
                                  self.weights, self.core.J.ravel(), self.core.J_inv.ravel(), self.core.params])
        self.anchor: NDArray[np.float64] = np.eye(3)[None]
        #: False where the last update's vectors gave no attitude (N,)
        self.quest_valid: NDArray[np.bool_] = np.ones(1, dtype=bool)
        #: the last estimate's buffer (N, 30) (:meth:`estimate`): the kernel's, or the reset's; None before reset
        self._last: NDArray[np.float64] | None = None

    def _vectors(self, meas: Mapping[str, NDArray[np.float64]]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The accelerometer and magnetometer rows (N, 3), C-contiguous (checked by :meth:`Observer.update` /
        :meth:`Observer.reset`: present, N rows, finite)."""
        return np.ascontiguousarray(meas[SPECIFIC_FORCE]), np.ascontiguousarray(meas[MAGNETOMETER])

    def _reset(self, measurement: Mapping[str, ArrayLike], force: ArrayLike | None, torque: ArrayLike | None,
               rows: NDArray[np.bool_] | None, **options: Any) -> int:
        """Anchor R_a := the QUEST attitude, g_hat = g_hat' = 0, clock t = 0 (force/torque guesses unused).

        State: ``anchor`` (N, 3, 3) and the core's x1, x2 (N, 3) and t (N,) (:meth:`GibbsSTSMO.reset`)."""
        sf, mag = self._vectors(batch_measurement(measurement))
        n = sf.shape[0]
        R_q, valid = np.empty((n, 3, 3)), np.empty(n, dtype=np.bool_)
        _measured_attitude_rows(sf, mag, self._ref_unit, self.weights, self.gravity, self._min_field, R_q, valid)
        if not valid.all():
            raise ValueError("cannot initialize pdt_sta: accelerometer/magnetometer give no attitude "
                             f"(first at row {int(np.argmin(valid))}: |a| < 0.2 g, weak field or parallel)")
        self.core.reset(np.zeros((n, 3)), rows=rows)
        self.anchor = np.ascontiguousarray(write_rows(self.anchor, R_q, rows))
        self.quest_valid = write_rows(self.quest_valid, valid, rows)
        # the estimate at the anchor: attitude R_a (g_hat = 0), omega_hat = 0, the QUEST attitude, no wrench
        start = np.zeros((n, 30))
        start[:, 6:15] = start[:, 18:27] = R_q.reshape(n, 9)
        self._last = write_rows(self._last, start, rows)
        return n

    def _update(self, meas: dict[str, NDArray[np.float64]], thrust: NDArray[np.float64],
                torque: NDArray[np.float64], dt: float) -> tuple[ObserverEstimate, Any]:
        """One kernel call (:func:`_pdt_sta_rows`); the new state (anchor, x1, x2, t) is stored by :meth:`_commit`."""
        core = self.core
        n = core.n
        sf, mag = self._vectors(meas)
        state, out, valid = np.empty((n, 16)), np.empty((n, 30)), np.empty(n, bool)
        _pdt_sta_rows(sf, mag, np.ascontiguousarray(torque), dt, self._k, self.anchor, core.x1, core.x2, core.t,
                      state, out, valid, np.empty(N_WORK))
        # views of two buffers: the new state (no update writes into a stored state) and the estimate
        anchor, x1, x2, t = state[:, 0:9].reshape(n, 3, 3), state[:, 9:12], state[:, 12:15], state[:, 15]
        est = ObserverEstimate(force=out[:, 0:3], torque=out[:, 3:6], states=BufferStates(out, _STATES))
        return est, (anchor, x1, x2, t, valid, out)

    def _commit(self, state: Any) -> None:
        self.anchor, self.core.x1, self.core.x2, self.core.t, self.quest_valid, self._last = state

    def snapshot(self) -> Any:
        return self.anchor, self.core.x1, self.core.x2, self.core.t, self.quest_valid, self._last

    def estimate(self) -> ObserverEstimate:
        """The last update's estimate (after a reset: the anchor's, omega_hat = 0), in a fresh buffer: the estimate
        needs the step's QUEST attitude, so the update's own is kept rather than recomputed from the state."""
        if self._last is None:
            raise RuntimeError("pdt_sta: estimate() before reset(); call reset(measurement) first")
        out = self._last.copy()
        return ObserverEstimate(force=out[:, 0:3], torque=out[:, 3:6], states=BufferStates(out, _STATES))

    def params(self) -> dict[str, Any]:
        c = self.core
        return dict(t_c=c.t_c, eta=c.eta, kappa1=c.kappa1, kappa2=c.kappa2, t_switch=c.t_s, mode=c.mode)
