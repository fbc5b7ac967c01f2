"""The plain-float N = 1 paths equal the batched paths: QUEST (observers/quest.py ``_quest_unit_single``) and
the STSMO step (observers/gyroless_attitude.py ``GibbsSTSMO._step_single``), and the whole N = 1 update of the env
estimator ``pdt_sta`` (``PdtStaAttitudeObserver._update_single``) against the batched numpy path (the reference)."""

import numpy as np
import pytest
from _tolerance import HOLDER, assert_same_law

from fawtgym.core.measurement import EARTH_FIELD_NED, batch_measurement
from fawtgym.core.so3 import exp_so3, log_so3
from fawtgym.observers import make_observer
from fawtgym.observers import quest as Q
from fawtgym.observers.gyroless_attitude import GibbsSTSMO, rot_to_gibbs

FIELDS = ("R", "quaternion", "gibbs", "lambda_max", "loss")


def _same_quest(got, ref, what):
    """Two implementations of QUEST (floats, numpy; tests/_tolerance.py): every field at unit scale (rotation
    entries, unit quaternion, normalized weights: lambda_max <= 1, loss = 1 - lambda_max) or its own size (the
    Gibbs vector); eq. 65 is a 3 x 3 solve whose condition grows like 1 + |g|^2, <= 101 in the frame QUEST
    solves it in (it switches frames beyond |g| = 10)."""
    cond = 1.0 + 10.0**2
    for f in FIELDS:
        want = getattr(ref, f)[:1]
        assert_same_law(getattr(got, f), want, scale=max(1.0, np.abs(want).max()), cond=cond, what=f"{what}: {f}")


def _case(rng: np.random.Generator, angle: float, noise: float, nobs: int):
    ref = rng.standard_normal((1, nobs, 3))
    ref /= np.linalg.norm(ref, axis=-1, keepdims=True)
    axis = rng.standard_normal(3)
    R = exp_so3(angle * axis / np.linalg.norm(axis))
    body = np.einsum("ji,nkj->nki", R, ref) + noise * rng.standard_normal((1, nobs, 3))
    body /= np.linalg.norm(body, axis=-1, keepdims=True)
    return body, ref, rng.uniform(0.1, 3.0, (1, nobs))


