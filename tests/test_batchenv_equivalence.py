"""HoverBatchEnv rows reproduce HoverEnv (the reference semantics) trajectory by trajectory.

Row ``i`` of ``HoverBatchEnv.reset(seed=s)`` uses the generator of ``HoverEnv.reset(seed=s + i)``; with
calm or deterministic wind and exact sensors every row must match its single env to rounding, through
autoresets (NEXT_STEP: the step after a termination/truncation returns the reset with reward 0): two
implementations of one law, compared with the policy of tests/_tolerance.py.
"""

import numpy as np
import pytest
from _tolerance import same_law_tol

from fawtgym.core.frames import FAWT_ORIGIN_NED, R_FAWT_TO_NED
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.wind.fawt import SHEAR_TI, fawt_profile


def _ratio(x, ref, steps):
    """|x - ref| over the tolerance for two implementations of one law after ``steps`` physics steps
    (tests/_tolerance.py), at the quantity's own scale; SI quantities, so at least 1 (m, m/s, rad, N: the order
    of the states in these runs); <= 1 passes."""
    x, ref = np.asarray(x, dtype=float), np.asarray(ref, dtype=float)
    return float(np.abs(x - ref).max() / same_law_tol(max(1.0, np.abs(ref).max()), steps))


def _compare(kw, n, seed, actions, wrench=None):
    """Run the batch env and n single envs on the same actions; return the largest difference seen, as a fraction
    of the policy's tolerance (see :func:`_ratio`), and the failures."""
    batch = HoverBatchEnv(n, **kw)
    obs_b, info_b = batch.reset(seed=seed)
    if wrench is not None:
        batch.set_external_wrench(*wrench)
    singles = [HoverEnv(**kw) for _ in range(n)]
    outs = [e.reset(seed=seed + i) for i, e in enumerate(singles)]
    if wrench is not None:
        for i, e in enumerate(singles):
            e.set_external_wrench(wrench[0][i], wrench[1][i])
    worst = max(_ratio(outs[i][0], obs_b[i], 1) for i in range(n))
    done = np.zeros(n, dtype=bool)
    failures = []
    for k, a in enumerate(actions):
        steps = (k + 1) * batch.n_substeps
        obs_b, rew_b, term_b, trunc_b, info_b = batch.step(a)
        for i, e in enumerate(singles):
            if done[i]:
                obs, info = e.reset()
                rew, term, trunc = 0.0, False, False
            else:
                obs, rew, term, trunc, info = e.step(a[i])
            assert term == term_b[i] and trunc == trunc_b[i]
            assert info["failure"] == info_b["failure"][i]
            assert info["action_clipped"] == info_b["action_clipped"][i]
            assert info["time"] == pytest.approx(info_b["time"][i], abs=1e-12)
            d = max(_ratio(obs, obs_b[i], steps), _ratio(rew, rew_b[i], steps))
            d = max(d, _ratio(info["setpoint"], info_b["setpoint"][i], steps))
            for part in ("truth", "applied", "measurement"):
                assert set(info[part]) == set(info_b[part])
                for key, val in info[part].items():
                    d = max(d, _ratio(val, info_b[part][key][i], steps))
            worst = max(worst, d)
            if info["failure"]:
                failures.append((i, info["failure"]))
        done = term_b | trunc_b
    return worst, failures


def _varied_actions(n, steps, seed=1):
    rng = np.random.default_rng(seed)
    a = 0.3 + 0.08 * rng.standard_normal((steps, n, 4))
    a[::7] += 0.5  # some entries above 1: clipped and flagged
    return a.astype(np.float32)


@pytest.mark.parametrize("init_noise", [0.0, 1.0])
def test_rows_match_hover_env_calm_exact_sensors(init_noise):
    kw = dict(wind="calm", sensors="none", init_noise=init_noise, episode_seconds=0.3)
    worst, _ = _compare(kw, 3, 10, _varied_actions(3, 45))  # 30-step episodes: an autoreset on the way
    assert worst <= 1.0


def _ctbr_actions(n, steps, seed=0):
    rng = np.random.default_rng(seed)
    a = np.empty((steps, n, 4))
    a[..., 0] = 0.27 + 0.05 * rng.standard_normal((steps, n))
    a[..., 1:] = 0.2 * rng.standard_normal((steps, n, 3))
    a[::9, :, 1] = 1.4  # clipped
    return a.astype(np.float32)


