"""QUEST's special cases (near a half turn: Shuster and Oh's sequential rotations; the eigenvector of K, eq. 64)
and the env estimator ``pdt_sta`` end to end: on the hover env, tumbling through half turns, and its errors (the
same text at every N, the state unchanged)."""

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.measurement import EARTH_FIELD_NED, batch_measurement
from fawtgym.core.so3 import exp_so3, log_so3
from fawtgym.observers import make_observer
from fawtgym.observers import quest as Q
from fawtgym.observers.gibbs import rot_to_gibbs

#: |g| beyond which QUEST solves again in the frames rotated by pi (observers/quest.py's documented switch)
GIBBS_SWITCH = 10.0


def _case(rng: np.random.Generator, angle: float, noise: float, nobs: int):
    ref = rng.standard_normal((1, nobs, 3))
    ref /= np.linalg.norm(ref, axis=-1, keepdims=True)
    axis = rng.standard_normal(3)
    R = exp_so3(angle * axis / np.linalg.norm(axis))
    body = np.einsum("ji,nkj->nki", R, ref) + noise * rng.standard_normal((1, nobs, 3))
    body /= np.linalg.norm(body, axis=-1, keepdims=True)
    return body, ref, rng.uniform(0.1, 3.0, (1, nobs))


def _eigh_quaternion(body, ref, a):
    """The eigenvector of K for its largest eigenvalue (eq. 64), (w, x, y, z) with w >= 0, computed independently;
    with lambda_max, |K| and the eigenvector's condition number |K| / (lambda_1 - lambda_2)."""
    a = a / a.sum(axis=1, keepdims=True)
    B = np.einsum("ni,nij,nik->njk", a, body, ref)
    S = B + np.swapaxes(B, 1, 2)
    rho = np.trace(B, axis1=1, axis2=2)
    z = np.einsum("ni,nij->nj", a, np.cross(body, ref))
    K = np.zeros((len(a), 4, 4))
    K[:, :3, :3] = S - rho[:, None, None] * np.eye(3)
    K[:, :3, 3] = K[:, 3, :3] = z
    K[:, 3, 3] = rho
    w, v = np.linalg.eigh(K)
    q = np.concatenate([v[:, 3:, -1], v[:, :3, -1]], axis=1)
    norm = np.abs(w).max(axis=1)
    cond = norm / (w[:, -1] - w[:, -2])
    return q * np.where(q[:, :1] < 0, -1.0, 1.0), w[:, -1], float(norm.max()), float(max(1.0, cond.max()))


@pytest.mark.parametrize("angle", [2.95, 3.05, np.pi - 1e-4, np.pi])
def test_near_half_turn_sequential_rotations(angle: float) -> None:
    """|g| > 10: QUEST is solved again with the references rotated by pi (Shuster and Oh's sequential rotations),
    the quaternion is the eigenvector of K (eq. 64) from eigh to 1e-12."""
    rng = np.random.default_rng(7)
    flipped = 0
    for k in range(30):
        body, ref, a = _case(rng, angle=angle, noise=(0.0, 1e-3, 0.05)[k % 3], nobs=2 + k % 2)
        single = Q.quest_unit(body, ref, a)
        q, lam, norm, cond = _eigh_quaternion(body, ref, a)
        if q[0, 0] < 1e-9:  # an exact half turn: q and -q have w = 0, compare up to sign
            q = q * np.sign(np.vdot(q, single.quaternion))
        # QUEST (eq. 65 + sequential rotations) and eigh (eq. 64): two implementations of one eigenpair of the
        # 4 x 4 matrix K (tests/_tolerance.py): eigenvalue to n |K| eps, eigenvector to n |K| / gap eps (n = 4)
        assert_same_law(single.quaternion, q, scale=1.0, cond=4 * cond, what=f"case {k}: quaternion vs eigh")
        assert_same_law(single.lambda_max, lam, scale=norm, cond=4, what=f"case {k}: lambda_max vs eigh")
        assert np.all(np.isfinite(single.gibbs))
        # the Gibbs vector of the attitude beyond QUEST's switch |g| > 10 (rotation angle > 168.6 deg): eq. 65 in
        # the given frame is ill-conditioned there and the kernel took the sequential rotations
        flipped += bool(np.linalg.norm(single.gibbs) > GIBBS_SWITCH)
    assert flipped >= 20  # eq. 65 in the given frame was ill-conditioned (|g| > 10) in most cases


