"""Runtime QB observer (seed-001 qb_observer_cayero2019.txt): shipped gains, frames, batch, no-cvxpy run,
and a shortened Fig. 7 check of the mu claim (the full reproduction is a long test)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
from _tolerance import assert_same_law
from scipy.integrate import solve_ivp

from fawtgym.core.so3 import hat
from fawtgym.envs.vehicles import GRAVITY
from fawtgym.eval.reproduce import qb_observer as rq
from fawtgym.observers import make_observer, observer_names
from fawtgym.observers import qb_design as qd
from fawtgym.observers.qb import GAIN_DIR, QBObserver, load_gain
from fawtgym.observers.qb_uav_model import HUMMINGBIRD_INERTIA, HUMMINGBIRD_MASS, scaled_q2, uav_model

M_H, J_H = HUMMINGBIRD_MASS, np.diag(HUMMINGBIRD_INERTIA)
MUS = {"0p2": 0.2, "0p5": 0.5, "0p95": 0.95}


@pytest.fixture(scope="module")
def gains():
    return {k: load_gain(f"qb_gain_hummingbird_mu{k}") for k in MUS}


def _as_solution(g) -> qd.QBSolution:
    pz = qd.projection_matrix(g.P, g.E1)
    return qd.QBSolution(alpha=g.alpha, P=g.P, Y=g.P @ g.L, X=pz, L=g.L, Pz=pz, log_volume=g.log_volume,
                         status="stored", solver="", solve_seconds=0.0)


def test_registered_and_default_constructible():
    assert "qb" in observer_names()
    obs = make_observer("qb", M_H, J_H)
    assert obs.channels == frozenset({"force", "torque"}) and obs.gain.mu == 0.5 and obs.order == 3


SHIPPED = sorted(p.stem for p in GAIN_DIR.glob("qb_gain_*.npz"))


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_gain_matches_its_design_inputs_and_satisfies_lmi7(name):
    g = load_gain(name)
    pr = uav_model(r=g.meta["r"], q1_scale=g.meta["q1_scale"], q2=scaled_q2(g.meta["mass"], g.meta["inertia"]))
    for arr_name, arr in pr.as_arrays().items():
        # built here and when the file was written (another machine, another BLAS): two runs of one law that may
        # round differently (tests/_tolerance.py); a stale file differs at the level of the changed inputs
        assert_same_law(getattr(g, arr_name), arr, what=f"{name}: stored {arr_name} is stale")
    sol = _as_solution(g)
    r = qd.lmi_residuals(pr, sol)
    assert r["lmi7_max_eig"] <= 1e-6 * r["lmi7_scale"], (name, r)  # LMI (7) with the stored P, L
    assert r["decay_margin"] <= 1e-6 * g.alpha, (name, r)
    assert math.isclose(qd.ellipsoid_log_volume(qd.projection_matrix(g.P, g.E1)), g.log_volume, abs_tol=1e-6)
    a = g.meta["anchors"]
    assert a["alpha_nadir"] <= g.alpha <= a["alpha_star"] == 20.0
    # picked automatically for its own vehicle, without a warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        if g.mu == 0.5:
            assert make_observer("qb", g.meta["mass"], g.meta["inertia"]).gain.meta == g.meta


def test_hummingbird_gains_follow_fig6_ordering(gains):
    for key, g in gains.items():
        assert g.mu == MUS[key] and g.meta["r"] == 3 and g.meta["mass"] == M_H
    # Fig. 6: higher mu -> smaller alpha and smaller volume
    assert gains["0p95"].alpha < gains["0p5"].alpha <= gains["0p2"].alpha
    assert gains["0p95"].log_volume < gains["0p5"].log_volume <= gains["0p2"].log_volume


def test_stored_gain_is_reproduced_by_the_sdp(gains):
    """Re-solve eq. 31 at the stored alpha (one r = 3 SDP): same optimal volume, LMIs hold."""
    g = gains["0p95"]
    pr = uav_model()
    sol = qd.solve_qb_lmi(pr, g.alpha)
    assert abs(sol.log_volume - g.log_volume) < 1e-3
    r = qd.lmi_residuals(pr, sol)
    assert r["lmi7_max_eig"] <= 1e-6 * r["lmi7_scale"] and r["lmi30_min_eig"] >= -1e-6 * r["lmi30_scale"]
    assert r["decay_margin"] <= 1e-6 * g.alpha and r["P_min_eig"] > 0


def _hover_meas(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    from fawtgym.core.so3 import exp_so3

    R = exp_so3(0.2 * rng.normal(size=(n, 3)))
    return {"position": rng.normal(size=(n, 3)), "velocity": rng.normal(size=(n, 3)), "attitude": R,
            "angular_velocity": 0.3 * rng.normal(size=(n, 3)),
            "specific_force": np.array([0.0, 0.0, -GRAVITY]) + 0.5 * rng.normal(size=(n, 3))}


def test_batch_equals_single(gains):
    rng = np.random.default_rng(0)
    n = 4
    seq = [_hover_meas(n, rng) for _ in range(6)]
    thrust = M_H * GRAVITY * (1 + 0.1 * rng.normal(size=(6, n)))
    torque = 0.01 * rng.normal(size=(6, n, 3))
    batch = QBObserver(M_H, J_H)
    batch.reset(seq[0])
    for k in range(1, 6):
        eb = batch.update(seq[k], thrust[k], torque[k], 0.01)
    for i in range(n):
        one = QBObserver(M_H, J_H)
        one.reset({key: v[i] for key, v in seq[0].items()})
        for k in range(1, 6):
            e1 = one.update({key: v[i] for key, v in seq[k].items()}, thrust[k, i], torque[k, i], 0.01)
        # a batch row and a separate N = 1 run: one kernel, each row's product its own loop -> bitwise equal
        assert e1.force[0].tobytes() == eb.force[i].tobytes(), (i, e1.force[0], eb.force[i])
        assert e1.torque[0].tobytes() == eb.torque[i].tobytes(), (i, e1.torque[0], eb.torque[i])
        for key, value in e1.states.items():
            assert value[0].tobytes() == eb.states[key][i].tobytes(), (i, key)


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("dt", [5e-324, 1e-310, 1e-12])
def test_a_step_below_min_dt_is_refused_with_the_dt_message(n, dt):
    """A subnormal dt is inside (0, max_dt] but the first-order hold divides by it: it used to overflow (numpy
    RuntimeWarning) and then report a diverged estimate; now the dt message with the lower bound, at every N, on
    both input paths, with the state unchanged and no warning."""
    obs, twin = QBObserver(M_H, J_H), QBObserver(M_H, J_H)
    rng = np.random.default_rng(3)
    meas, after = _hover_meas(n, rng), _hover_meas(n, rng)
    obs.reset(meas)
    twin.reset(meas)
    f, tau = np.full(n, M_H * GRAVITY), np.zeros((n, 3))
    text = (f"qb: dt must be a finite number of seconds in [1e-09, 0.1] (min_dt: the first-order hold divides by dt; "
            f"max_dt, the bound of its discretisation), got {dt!r}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for step in (dt, np.float64(dt)):       # a float takes the compiled input checks, np.float64 the Python ones
            with pytest.raises(ValueError) as info:
                obs.update(meas, f, tau, step)
            assert str(info.value) == text
        # the refused updates changed nothing: the next update equals that of a twin that never saw them
        est, want = obs.update(after, f, tau, 0.01), twin.update(after, f, tau, 0.01)
        assert est.force.tobytes() == want.force.tobytes() and est.torque.tobytes() == want.torque.tobytes()
        assert np.isfinite(obs.update(after, f, tau, 1e-9).force).all()        # the bound itself: accepted


def test_estimates_true_disturbance_of_a_rotating_rigid_body():
    """Frames: force NED and torque FRD of the seed-000 model (eq. 38) are recovered from the env's
    measurement keys, with the vehicle rotating (world torque R tau_D changes with time)."""
    m, J = 1.2, np.diag([0.02, 0.025, 0.04])
    phi = np.array([0.4, -0.3, 0.2])  # NED
    tau_d = np.array([0.01, -0.02, 0.008])  # FRD
    f, tau_a = m * GRAVITY * 0.95, np.array([0.002, 0.001, -0.003])

    def rhs(_t, s):
        v, R, w = s[3:6], s[6:15].reshape(3, 3), s[15:18]
        a = GRAVITY * np.array([0, 0, 1.0]) + (-f * R[:, 2] + phi) / m
        wd = np.linalg.solve(J, np.cross(J @ w, w) + tau_a + tau_d)
        return np.concatenate([v, a, (R @ hat(w)).ravel(), wd])

    dt, n_steps = 0.01, 300
    s0 = np.concatenate([np.zeros(6), np.eye(3).ravel(), [0.5, -0.3, 0.8]])
    sol = solve_ivp(rhs, (0, dt * n_steps), s0, t_eval=np.arange(n_steps + 1) * dt, rtol=1e-10, atol=1e-12)

    def meas(k):
        s = sol.y[:, k]
        R = s[6:15].reshape(3, 3)
        acc = rhs(0, s)[3:6]
        return {"velocity": s[3:6], "attitude": R, "angular_velocity": s[15:18],
                "specific_force": R.T @ (acc - GRAVITY * np.array([0, 0, 1.0]))}

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise ellipsoid designed for the Hummingbird mass
        obs = make_observer("qb", m, J)
    obs.reset(meas(0), thrust=f)
    for k in range(1, n_steps + 1):
        est = obs.update(meas(k), f, tau_a, dt)
    np.testing.assert_allclose(est.force[0], phi, atol=2e-3)
    np.testing.assert_allclose(est.torque[0], tau_d, atol=1e-3)
    np.testing.assert_allclose(est.states["angular_velocity"][0], sol.y[15:18, -1], atol=1e-3)
    np.testing.assert_allclose(est.states["velocity"][0], sol.y[3:6, -1], atol=1e-3)


def test_saved_gain_round_trip_runs_without_cvxpy_and_design_names_the_extra(tmp_path, gains):
    path = gains["0p95"].save(tmp_path / "g.npz")
    again = load_gain(path)
    for name in ("A", "C", "L", "P", "Q"):
        np.testing.assert_array_equal(getattr(again, name), getattr(gains["0p95"], name))
    assert again.alpha == gains["0p95"].alpha and again.meta == gains["0p95"].meta
    rng = np.random.default_rng(5)
    seq = [_hover_meas(1, rng) for _ in range(4)]
    obs = QBObserver(M_H, J_H, gain_file=path)
    obs.reset(seq[0])
    for k in range(1, 4):
        est = obs.update(seq[k], M_H * GRAVITY, np.zeros(3), 0.01)
    (tmp_path / "seq.json").write_text(json.dumps([{k: v.tolist() for k, v in s.items()} for s in seq]))
    code = f"""
