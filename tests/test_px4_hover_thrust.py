"""PX4's hover-thrust EKF (ZeroOrderHoverThrustEkf + module logic) and the PositionControl version differences."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from _tolerance import assert_same_law

import fawtgym  # noqa: F401  (registers the env)
from fawtgym.agents.px4_agent import PX4Agent
from fawtgym.agents.px4_hover_thrust import HoverThrustEstimator
from fawtgym.agents.px4_params import PX4Params
from fawtgym.agents.px4_position_control import PositionControl
from fawtgym.core.constants import GRAVITY

DT = 0.01  # s, the position loop / local-position rate
Z3 = np.zeros((1, 3))


def _run(hte: HoverThrustEstimator, th_true, seconds: float, thrust: float = 0.3, vel=None, noise: float = 0.5,
         seed: int = 0):
    """Feed ``a_z = g T / Th_true - g + noise`` for ``seconds``; return the estimate and validity traces."""
    rng = np.random.default_rng(seed)
    th_true = np.atleast_1d(np.asarray(th_true, dtype=float))
    n = th_true.size
    vel = np.zeros((n, 3)) if vel is None else np.broadcast_to(vel, (n, 3))
    est, valid = [], []
    for _ in range(int(round(seconds / DT))):
        acc = GRAVITY * thrust / th_true - GRAVITY + noise * rng.standard_normal(n)
        est.append(hte.update(acc, np.full(n, thrust), vel, DT).copy())
        valid.append(hte.valid.copy())
    return np.array(est), np.array(valid)


def test_converges_and_becomes_valid_after_two_seconds_of_low_variance() -> None:
    hte = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.3)
    est, valid = _run(hte, 0.35, 20.0)
    assert abs(est[-1, 0] - 0.35) < 0.005
    assert not valid[0, 0]
    hte2 = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.3)
    variances = []
    for _ in range(2000):
        hte2.update(np.array([GRAVITY * 0.3 / 0.35 - GRAVITY]), np.array([0.3]), Z3, DT)
        variances.append(hte2.var[0])
        if hte2.valid[0]:
            break
    k = len(variances) - 1
    first_low = int(np.argmax(np.array(variances) < 1e-3))
    # valid exactly when the variance has stayed below 1e-3 for 2 s (PX4's hysteresis), not before
    assert (k - first_low + 1) * DT == pytest.approx(2.0, abs=1.5 * DT)


def test_noise_is_inflated_above_the_velocity_thresholds_not_stopped() -> None:
    fast, slow = (HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.3) for _ in range(2))
    acc = np.array([GRAVITY * 0.3 / 0.4 - GRAVITY])
    slow.update(acc, np.array([0.3]), Z3, DT)
    fast.update(acc, np.array([0.3]), np.array([[0.0, 0.0, 5.0]]), DT)  # |v_z| 5 > HTE_VZ_THR 2: noise x4
    d_slow, d_fast = slow.hover_thrust[0] - 0.3, fast.hover_thrust[0] - 0.3
    assert d_slow > d_fast > 0.0  # still fused, with less weight
    # gain ratio from the Kalman gain with R and 4 R (P and H equal): (HPH + 4R) / (HPH + R)
    h = -GRAVITY * 0.3 / 0.09
    p = 0.1**2 + 0.0036**2 * DT**2
    assert d_slow / d_fast == pytest.approx((h * p * h + 4 * 5.0) / (h * p * h + 5.0), rel=1e-9)


def test_bounds_are_mpc_thr_hover_plus_minus_range() -> None:
    hte = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.275)
    assert (hte.min_hover_thrust, hte.max_hover_thrust) == pytest.approx((0.075, 0.475))
    est, _ = _run(hte, 0.7, 30.0, thrust=0.6)
    assert est.max() == pytest.approx(0.475)
    hte = HoverThrustEstimator(PX4Params.s500(HTE_THR_RANGE=0.4), hover_thrust=0.6)
    assert (hte.min_hover_thrust, hte.max_hover_thrust) == pytest.approx((0.2, 0.9))


def test_variance_recovery_after_a_hover_thrust_jump() -> None:
    """A jump 0.3 -> 0.55 fails the 3-sigma gate every step; only the variance bump lets the EKF follow."""
    final = {}
    for bump in (1e3, 0.0):
        hte = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.4)
        assert hte.variance_bump == 1e3  # PX4's value by default
        hte.variance_bump = bump
        _run(hte, 0.3, 20.0, noise=0.3)
        assert abs(hte.hover_thrust[0] - 0.3) < 0.01
        est, _ = _run(hte, 0.55, 20.0, noise=0.3, seed=1)
        final[bump] = est[-1, 0]
    assert abs(final[0.0] - 0.3) < 0.03  # without recovery: stuck near the old value
    assert final[1e3] > 0.45  # with PX4's recovery: most of the way to 0.55 within 20 s


def test_innovation_variance_never_below_measurement_noise() -> None:
    hte = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.3)
    hte.update(np.array([1.0]), np.array([0.0]), Z3, DT)  # zero thrust: H = 0, S = R, K = 0
    assert hte.hover_thrust[0] == pytest.approx(0.3)
    assert hte.test_ratio[0] == pytest.approx((1.0 + GRAVITY) ** 2 / (9.0 * 5.0))  # S = R: innovation vs R alone


def test_batch_rows_equal_single_runs_and_row_mask() -> None:
    th = np.array([0.3, 0.35, 0.4])
    batch = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.3)
    batch.reset(3)
    est_b, _ = _run(batch, th, 5.0, noise=0.0)
    for i, t in enumerate(th):
        one = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.3)
        est_1, _ = _run(one, t, 5.0, noise=0.0)
        assert_same_law(est_b[:, i], est_1[:, 0], steps=est_1.shape[0], what=f"row {i}")
    before = batch.hover_thrust.copy()
    acc = np.full(3, GRAVITY * 0.3 / 0.33 - GRAVITY)
    batch.update(acc, np.full(3, 0.3), np.zeros((3, 3)), DT, rows=np.array([False, True, False]))
    assert batch.hover_thrust[0] == before[0] and batch.hover_thrust[2] == before[2]
    assert batch.hover_thrust[1] != before[1]


def test_non_finite_measurement_is_not_fused_and_bad_input_errors() -> None:
    hte = HoverThrustEstimator(PX4Params.s500(), hover_thrust=0.3)
    hte.update(np.array([np.nan]), np.array([0.3]), Z3, DT)
    assert hte.hover_thrust[0] == pytest.approx(0.3) and np.isfinite(hte.var[0])
    with pytest.raises(ValueError, match="dt"):
        hte.update(np.array([0.0]), np.array([0.3]), Z3, 0.0)
    with pytest.raises(ValueError, match="hover_thrust"):
        HoverThrustEstimator(hover_thrust=1.2)


# ---- PositionControl: v1.13.2 (the paper's) and v1.14 ------------------------------------------------
def test_vertical_integrator_clamp_after_versus_before() -> None:
    """A hover-thrust shift while i_z sits at -g: v1.13 uses the shifted i_z once, v1.14 clamps it first."""
    out = {}
    for version in ("1.13", "1.14"):
        pc = PositionControl(PX4Params(), hover_thrust=0.5, px4_version=version)
        pc.reset(1)
        pc.vel_int[:, 2] = -GRAVITY
        pc.acc_sp[:, 2] = -GRAVITY
        pc.update_hover_thrust(np.array([0.4]))
        shifted = pc.vel_int[0, 2]
        pc.update(Z3, Z3, Z3, Z3, dt=DT)
        out[version] = (shifted, pc.acc_sp[0, 2], pc.vel_int[0, 2])
    shifted, acc13, int13 = out["1.13"]
    assert shifted == pytest.approx(-1.5 * GRAVITY)  # (a - g) Th / Th' + g - a with a = -g, Th 0.5 -> 0.4
    assert acc13 == pytest.approx(shifted)  # v1.13: the unclamped integrator is used this step ...
    assert int13 == pytest.approx(-GRAVITY)  # ... and clamped after integrating
    _, acc14, int14 = out["1.14"]
    assert acc14 == pytest.approx(-GRAVITY) and int14 == pytest.approx(-GRAVITY)


def test_hover_thrust_constrained_and_shift_per_version() -> None:
    for version, bounds in (("1.13", (0.1, 0.9)), ("1.14", (0.05, 0.9))):
        pc = PositionControl(PX4Params(), hover_thrust=0.5, px4_version=version)
        pc.reset(1)
        pc.acc_sp[:, 2] = 1.0
        thrust_before = pc.acc_sp[0, 2] * 0.5 / GRAVITY - 0.5
        pc.update_hover_thrust(np.array([0.02]))
        assert pc.hover_thrust[0] == pytest.approx(bounds[0])
        a_new = pc.acc_sp[0, 2] + pc.vel_int[0, 2]
        thrust_after = a_new * pc.hover_thrust[0] / GRAVITY - pc.hover_thrust[0]
        if version == "1.14":  # consistent: the thrust is continuous
            assert thrust_after == pytest.approx(thrust_before, rel=1e-12)
        else:  # v1.13.2 shifts by the unclamped value (PX4 PR #21372): a thrust jump
            assert abs(thrust_after - thrust_before) > 0.1
        pc.update_hover_thrust(np.array([0.97]))
        assert pc.hover_thrust[0] == pytest.approx(0.9)
    with pytest.raises(ValueError, match="px4_version"):
        PositionControl(px4_version="1.12")


@pytest.mark.parametrize("duty", [50])
def test_fawt_hover_keeps_the_version_differences_dormant(duty: int) -> None:
    """In FAWT wind the integrator stays well inside +-g and the estimate inside [0.1, 0.9], so the
    v1.13/v1.14 differences above do not act; estimates are applied only once valid."""
    env = gym.make("fawtgym/Hover-v0", vehicle="s500", control_rate=200.0, episode_seconds=12.0, init_noise=0.0,
                   wind={"name": f"fawt-{duty}", "on_time": 2.0, "off_time": 12.0}, sensors="mocap_imu")
    agent = PX4Agent.for_env(env)
    obs, info = env.reset(seed=0)
    agent.reset(info)
    th0 = agent.position_control.hover_thrust[0]
    max_int, ths, first_valid = 0.0, [], None
    for k in range(int(11.5 * 200)):
        obs, _, term, _, info = env.step(agent.act(obs, info))
        assert not term, info["failure"]
        max_int = max(max_int, abs(agent.position_control.vel_int[0, 2]))
        ths.append(agent.position_control.hover_thrust[0])
        if first_valid is None and agent.hover_thrust_estimator.valid[0]:
            first_valid = k
    assert max_int < 0.5 * GRAVITY
    assert 0.1 < min(ths) and max(ths) < 0.9
    assert first_valid is not None and first_valid / 200.0 >= 2.0  # the 2 s hysteresis
    assert np.all(np.array(ths[:first_valid]) == th0)  # nothing applied before it was valid
