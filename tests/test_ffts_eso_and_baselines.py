"""FFTS-ESO (seed-000 Props. 1-2) and the LESO / FxTSDO / STO baselines behind the observer interface."""

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.core.frames import euler_to_rot
from fawtgym.core.so3 import exp_so3, hat, orthogonality_error
from fawtgym.observers import make_observer, observer_names
from fawtgym.observers.ffts_eso import FFTSESO, morse, s_k, s_k_rate
from fawtgym.observers.hc_ffts import frac_power, frac_power_rate, phi1, phi2

MASS = 4.34
J = np.diag([0.0820, 0.0845, 0.1377])
G = 9.80665
E3 = np.array([0.0, 0.0, 1.0])
OURS = ("ffts_eso", "leso", "fxtsdo", "sto")
RNG = np.random.default_rng(11)


def _rigid_body(n, steps, h, phi, tau_d, seed=0, amp=1.0):
    """Noise-free trajectories of eq. (38) under smooth random inputs; yields (meas, f, tau) per step."""
    rng = np.random.default_rng(seed)
    b = rng.standard_normal((n, 3))
    v = rng.standard_normal((n, 3))
    r = exp_so3(rng.standard_normal((n, 3)) * 0.5)
    w = rng.standard_normal((n, 3)) * 0.5
    freq = rng.uniform(0.3, 2.0, (n, 4))
    for k in range(steps):
        t = k * h
        meas = {"position": b.copy(), "velocity": v.copy(), "attitude": r.copy(), "angular_velocity": w.copy()}
        f = MASS * G + amp * 5.0 * np.sin(freq[:, 0] * t)
        tau = amp * 0.05 * np.sin(freq[:, 1:] * t + np.arange(3))
        yield meas, f, tau
        acc = G * E3 - (f / MASS)[:, None] * r[:, :, 2] + phi / MASS
        wdot = (np.cross(w @ J.T, w) + tau + tau_d) @ np.linalg.inv(J).T
        b, v = b + h * v + 0.5 * h * h * acc, v + h * acc
        r = r @ exp_so3(h * w + 0.5 * h * h * wdot)
        w = w + h * wdot


def test_registry_builds_every_observer_with_defaults():
    for name in OURS:
        assert name in observer_names()
    for name in observer_names():   # every registered observer must be constructible with (m, J) only
        obs = make_observer(name, MASS, J)
        assert obs.name == name


@pytest.mark.parametrize("name", OURS)
@pytest.mark.parametrize("n", [1, 3])
def test_update_shapes_and_finite(name, n):
    obs = make_observer(name, MASS, J)
    gen = _rigid_body(n, 20, 1e-3, np.zeros(3), np.zeros(3))
    meas, _, _ = next(gen)
    obs.reset(meas)
    for meas, f, tau in gen:
        est = obs.update(meas, f, tau, 1e-3)
    assert est.force.shape == (n, 3) and est.torque.shape == (n, 3)
    assert np.all(np.isfinite(est.force)) and np.all(np.isfinite(est.torque))


@pytest.mark.parametrize("name", OURS)
def test_batch_equals_separate_runs(name):
    n, steps, h = 4, 300, 1e-3
    phi = RNG.standard_normal((n, 3))
    tau_d = 0.1 * RNG.standard_normal((n, 3))
    data = list(_rigid_body(n, steps, h, phi, tau_d, seed=5))
    batch = make_observer(name, MASS, J)
    batch.reset(data[0][0])
    singles = [make_observer(name, MASS, J) for _ in range(n)]
    for i, o in enumerate(singles):
        o.reset({k: v[i] for k, v in data[0][0].items()})
    got, want = [], []
    for meas, f, tau in data:
        eb = batch.update(meas, f, tau, h)
        want.append((eb.force, eb.torque))
        es = [o.update({k: v[i] for k, v in meas.items()}, f[i:i + 1], tau[i], h) for i, o in enumerate(singles)]
        got.append((np.concatenate([e.force for e in es]), np.concatenate([e.torque for e in es])))
    # one kernel, looped over rows: a batch of N is N separate runs, bitwise (tests/_tolerance.py, policy 1)
    np.testing.assert_array_equal(np.array(got), np.array(want))