import sys, json
sys.modules['cvxpy'] = None  # any 'import cvxpy' now raises ImportError
import numpy as np
from fawtgym.observers import make_observer
seq = json.load(open({str(tmp_path / 'seq.json')!r}))
obs = make_observer('qb', {M_H}, {list(J_H)}, gain_file={str(path)!r})
obs.reset(seq[0])
for s in seq[1:]:
    e = obs.update(s, {M_H * GRAVITY}, [0.0, 0.0, 0.0], 0.01)
from fawtgym.observers.qb_design import solve_qb_lmi
from fawtgym.observers.qb_uav_model import uav_model
try:
    solve_qb_lmi(uav_model(r=1), 1.0)
    msg = "designed without cvxpy?"
except ImportError as exc:
    msg = str(exc)
print(json.dumps([e.force[0].tolist(), e.torque[0].tolist(), msg]))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    force, torque, msg = json.loads(out.stdout.strip().splitlines()[-1])
    # lists in the subprocess, (1, 3) arrays here: possibly two paths of one law (tests/_tolerance.py)
    assert_same_law(force, est.force[0], steps=3, what="force without cvxpy")
    assert_same_law(torque, est.torque[0], steps=3, what="torque without cvxpy")
    # ... and designing without cvxpy names the optional extra
    assert "pip install 'fawtgym[design]'" in msg, msg


