"""The ctbr inner rate loop (batch-first): saturation keeps the collective thrust, the integrator freezes, rows
are independent."""

import numpy as np
import pytest

from fawtgym.envs.ctbr import RateLoop
from fawtgym.envs.motors import allocation_matrix
from fawtgym.envs.vehicles import make_vehicle


def test_rate_loop_saturation_rows_and_reset():
    p = make_vehicle("s500")
    loop = RateLoop(p, 0.001, n=3)
    collective = np.full(3, 2.0 * p.max_thrust_per_rotor)  # half the maximum
    rate = np.zeros((3, 3))
    rate_sp = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0], [50.0, 0.0, 0.0]])  # row 2 saturates
    t = loop.rotor_thrusts(collective, rate_sp, rate)
    assert t.shape == (3, 4)
    assert np.all(t >= loop.t_min - 1e-12) and np.all(t <= loop.t_max + 1e-12)
    wrench = t @ allocation_matrix(p).T  # [collective, torque]
    assert wrench[:, 0] == pytest.approx(collective, rel=1e-12)  # the collective thrust is kept first
    assert np.abs(wrench[0, 1:]).max() < 1e-12  # no rate error: no torque
    assert wrench[1, 1] > 0 and wrench[2, 1] > wrench[1, 1]  # roll torque toward the set point
    assert np.isclose(t[2], loop.t_max).any() or np.isclose(t[2], loop.t_min).any()
    # the integrator runs where the rotors are free and freezes where they saturate (PX4)
    assert loop.integral[1, 0] == pytest.approx(15.0 * 0.2 * 0.001)
    assert loop.integral[2, 0] == 0.0
    # a per-row reset clears that row only
    loop.reset(np.array([1]))
    assert loop.integral[1, 0] == 0.0 and not loop.has_prev[1] and loop.has_prev[0]
    # a single row reproduces its row of the batch
    one = RateLoop(p, 0.001, n=1)
    np.testing.assert_array_equal(one.rotor_thrusts(collective[2:], rate_sp[2:], rate[2:]), t[2:])
