"""Quad X control allocation: PX4 normalization, round trip, desaturation (agents/px4_allocation.py)."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.agents.px4_allocation import QuadXAllocation
from fawtgym.core.constants import GRAVITY
from fawtgym.envs.motors import command_to_thrust, hover_command
from fawtgym.envs.vehicles import make_vehicle


@pytest.fixture(scope="module")
def alloc() -> QuadXAllocation:
    return QuadXAllocation(make_vehicle("s500"))


def test_px4_normalization_and_physical_scales(alloc: QuadXAllocation) -> None:
    p = alloc.preset
    t_max = p.k_thrust * p.omega_max**2
    # PX4's normalized quad X mix: +-1/sqrt(2) for roll/pitch, +-1 for yaw, -1 for F_z
    np.testing.assert_allclose(np.abs(alloc.mix[:, :2]), np.sqrt(0.5))
    np.testing.assert_allclose(np.abs(alloc.mix[:, 2:]), 1.0)
    np.testing.assert_allclose(alloc.thrust_scale, 4 * t_max)
    np.testing.assert_allclose(alloc.torque_scale, [2 * p.arm_length * t_max, 2 * p.arm_length * t_max,
                                                    4 * p.k_moment * t_max])


def test_round_trip_wrench_motors_wrench(alloc: QuadXAllocation) -> None:
    rng = np.random.default_rng(0)
    tau_n = rng.uniform(-0.05, 0.05, size=(20, 3))
    thr_n = rng.uniform(0.25, 0.6, size=20)
    rotor, unallocated = alloc.allocate(tau_n, thr_n)
    assert np.all((rotor > 0) & (rotor < 1))
    np.testing.assert_allclose(unallocated, 0.0, atol=1e-12)
    f, tau = alloc.wrench(rotor)
    np.testing.assert_allclose(f, thr_n * alloc.thrust_scale, rtol=1e-12)
    np.testing.assert_allclose(tau, tau_n * alloc.torque_scale, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(alloc.normalized_to_torque(alloc.torque_to_normalized(tau)), tau)
    # motor commands realise the rotor thrusts through the preset's rotor map
    cmd = alloc.motor_commands(rotor)
    np.testing.assert_allclose(command_to_thrust(alloc.preset, cmd), rotor * alloc.max_rotor_thrust, rtol=1e-12)


def test_hover_maps_to_hover_command(alloc: QuadXAllocation) -> None:
    p = alloc.preset
    rotor, _ = alloc.allocate(np.zeros((1, 3)), [p.mass * GRAVITY / alloc.thrust_scale])
    np.testing.assert_allclose(alloc.motor_commands(rotor), hover_command(p), rtol=1e-12)


def test_desaturation_keeps_outputs_in_range_and_reports_saturation(alloc: QuadXAllocation) -> None:
    # large roll demand at high thrust: roll is reduced (not thrust increased), outputs stay in [0, 1]
    rotor, un = alloc.allocate(np.array([[0.8, 0.0, 0.0]]), [0.9])
    assert np.all((rotor >= 0) & (rotor <= 1))
    assert un[0, 0] > 1e-3  # roll not fully achieved: positive saturation
    f, _ = alloc.wrench(rotor)
    assert f[0] <= 0.9 * alloc.thrust_scale + 1e-9  # thrust never raised to unsaturate
    # yaw is sacrificed before roll/pitch
    rotor, un = alloc.allocate(np.array([[0.2, 0.0, 0.9]]), [0.5])
    assert abs(un[0, 0]) < 1e-9 and un[0, 2] > 0.1
    # negative saturation at low thrust
    rotor, un = alloc.allocate(np.array([[-0.5, 0.0, 0.0]]), [0.1])
    assert np.all(rotor >= 0) and un[0, 0] < 0