def test_bad_inputs_raise(tmp_path):
    obs = QBObserver(M_H, J_H)
    meas = _hover_meas(1, np.random.default_rng(1))
    with pytest.raises(RuntimeError, match="reset"):
        obs.update(meas, M_H * GRAVITY, np.zeros(3), 0.01)
    obs.reset(meas)
    with pytest.raises(ValueError, match="specific_force"):
        obs.update({k: v for k, v in meas.items() if k != "specific_force"}, M_H * GRAVITY, np.zeros(3), 0.01)
    with pytest.raises(ValueError, match="dt"):
        obs.update(meas, M_H * GRAVITY, np.zeros(3), 0.0)
    bad = dict(meas, velocity=np.array([[np.nan, 0, 0]]))
    with pytest.raises(ValueError, match="velocity"):
        obs.update(bad, M_H * GRAVITY, np.zeros(3), 0.01)
    with pytest.raises(ValueError, match="shipped gains"):
        QBObserver(M_H, J_H, gain_file="no_such_gain")
    with pytest.warns(UserWarning, match="design for this vehicle"):
        QBObserver(2.0, [0.02, 0.02, 0.04])


def test_fig7_mu_claim_shortened(gains):
    """Shortened Fig. 7 (first 12 s of the Fig. 3 signal): mu = 0.95 converges slower than mu = 0.2
    but to a smaller error region (paper Sec. 4, last paragraph)."""
    settle, rms = {}, {}
    for key in ("0p2", "0p95"):
        clean = rq.simulate_fig7(gains[key], t_end=9.0, noise=False)
        noisy = rq.simulate_fig7(gains[key], t_end=12.0, noise=True, seed=3)
        settle[key] = rq.settling_time(clean)
        rms[key] = rq.error_region(noisy, 9.5, 11.0)["rms"]
    assert 0 < settle["0p2"] < settle["0p95"] < 3.0, settle
    assert rms["0p95"] < 0.7 * rms["0p2"], rms