def test_ctbr_rows_match_hover_env():
    # the inner rate loop at the physics rate: one single-substep rollout per substep
    kw = dict(wind="calm", sensors="none", init_noise=1.0, episode_seconds=0.3, action_type="ctbr")
    worst, _ = _compare(kw, 3, 5, _ctbr_actions(3, 45))
    assert worst <= 1.0
    kw.update(wind="fawt-50", sensors="mocap_imu", control_rate=200.0)
    worst, _ = _compare(kw, 1, 5, _ctbr_actions(1, 30))
    assert worst <= 1.0


def test_single_row_matches_hover_env_in_fawt_wind_with_noisy_sensors():
    # N = 1: the row's own wind and sensor streams are the single env's
    kw = dict(wind="fawt-50", sensors="mocap_imu", init_noise=1.0, episode_seconds=0.2, control_rate=200.0)
    worst, _ = _compare(kw, 1, 4, _varied_actions(1, 50))
    assert worst <= 1.0


def test_rows_reset_at_different_times_in_time_varying_wind():
    # a gust that starts at t = 0.2 s (wind depends on episode time): rows reset at different steps run in
    # cohorts with their own episode times; row 1 falls (zero thrust) and restarts before the others
    kw = dict(wind={"name": "gust-1cos", "start_time": 0.2, "amplitude": 4.0, "length": 2.0}, sensors="none",
              init_noise=0.5, episode_seconds=0.8, setpoint=(0.0, 0.0, -0.4))
    n, steps = 3, 100
    a = _varied_actions(n, steps)
    a[:30, 1] = 0.0
    worst, failures = _compare(kw, n, 7, a)
    assert (1, "ground_contact") in failures
    assert worst <= 1.0


def test_diverged_row_matches_hover_env():
    kw = dict(wind="calm", sensors="none", init_noise=0.0)
    force = np.zeros((2, 3))
    force[1] = 1e308
    worst, failures = _compare(kw, 2, 0, _varied_actions(2, 4), wrench=(force, np.zeros((2, 3))))
    assert failures and set(failures) == {(1, "diverged")}  # the wrench persists over resets
    assert worst <= 1.0


def test_fawt_wind_and_sensor_statistics_across_rows():
    """N > 1 rows draw their own wind and noise streams: compare their statistics with the model's."""
    n = 256
    env = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu", init_noise=0.0, control_rate=100.0)
    obs, info = env.reset(seed=0)
    sp = env.setpoint[0]
    wind0 = info["truth"]["wind"]
    # at reset every row's gust filter is a draw from the stationary distribution
    factor, shear = fawt_profile(((sp - FAWT_ORIGIN_NED) @ R_FAWT_TO_NED)[None, None])
    w = env.wind.model
    u = w.mean_speed * factor[0, 0]
    sigma = np.sqrt((w.ti * u) ** 2 + (SHEAR_TI * w.mean_speed) ** 2 * shear[0, 0])
    assert wind0[:, 0].mean() == pytest.approx(u, abs=4 * sigma / np.sqrt(n))
    assert wind0[:, 0].std() == pytest.approx(sigma, rel=0.15)
    assert wind0[:, 1].std() == pytest.approx(sigma, rel=0.15)
    # sensor noise (pose hold at 100 Hz = every step here) and per-row turn-on gyro biases
    pos_err, gyro_err = [], []
    hover = env.hover_action()
    for _ in range(10):
        obs, rew, term, trunc, info = env.step(hover)
        m, t = info["measurement"], info["truth"]
        pos_err.append(m["position"] - t["position"])
        gyro_err.append(m["gyro"] - t["angular_velocity"])
    assert not term.any()
    spec = env.sensor
    pos_err, gyro_err = np.array(pos_err), np.array(gyro_err)
    assert pos_err.std() == pytest.approx(spec.sig_pos, rel=0.1)
    bias = gyro_err.mean(axis=0)  # (n, 3): per-row turn-on bias + averaged noise
    assert bias.std() == pytest.approx(np.hypot(0.003, spec.sig_gyro / np.sqrt(10)), rel=0.15)
    assert np.allclose(bias, env.sensor.gyro_bias, atol=5 * spec.sig_gyro / np.sqrt(10))
    # rows are independent: row-to-row correlation of the gust series is small
    series = []
    for _ in range(20):
        *_, info = env.step(hover)
        series.append(info["truth"]["wind"][:, 0])
    c = np.corrcoef(np.array(series).T)
    assert np.abs(c[np.triu_indices(n, 1)]).mean() < 0.35