def test_eigh_is_the_last_resort() -> None:
    """The last resort of the QUEST kernel, the eigenvector of K (eq. 64), equals the regular result (eq. 65)."""
    rng = np.random.default_rng(8)
    cases = [_case(rng, angle=rng.uniform(0.0, np.pi), noise=0.01, nobs=2) for _ in range(20)]
    body, ref, a = (np.concatenate(x) for x in zip(*cases, strict=True))
    regular = Q.quest_unit(body, ref, a)
    last_q = np.array([Q._eigh_quaternion(body[i], ref[i], a[i])[:4] for i in range(len(body))])
    last = Q.QuestResult(R=np.array([_rot(q) for q in last_q]), quaternion=last_q, gibbs=regular.gibbs,
                         lambda_max=regular.lambda_max, loss=regular.loss)
    # eigh (eq. 64) and QUEST (eq. 65): two implementations of one eigenvector, tests/_tolerance.py
    cond = 4 * _eigh_quaternion(body, ref, a)[3]
    assert_same_law(last.quaternion, regular.quaternion, scale=1.0, cond=cond, what="quaternion")
    assert_same_law(last.R, regular.R, scale=1.0, cond=cond, what="R")


def _rot(q):
    R = np.empty((3, 3))
    Q.quat_to_rot_row(q, R)
    return R


@pytest.fixture(scope="module")
def env_sequence():
    """1000 steps (10 s at 100 Hz) of the hover env in the fawt-50 wind under PX4 control, with its noisy IMU."""
    from _env_helpers import px4_hover_sequence

    return px4_hover_sequence(seed=5)


def _imu(r, rng, noise, field=EARTH_FIELD_NED):
    rt = r.T
    return {"specific_force": -9.80665 * rt[:, 2] + noise * rng.standard_normal(3),
            "magnetometer": rt @ field + 0.02 * noise * rng.standard_normal(3), "time": 0.0}


def _hover_meas(n: int = 1):
    r = exp_so3(np.array([0.05, -0.03, 0.4]))
    m = {"position": np.zeros(3), "velocity": np.zeros(3), "attitude": r, "angular_velocity": np.zeros(3),
         "gyro": np.zeros(3), "specific_force": r.T @ np.array([0.0, 0.0, -9.80665]),
         "magnetometer": r.T @ EARTH_FIELD_NED, "time": 0.0}
    return m if n == 1 else {k: np.repeat(v, n, 0) for k, v in batch_measurement(m).items()}




def test_pdt_sta_on_the_env(env_sequence) -> None:
    """PX4 in the fawt-50 wind with the mocap_imu sensors at 100 Hz: after t_c the attitude follows the truth, and a
    batch of three copies of the vehicle gives each row the N = 1 numbers bitwise (a row does not see the others)."""
    first, steps, preset, dt = env_sequence
    one = make_observer("pdt_sta", preset.mass, preset.inertia_matrix)
    three = make_observer("pdt_sta", preset.mass, preset.inertia_matrix)
    one.reset(first)
    three.reset({k: np.repeat(v, 3, 0) for k, v in batch_measurement(first).items()})
    att_err = []
    for meas, thrust, torque, truth in steps:
        a = one.update(meas, thrust, torque, dt)
        b = three.update({k: np.repeat(v, 3, 0) for k, v in batch_measurement(meas).items()}, np.repeat(thrust, 3),
                         np.repeat(np.atleast_2d(torque), 3, 0), dt)
        for key in ("attitude", "angular_velocity", "attitude_quest", "gibbs"):
            np.testing.assert_array_equal(b.states[key], np.repeat(a.states[key], 3, 0), err_msg=key)
        np.testing.assert_array_equal(three.quest_valid, np.repeat(one.quest_valid, 3))
        r_true = np.asarray(truth["attitude"]).reshape(3, 3)
        att_err.append(float(np.linalg.norm(log_so3(a.states["attitude"][0].T @ r_true))))
    assert one.core.t[0] > one.core.t_s  # both phases of eq. 77 were run
    assert np.median(att_err[200:]) < 0.05