def test_s_k_closed_forms_match_eqs_41_66_and_lemma5():
    k = np.array([1.4, 1.2, 1.0])
    e = np.eye(3)
    for _ in range(20):
        r = exp_so3(RNG.standard_normal(3) * 1.5)
        w = RNG.standard_normal(3)
        s_def = sum(k[i] * np.cross(r.T @ e[i], e[i]) for i in range(3))
        # closed forms vs the sums: two implementations of one law, at the scale of the summed terms
        assert_same_law(s_k(r, k), s_def, scale=k.sum(), what="s_K")
        rate_def = sum(k[i] * np.cross(e[i], np.cross(w, r.T @ e[i])) for i in range(3))
        assert_same_law(s_k_rate(r, w, k), rate_def, scale=k.sum() * np.abs(w).sum(), what="s_K rate")
        h = 1e-6   # eq. (66) is d/dt s_K(E) along E' = E w^; Lemma 5: d/dt <K, I - R> = w . s_K(R)
        np.testing.assert_allclose((s_k(r @ exp_so3(h * w), k) - s_k(r @ exp_so3(-h * w), k)) / (2 * h),
                                   s_k_rate(r, w, k), atol=1e-8)
        assert np.isclose((morse(r @ exp_so3(h * w), k) - morse(r @ exp_so3(-h * w), k)) / (2 * h),
                          w @ s_k(r, k), atol=1e-8)
    for crit in (np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])):
        np.testing.assert_allclose(s_k(crit, k), 0.0, atol=1e-15)   # critical set C of eq. (44)


def test_ffts_eso_step_matches_the_paper_equations():
    """One update equals eqs. (49)/(68) written with the hc_ffts building blocks, advanced as documented
    (b, v, phi, Omega, tau by Euler, b and R_hat exactly for the held derivatives)."""
    obs = FFTSESO(MASS, J)
    n, dt = 5, 2e-3
    start = {"position": RNG.standard_normal((n, 3)), "velocity": RNG.standard_normal((n, 3)),
             "attitude": exp_so3(RNG.standard_normal((n, 3))), "angular_velocity": RNG.standard_normal((n, 3))}
    phi0, tau0 = RNG.standard_normal((n, 3)), RNG.standard_normal((n, 3))
    obs.reset(start, phi0, tau0)
    m = {"position": start["position"] + 0.1 * RNG.standard_normal((n, 3)), "velocity": RNG.standard_normal((n, 3)),
         "attitude": exp_so3(RNG.standard_normal((n, 3))), "angular_velocity": RNG.standard_normal((n, 3))}
    m["position"][0] = start["position"][0]           # one row with e_b = 0 exactly
    f, tau = RNG.uniform(30, 50, n), RNG.standard_normal((n, 3))
    est = obs.update(m, f, tau, dt)
    eps_t, eps_a = obs.eps_at(dt)
    p, kt, ka = 1.2, 0.8, 0.6
    e_b, e_v = m["position"] - start["position"], m["velocity"] - start["velocity"]
    psi = e_v + kt * (e_b + frac_power(e_b, p, eps_t))
    v_dot = (G * E3 - (f / MASS)[:, None] * m["attitude"][:, :, 2] + 3 * phi1(psi, 6, p)
             + kt * (frac_power_rate(e_b, e_v, p, eps_t) + e_v) + phi0 / MASS)
    # the kernel and the paper's equations from the building blocks: two implementations of one law
    # (tests/_tolerance.py), at the scale of their largest term (G, f/m) times the step
    assert_same_law(est.states["velocity"], start["velocity"] + dt * v_dot, scale=np.abs(f).max() / MASS, what="v")
    assert_same_law(est.states["position"], start["position"] + dt * start["velocity"] + 0.5 * dt * dt * v_dot,
                    scale=np.abs(start["position"]).max(), what="b")
    assert_same_law(est.force, phi0 + dt * MASS * 2 * phi2(psi, 6, p), scale=np.abs(phi0).max(), what="phi")
    kk = np.array([1.2, 1.1, 1.0])
    for i in range(n):
        r_hat, w_hat = start["attitude"][i], start["angular_velocity"][i]
        er_m = r_hat.T @ m["attitude"][i]
        e_om = m["angular_velocity"][i] - er_m.T @ w_hat
        e_r = s_k(er_m, kk)
        e_w = s_k_rate(er_m, e_om, kk)
        psi_a = e_om + ka * (e_r + frac_power(e_r, p, eps_a))
        om = m["angular_velocity"][i]
        inner = (np.cross(J @ om, om) + tau0[i] + tau[i] + 3 * J @ phi1(psi_a, 4, p)
                 + ka * J @ frac_power_rate(e_r, e_w, p, eps_a))
        w_dot = er_m @ np.linalg.solve(J, inner) + er_m @ np.linalg.solve(J, ka * J @ e_w) \
            + er_m @ hat(e_om) @ er_m.T @ w_hat
        # J^-1 of the inner terms: scale |J^-1| |inner|
        assert_same_law(est.states["angular_velocity"][i], w_hat + dt * w_dot,
                        scale=np.abs(inner).max() / J.min(where=J > 0, initial=1.0), what=f"Omega row {i}")
        assert_same_law(est.torque[i], tau0[i] + dt * J @ (2 * phi2(psi_a, 4, p)), scale=np.abs(tau0).max(),
                        what=f"tau row {i}")
        assert_same_law(est.states["attitude"][i], r_hat @ exp_so3(dt * (w_hat + 0.5 * dt * w_dot)),
                        scale=1.0, what=f"R row {i}")