def test_fig3_disturbance_shape():
    t = np.array([0.0, 5.0, 8.5, 12.0, 25.0, 27.5, 40.0, 45.0])
    np.testing.assert_allclose(rq.fig3_disturbance(t), [0, 1.0, 2.0, 0.5, 2.0, 1.0, 2.0, 0.0])


@pytest.mark.long
def test_full_reproduction(tmp_path):
    s = rq.run(tmp_path, quick=False)
    assert all(s["claims"].values()), s["claims"]
    for name in ("qb_fig4_volume.csv", "qb_fig5_jmu.csv", "qb_fig6_mu.csv", "qb_fig7_estimation.csv",
                 "qb_summary.md", "qb_fig4.png", "qb_fig7.png"):
        assert (tmp_path / name).is_file()
    assert s["max_rel_lmi7"] < 1e-6 and s["max_decay_margin"] <= 0
    # what the table shows is said: the mu = 0.2 design at alpha = 20, the sweep's edge; its guaranteed |e_dx| bound
    # (5.5-5.8 N) above the 2 N signal; the trivial estimate beside the noisy error (median of 5 seeds)
    text = (tmp_path / "qb_summary.md").read_text()
    assert "mu = 0.2 design has alpha = 20, at the upper edge of the sweep" in text
    assert s["ellipsoid_dx"][0.2] > s["trivial"]["max_d"] and "certifies nothing" in text
    assert s["region"][0.2]["n_seeds"] == 5 and s["region"][0.95]["rms"] < s["trivial"]["rms_d"]


def test_runs_in_the_hover_env_with_its_measurement_and_applied_inputs():
    """Batch-first use at the env's control rate: info['measurement'] and info['applied'] as given by
    fawtgym/Hover-v0 (ENV_API.md), constant external wrench plus the env's own aero forces."""
    gym = pytest.importorskip("gymnasium")
    import fawtgym  # noqa: F401  (registers the env ids)

    if "fawtgym/Hover-v0" not in gym.registry:
        pytest.skip("hover env not registered in this build")
    env = gym.make("fawtgym/Hover-v0", vehicle="hummingbird", wind="calm", init_noise=0.0, sensors="none")
    _, info = env.reset(seed=0)
    u = env.unwrapped
    u.set_external_wrench(np.array([0.3, -0.2, 0.1]), np.array([0.005, -0.004, 0.002]))
    obs = make_observer("qb", u.preset.mass, u.preset.inertia_matrix)
    obs.reset(info["measurement"], thrust=u.preset.mass * GRAVITY)
    a = u.hover_action()
    for _ in range(150):
        _, _, term, trunc, info = env.step(a)
        assert not (term or trunc), info.get("failure")
        est = obs.update(info["measurement"], info["applied"]["thrust"], info["applied"]["torque"], u.dt)
    f_true, t_true = np.asarray(info["truth"]["force"]), np.asarray(info["truth"]["torque"])
    assert np.linalg.norm(est.force[0] - f_true) < 0.1 * np.linalg.norm(f_true) + 0.02, (est.force, f_true)
    np.testing.assert_allclose(est.torque[0], t_true, atol=5e-4)
    env.close()


@pytest.mark.long
def test_design_for_another_preset(tmp_path):
    path = rq.design_for("s500", 0.5, tmp_path, quick=True)
    g = load_gain(path)
    assert g.meta["vehicle"] == "s500" and g.meta["mass"] == 1.0 and g.mu == 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # designed for this vehicle: no mass-mismatch warning
        obs = make_observer("qb", 1.0, [0.03, 0.03, 0.06], gain_file=path)
    obs.reset(_hover_meas(2, np.random.default_rng(0)))
    assert obs.update(_hover_meas(2, np.random.default_rng(1)), 9.8, np.zeros(3), 0.01).force.shape == (2, 3)


@pytest.mark.parametrize("n", [1, 3])
def test_reset_thrust_of_the_wrong_shape_is_a_clear_error(n):
    """A reset thrust of the wrong shape names the shape (it used to be a numpy broadcast error); the same
    exception type and text, sizes apart, at every N."""
    from fawtgym.eval.bench.observers import hover_measurement

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        obs = make_observer("qb", 1.5, [0.03, 0.03, 0.05])
    meas = hover_measurement(n, np.random.default_rng(0))
    with pytest.raises(ValueError, match=rf"^qb: reset thrust must be a finite real number \(every row\) or shape "
                                         rf"\(N,\) with N = {n} \(one per row\), got shape \({n + 1},\)$"):
        obs.reset(meas, thrust=np.ones(n + 1))
    with pytest.raises(TypeError, match="unknown reset options"):
        obs.reset(meas, thrust_typo=1.0)