def test_pdt_sta_tumbling() -> None:
    """1200 steps of a body tumbling through large angles (re-anchoring, QUEST's sequential rotations near a half
    turn from NED), with noise, varying dt and free-fall steps (no vector attitude: no correction, flagged): the
    estimate stays finite and, after t_c, follows the truth."""
    J3 = np.diag([0.03, 0.03, 0.06])
    rng = np.random.default_rng(21)
    obs = make_observer("pdt_sta", 1.0, J3)
    r = exp_so3(np.array([0.2, -0.1, 3.0]))  # yaw near pi: |g| of the QUEST attitude > 10
    w = np.array([0.5, -0.4, 1.5])
    obs.reset(_imu(r, rng, 0.05))
    anchors = half = 0
    err = []
    for k in range(1200):
        dt = (0.01, 0.004, 0.0075)[k % 3]
        tau = -0.02 * w + 0.01 * np.array([np.sin(0.01 * k), np.cos(0.02 * k), 0.3])
        w = w + dt * (np.cross(J3 @ w, w) + tau) / np.diag(J3)
        r = r @ exp_so3(dt * w)
        m = _imu(r, rng, 0.05)
        if k % 150 == 75:
            m["specific_force"] = 0.01 * rng.standard_normal(3)  # free fall
        anchor = obs.anchor.copy()
        est = obs.update(m, 0.0, tau, dt)
        assert bool(obs.quest_valid[0]) == (k % 150 != 75)
        anchors += not np.array_equal(obs.anchor, anchor)
        rq = est.states["attitude_quest"]
        half += abs(np.trace(rq[0]) + 1) <= 1e-6 or bool(np.linalg.norm(rot_to_gibbs(rq)) > 10)
        err.append(float(np.linalg.norm(log_so3(est.states["attitude"][0].T @ r))))
    assert anchors >= 3 and half >= 5, (anchors, half)  # both special cases were exercised
    assert np.all(np.isfinite(err)) and np.median(err[400:]) < 0.1


def _bad(change):
    def apply(m):
        m = dict(m)
        change(m)
        return m
    return apply


@pytest.mark.parametrize("change, match", [
    (lambda m: m.update(specific_force=np.array([np.nan, 0.0, -9.8])), "non-finite"),
    (lambda m: m.update(magnetometer=np.array([np.inf, 0.0, 0.0])), "non-finite"),
    (lambda m: m.pop("magnetometer"), "magnetometer"),
])
def test_bad_measurement_raises_the_same_at_every_n(change, match) -> None:
    """One message and exception type at N = 1 and N = 3, and the state is unchanged."""
    texts = []
    for n in (1, 3):
        obs = make_observer("pdt_sta", 1.0, [0.03, 0.03, 0.06])
        obs.reset(_hover_meas(n))
        obs.update(_hover_meas(n), np.ones(n), np.zeros((n, 3)), 0.01)
        before = (obs.core.x1.copy(), obs.core.x2.copy(), obs.core.t.copy(), obs.anchor.copy())
        m = _hover_meas(n)
        if n == 1:
            change(m)
        else:
            one = _hover_meas(1)
            change(one)
            m = {k: np.repeat(np.asarray(v)[None], n, 0) if k in one and np.ndim(v) else v for k, v in one.items()}
        with pytest.raises(ValueError, match=match) as info:
            obs.update(m, np.ones(n), np.zeros((n, 3)), 0.01)
        texts.append(str(info.value))
        for now, was in zip((obs.core.x1, obs.core.x2, obs.core.t, obs.anchor), before, strict=True):
            np.testing.assert_array_equal(now, was)
    assert texts[0] == texts[1]


def test_update_before_reset_is_a_runtime_error() -> None:
    obs = make_observer("pdt_sta", 1.0, [0.03, 0.03, 0.06])
    with pytest.raises(RuntimeError, match="reset"):
        obs.update(_hover_meas(), 1.0, np.zeros(3), 0.01)


@pytest.mark.parametrize("n", [1, 3])
def test_dt_above_max_dt_is_refused(n):
    """dt is bounded by the STA phase's forward-Euler step (max_dt = 0.02 s, see PdtStaAttitudeObserver)."""
    obs = make_observer("pdt_sta", 1.0, [0.03, 0.03, 0.06])
    obs.reset(_hover_meas(n))
    with pytest.raises(ValueError, match=r"^pdt_sta: dt must be .* \(0, 0.02\]"):
        obs.update(_hover_meas(n), np.ones(n), np.zeros((n, 3)), 0.025)
    obs.update(_hover_meas(n), np.ones(n), np.zeros((n, 3)), 0.02)