def test_ffts_eso_converges_to_constant_disturbances():
    """Noise-free, constant phi_D / tau_D (Theorems 2-3): estimates converge; R_hat stays on SO(3)."""
    n, h = 3, 1e-3
    phi = np.array([[3.0, 4.0, -5.0], [5.0, -3.0, 4.0], [-2.0, 1.0, 0.5]])
    tau_d = np.array([[-0.3, 0.2, 0.2], [0.2, -0.3, -0.2], [0.05, 0.1, -0.1]])
    obs = make_observer("ffts_eso", MASS, J)
    gen = _rigid_body(n, 4000, h, phi, tau_d, seed=2)
    meas, _, _ = next(gen)
    obs.reset(meas)
    for meas, f, tau in gen:
        est = obs.update(meas, f, tau, h)
    assert np.max(np.abs(est.force - phi)) < 1e-3
    assert np.max(np.abs(est.torque - tau_d)) < 1e-4
    assert np.max(orthogonality_error(est.states["attitude"])) < 1e-12


def test_ffts_eso_zero_error_update_is_exact_and_quiet():
    """At e = 0 (reset from the measurement) with matching disturbances the update stays finite, no FP warning."""
    obs = make_observer("ffts_eso", MASS, J)
    meas = {"position": np.zeros(3), "velocity": np.zeros(3), "attitude": np.eye(3), "angular_velocity": np.zeros(3)}
    obs.reset(meas)
    with np.errstate(all="raise"):
        est = obs.update(meas, MASS * G, np.zeros(3), 1e-3)
    np.testing.assert_allclose(est.force, 0.0, atol=1e-12)
    np.testing.assert_allclose(est.torque, 0.0, atol=1e-12)


@pytest.mark.parametrize("kwargs,match", [
    ({"p": 1.0}, "open interval"), ({"p": 2.5}, "open interval"),
    ({"kappa_t": 0.5}, r"kappa_t must be a finite real number in \(0.5, "),
    ({"kappa_a": 0.2}, r"kappa_a must be a finite real number in \(0.5, "),
    ({"kt1": -3.0}, "A_t"), ({"ka2": 0.0}, "A_a"),
    ({"kt3": 0.0}, "kt3"), ({"morse_k": (1.0, 1.0, 1.0)}, "K1 > K2 > K3 >= 1"),
    ({"morse_k": (1.2, 1.1, 0.9)}, "K1 > K2 > K3 >= 1"),
])
def test_ffts_eso_gain_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_observer("ffts_eso", MASS, J, **kwargs)