@pytest.mark.parametrize("nobs", [2, 3, 4])
def test_single_path_equals_batch_path(nobs: int) -> None:
    rng = np.random.default_rng(nobs)
    used = 0
    for k in range(200):
        body, ref, a = _case(rng, angle=rng.uniform(0.0, 3.1), noise=(0.0, 1e-3, 0.1)[k % 3], nobs=nobs)
        used += Q._quest_unit_single(body[0].tolist(), ref[0].tolist(), a[0].tolist()) is not None
        one = Q.quest_unit(body, ref, a)  # N = 1: the float path (or its fallback)
        two = Q.quest_unit(np.repeat(body, 2, 0), np.repeat(ref, 2, 0), np.repeat(a, 2, 0))  # batched
        _same_quest(one, two, f"case {k}")
    assert used == 200  # the float path handled every case (also the near half turns, by sequential rotations)


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
    on floats as in the batch; the quaternion is the eigenvector of K (eq. 64) from eigh to 1e-12."""
    rng = np.random.default_rng(7)
    flipped = 0
    for k in range(30):
        body, ref, a = _case(rng, angle=angle, noise=(0.0, 1e-3, 0.05)[k % 3], nobs=2 + k % 2)
        single = Q._quest_unit_single(body[0].tolist(), ref[0].tolist(), a[0].tolist())
        assert single is not None  # the float path handles it
        two = Q.quest_unit(np.repeat(body, 2, 0), np.repeat(ref, 2, 0), np.repeat(a, 2, 0))
        _same_quest(single, two, f"case {k}")
        q, lam, norm, cond = _eigh_quaternion(body, ref, a)
        if q[0, 0] < 1e-9:  # an exact half turn: q and -q have w = 0, compare up to sign
            q = q * np.sign(np.vdot(q, single.quaternion))
        # QUEST (eq. 65 + sequential rotations) and eigh (eq. 64): two implementations of one eigenpair of the
        # 4 x 4 matrix K (tests/_tolerance.py): eigenvalue to n |K| eps, eigenvector to n |K| / gap eps (n = 4)
        assert_same_law(single.quaternion, q, scale=1.0, cond=4 * cond, what=f"case {k}: quaternion vs eigh")
        assert_same_law(single.lambda_max, lam, scale=norm, cond=4, what=f"case {k}: lambda_max vs eigh")
        assert np.all(np.isfinite(single.gibbs))
        flipped += Q._gibbs_floats(body[0].tolist(), ref[0].tolist(), a[0].tolist()) is None
    assert flipped >= 20  # eq. 65 in the given frame was ill-conditioned (|g| > 10) in most cases


def test_eigh_is_the_last_resort(monkeypatch: pytest.MonkeyPatch) -> None:
    """With eq. 65 declared ill-conditioned everywhere, every frame fails: the float path returns None and the batch
    takes the eigenvector of K (eq. 64), which equals the regular result."""
    rng = np.random.default_rng(8)
    cases = [_case(rng, angle=rng.uniform(0.0, np.pi), noise=0.01, nobs=2) for _ in range(20)]
    body, ref, a = (np.concatenate(x) for x in zip(*cases, strict=True))
    regular = Q.quest_unit(body, ref, a)
    monkeypatch.setattr(Q, "_GIBBS_SWITCH", 0.0)
    assert Q._quest_unit_single(body[0].tolist(), ref[0].tolist(), a[0].tolist()) is None
    last = Q.quest_unit(body, ref, a)
    # eigh (eq. 64) and QUEST (eq. 65): two implementations of one eigenvector, tests/_tolerance.py
    cond = 4 * _eigh_quaternion(body, ref, a)[3]
    assert_same_law(last.quaternion, regular.quaternion, scale=1.0, cond=cond, what="quaternion")
    assert_same_law(last.R, regular.R, scale=1.0, cond=cond, what="R")


def _same_stsmo(one, two, steps):
    """The float (N = 1) and the batched STSMO: two implementations of one law (tests/_tolerance.py) after ``steps``
    steps; the super-twisting terms |e1|^(1/2) sign(e1) are Hölder (cond=HOLDER).  Gibbs vectors and their rates
    at the scale of the run (0.3 rad/s input noise: at least 1), the time at its own."""
    for a, b, what in ((one.x1, two.x1, "x1"), (one.x2, two.x2, "x2")):
        assert_same_law(a, b[:1], scale=max(1.0, np.abs(b).max()), steps=steps, cond=HOLDER, what=what)
    assert_same_law(one.t, two.t[:1], steps=steps, what="t")


def test_stsmo_single_step_equals_batch_step() -> None:
    """Through the exact (t < t_c) and STA phases, with e1 = 0 steps and varying dt."""
    rng = np.random.default_rng(3)
    J = np.diag([0.082, 0.0845, 0.1377])
    for _ in range(5):
        one, two = (GibbsSTSMO(J, t_c=0.3, eta=5.0, kappa1=2.5, kappa2=0.5) for _ in range(2))
        x0 = 0.3 * rng.standard_normal((1, 3))
        one.reset(x0, 0.1 * x0)
        two.reset(np.repeat(x0, 2, 0), np.repeat(0.1 * x0, 2, 0))
        for k in range(200):
            y = 0.3 * rng.standard_normal((1, 3)) if k % 7 else one.x1.copy()
            u = 0.05 * rng.standard_normal((1, 3))
            dt = float(rng.choice([1e-3, 2e-3, 7e-3]))
            one.step(y, u, dt)  # N = 1: the float path
            two.step(np.repeat(y, 2, 0), np.repeat(u, 2, 0), dt)  # batched
            _same_stsmo(one, two, k + 1)
        assert one.t[0] > one.t_s  # both phases were covered


# --------------------------------------------------------------------------------------------------
# the env estimator pdt_sta: PdtStaAttitudeObserver._update_single (plain floats) vs the batched path
# --------------------------------------------------------------------------------------------------
#: the N = 1 float path and the batched numpy path are two implementations of one law (tests/_tolerance.py):
#: they differ in the rounding of a few sums/products (BLAS matmul, numpy reductions), which the super-twisting
#: terms |e|^(1/2) sign(e) of eqs. 77-82 amplify (cond=HOLDER); compared at every step over the whole run.
KEYS = ("attitude", "angular_velocity", "attitude_quest", "gibbs", "quest_valid")


def _pair(mass, inertia, **kw):
    """(fast, spy, ref): an N = 1 observer whose fast-path calls are recorded, and the reference observer that
    runs the same vehicle twice (N = 2 equal rows: the batched numpy path throughout)."""
    fast = make_observer("pdt_sta", mass, inertia, **kw)
    ref = make_observer("pdt_sta", mass, inertia, **kw)
    spy = []
    inner = fast._update_single

    def wrapped(*args, **kwargs):
        est = inner(*args, **kwargs)
        spy.append(est is not None)
        return est

    fast._update_single = wrapped
    return fast, spy, ref


def _twice(meas):
    """The measurement of one vehicle as a batch of two equal rows."""
    return {k: np.repeat(v, 2, 0) for k, v in batch_measurement(meas).items()}


def _agree(a, b, what, steps):
    """Attitude matrices at unit scale, Gibbs vectors and rates at their own scale or at least 1 (rad/s: the rates
    of these runs), the QUEST flag and the (zero) wrench exactly."""
    assert set(a.states) == set(b.states) == set(KEYS), what
    for k in ("attitude", "attitude_quest", "gibbs", "angular_velocity"):
        want = b.states[k][:1]
        assert_same_law(a.states[k], want, scale=max(1.0, np.abs(want).max()), steps=steps, cond=HOLDER,
                        what=f"{what}: {k}")
    np.testing.assert_array_equal(a.states["quest_valid"], b.states["quest_valid"][:1])
    np.testing.assert_array_equal(a.force, np.zeros((1, 3)))
    np.testing.assert_array_equal(a.torque, np.zeros((1, 3)))


@pytest.fixture(scope="module")
def env_sequence():
    """1000 steps (10 s at 100 Hz) of the hover env in the fawt-50 wind under PX4 control, with its noisy IMU."""
    import gymnasium as gym

    import fawtgym  # noqa: F401  (registers the env ids)
    from fawtgym.agents.px4_agent import PX4Agent

    env = gym.make("fawtgym/Hover-v0", sensors="mocap_imu", wind="fawt-50")
    u = env.unwrapped
    _, info = env.reset(seed=5)
    agent = PX4Agent.for_env(env)
    agent.reset(info, seed=5)
    first = info["measurement"]
    steps = []
    for _ in range(1000):
        _, _, term, _, info = env.step(agent.act(None, info))
        assert not term, info["failure"]
        ap = info["applied"]
        steps.append((info["measurement"], ap["thrust"], ap["torque"], info["truth"]))
    env.close()
    return first, steps, u.preset, u.dt


def test_observer_fast_path_equals_batched_path_on_the_env(env_sequence) -> None:
    first, steps, preset, dt = env_sequence
    fast, spy, ref = _pair(preset.mass, preset.inertia_matrix)
    fast.reset(first)
    ref.reset(_twice(first))
    att_err = []
    for k, (meas, thrust, torque, truth) in enumerate(steps):
        a = fast.update(meas, thrust, torque, dt)
        b = ref.update(_twice(meas), np.repeat(thrust, 2), np.repeat(np.atleast_2d(torque), 2, 0), dt)
        _agree(a, b, f"step {k}", k + 1)
        r_true = np.asarray(truth["attitude"]).reshape(3, 3)
        att_err.append(float(np.linalg.norm(log_so3(a.states["attitude"][0].T @ r_true))))
    assert all(spy) and len(spy) == len(steps)  # every env step took the float path
    assert fast.core.t[0] > fast.core.t_s  # both phases of eq. 77 were run
    n = len(steps)
    assert_same_law(fast.core.x1, ref.core.x1[:1], scale=max(1.0, np.abs(ref.core.x1).max()), steps=n, cond=HOLDER,
                    what="x1")
    assert_same_law(fast.core.t, ref.core.t[:1], steps=n, what="t")
    # a real estimation run, not two equal failures: after t_c the attitude follows the truth
    assert np.median(att_err[200:]) < 0.05


def _imu(r, rng, noise, field=EARTH_FIELD_NED):
    rt = r.T
    return {"specific_force": -9.80665 * rt[:, 2] + noise * rng.standard_normal(3),
            "magnetometer": rt @ field + 0.02 * noise * rng.standard_normal(3), "time": 0.0}


def test_observer_fast_path_equals_batched_path_tumbling() -> None:
    """1200 steps of a body tumbling through large angles (re-anchoring, QUEST's sequential rotations near a half
    turn from NED), with noise, varying dt, free-fall rows (no vector attitude: the batched path in both) and
    the conventional STSMO (eqs. 81-82)."""
    J3 = np.diag([0.03, 0.03, 0.06])
    rng = np.random.default_rng(21)
    for kw, n_steps in (({}, 1200), ({"mode": "conventional"}, 300), ({"t_c": 0.8, "noise_bound": 0.05}, 300)):
        fast, spy, ref = _pair(1.0, J3, **kw)
        r = exp_so3(np.array([0.2, -0.1, 3.0]))  # yaw near pi: |g| of the QUEST attitude > 10
        w = np.array([0.5, -0.4, 1.5])
        m0 = _imu(r, rng, 0.05)
        fast.reset(m0)
        ref.reset(_twice(m0))
        anchors = 0
        half = 0
        for k in range(n_steps):
            dt = (0.01, 0.004, 0.0075)[k % 3]
            tau = -0.02 * w + 0.01 * np.array([np.sin(0.01 * k), np.cos(0.02 * k), 0.3])
            w = w + dt * (np.cross(J3 @ w, w) + tau) / np.diag(J3)
            r = r @ exp_so3(dt * w)
            m = _imu(r, rng, 0.05)
            if k % 150 == 75:
                m["specific_force"] = 0.01 * rng.standard_normal(3)  # free fall
            anchor = fast.anchor
            a = fast.update(m, 0.0, tau, dt)
            b = ref.update(_twice(m), np.zeros(2), np.repeat(tau[None], 2, 0), dt)
            assert spy[-1] == (k % 150 != 75)
            _agree(a, b, f"{kw} step {k}", k + 1)
            anchors += fast.anchor is not anchor
            g = rot_to_gibbs(a.states["attitude_quest"]) if abs(np.trace(a.states["attitude_quest"][0]) + 1) > 1e-6 \
                else np.full((1, 3), np.inf)
            half += bool(np.linalg.norm(g) > 10)
        if n_steps == 1200:
            assert anchors >= 3 and half >= 5, (anchors, half)  # both special cases were exercised
        assert_same_law(fast.core.x2, ref.core.x2[:1], scale=max(1.0, np.abs(ref.core.x2).max()), steps=n_steps,
                        cond=HOLDER, what=f"{kw} x2")


def _hover_meas(n: int = 1):
    r = exp_so3(np.array([0.05, -0.03, 0.4]))
    m = {"position": np.zeros(3), "velocity": np.zeros(3), "attitude": r, "angular_velocity": np.zeros(3),
         "gyro": np.zeros(3), "specific_force": r.T @ np.array([0.0, 0.0, -9.80665]),
         "magnetometer": r.T @ EARTH_FIELD_NED, "time": 0.0}
    return m if n == 1 else {k: np.repeat(v, n, 0) for k, v in batch_measurement(m).items()}


def test_batch_of_two_takes_the_batched_path() -> None:
    fast, spy, _ = _pair(1.0, [0.03, 0.03, 0.06])
    fast.reset(_hover_meas(2))
    est = fast.update(_hover_meas(2), np.ones(2), np.zeros((2, 3)), 0.01)
    assert spy == [] and est.states["attitude"].shape == (2, 3, 3)


@pytest.mark.parametrize("change, match", [
    (lambda m: m.update(specific_force=np.array([np.nan, 0.0, -9.8])), "non-finite"),
    (lambda m: m.update(magnetometer=np.array([np.inf, 0.0, 0.0])), "non-finite"),
    (lambda m: m.pop("magnetometer"), "magnetometer"),
    (lambda m: m.update(specific_force=np.zeros((2, 3)), magnetometer=np.zeros((2, 3))), "batch size changed"),
])
def test_malformed_measurement_takes_the_batched_path_and_raises(change, match) -> None:
    fast, spy, _ = _pair(1.0, [0.03, 0.03, 0.06])
    fast.reset(_hover_meas())
    fast.update(_hover_meas(), 1.0, np.zeros(3), 0.01)
    x1, x2, t = fast.core.x1.copy(), fast.core.x2.copy(), fast.core.t.copy()
    m = _hover_meas()
    change(m)
    with pytest.raises(ValueError, match=match):
        fast.update(m, 1.0, np.zeros(3), 0.01)
    assert spy == [True, False]
    for now, before in ((fast.core.x1, x1), (fast.core.x2, x2), (fast.core.t, t)):
        np.testing.assert_array_equal(now, before)  # nothing was changed


@pytest.mark.parametrize("thrust, torque, dt, match", [
    (1.0, np.zeros(3), 0.0, "dt"), (1.0, np.zeros(3), float("nan"), "dt"),
    (1.0, np.array([0.0, np.nan, 0.0]), 0.01, "non-finite"), (np.nan, np.zeros(3), 0.01, "non-finite"),
    (1.0, np.zeros(4), 0.01, "torque"),
])
def test_malformed_step_takes_the_batched_path_and_raises(thrust, torque, dt, match) -> None:
    fast, spy, _ = _pair(1.0, [0.03, 0.03, 0.06])
    fast.reset(_hover_meas())
    with pytest.raises(ValueError, match=match):
        fast.update(_hover_meas(), thrust, torque, dt)
    assert spy == [False]


@pytest.mark.parametrize("mode, integrator", [("conventional", "exact"), ("predefined", "euler")])
def test_stsmo_single_step_equals_batch_step_other_modes(mode, integrator) -> None:
    rng = np.random.default_rng(4)
    J = np.diag([0.082, 0.0845, 0.1377])
    one, two = (GibbsSTSMO(J, t_c=0.3, eta=5.0, kappa1=2.5, kappa2=0.5, mode=mode, integrator=integrator)
                for _ in range(2))
    x0 = 0.3 * rng.standard_normal((1, 3))
    one.reset(x0)
    two.reset(np.repeat(x0, 2, 0))
    for k in range(200):
        y = 0.3 * rng.standard_normal((1, 3)) if k % 7 else one.x1.copy()
        u = 0.05 * rng.standard_normal((1, 3))
        dt = float(rng.choice([1e-3, 2e-3, 7e-3]))
        one.step(y, u, dt)
        two.step(np.repeat(y, 2, 0), np.repeat(u, 2, 0), dt)
        assert one._floats is not None  # the float path ran
        _same_stsmo(one, two, k + 1)