@pytest.mark.parametrize("name", OURS)
def test_bad_use_raises(name):
    obs = make_observer(name, MASS, J)
    meas = {"position": np.zeros((2, 3)), "velocity": np.zeros((2, 3)), "attitude": np.tile(np.eye(3), (2, 1, 1)),
            "angular_velocity": np.zeros((2, 3))}
    with pytest.raises(RuntimeError, match="reset"):
        obs.update(meas, np.zeros(2), np.zeros((2, 3)), 1e-3)
    obs.reset(meas)
    with pytest.raises(ValueError, match="dt"):
        obs.update(meas, np.zeros(2), np.zeros((2, 3)), 0.0)
    bad = dict(meas, velocity=np.full((2, 3), np.nan))
    with pytest.raises(ValueError, match="non-finite"):
        obs.update(bad, np.zeros(2), np.zeros((2, 3)), 1e-3)
    with pytest.raises(ValueError, match="batch size|thrust"):
        obs.update({k: v[:1] for k, v in meas.items()}, np.zeros(1), np.zeros((1, 3)), 1e-3)
    with pytest.raises(ValueError, match="attitude"):
        obs.update({k: v for k, v in meas.items() if k != "attitude"}, np.zeros(2), np.zeros((2, 3)), 1e-3)


def test_leso_breaks_through_90_deg_pitch_while_ffts_eso_does_not():
    """A pitch-up through 90 deg (Z-Y-X singularity) wrecks LESO's torque estimate; FFTS-ESO is unaffected."""
    h = 1e-3
    obs = {k: make_observer(k, MASS, J) for k in ("ffts_eso", "leso")}
    rate = 2.0                     # rad/s pitch rate about body y, from 30 deg to 150 deg of pitch
    r0 = euler_to_rot(0.0, np.radians(30), 0.0)
    w = np.array([0.0, rate, 0.0])
    tau_cmd = np.cross(w, J @ w)  # torque that keeps the body rate constant (J w' = J w x w + tau = 0)
    worst = {k: 0.0 for k in obs}
    for k in range(int(np.radians(120) / rate / h)):
        r = r0 @ exp_so3(k * h * w)
        meas = {"position": np.zeros(3), "velocity": np.zeros(3), "attitude": r, "angular_velocity": w}
        for name, o in obs.items():
            if k == 0:
                o.reset(meas)
            est = o.update(meas, MASS * G, tau_cmd, h)
            worst[name] = max(worst[name], float(np.linalg.norm(est.torque)))
    assert worst["ffts_eso"] < 1e-6      # no disturbance, none estimated
    assert worst["leso"] > 0.1           # Euler angles jump by pi at 90 deg: a spurious torque of > 0.1 N m



def test_leso_max_dt_is_half_the_euler_stability_limit():
    """The LESO step (Gao's axis law, z1 chain exact) is linear in (z1, z2, z3); its error map's spectral radius
    crosses 1 at omega0 dt = 2/3, and max_dt = 1 / (3 omega0) is half of that."""
    from fawtgym.observers.leso import leso_axis

    def radius(w0, dt):
        b1, b2, b3 = 3 * w0, 3 * w0**2, w0**3
        cols = [leso_axis(*z, 0.0, 0.0, b1, b2, b3, dt) for z in np.eye(3)]   # y = u = 0: the map's columns
        return np.max(np.abs(np.linalg.eigvals(np.array(cols).T)))

    for w0 in (2.0, 10.0, 40.0):
        assert radius(w0, 0.99 * (2 / 3) / w0) < 1.0 < radius(w0, 1.01 * (2 / 3) / w0)
    obs = make_observer("leso", MASS, J, omega_t=10.0, omega_a=20.0)
    assert obs.max_dt == pytest.approx(1 / 60)
    assert radius(20.0, obs.max_dt) < 0.9
