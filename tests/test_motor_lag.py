"""The rotor-speed lag kernel (envs/motors.py lag_thrusts) against its closed form; rows independent."""

import numpy as np
from _tolerance import assert_same_law

from fawtgym.envs.motors import decay_factors, lag_speeds, lag_thrusts, substep_times
from fawtgym.envs.vehicles import make_vehicle


def test_lag_kernel_is_the_closed_form_lag():
    """lag_thrusts (the env's motor lag) against lag_speeds' closed form at the substep midpoints and the end; rows
    speeding up and slowing down; rows do not depend on each other (a row alone is bitwise its row in the batch)."""
    p = make_vehicle("s500")
    rng = np.random.default_rng(2)
    w0, ref = rng.uniform(200, 900, (5, 4)), rng.uniform(200, 900, (5, 4))
    times = substep_times(0.005, 5)
    np.testing.assert_allclose(times, [0.0005, 0.0015, 0.0025, 0.0035, 0.0045, 0.005])
    up, down = decay_factors(p, times)
    thrusts, speeds, mean = np.zeros((5, 5, 7)), np.empty((5, 4)), np.empty((5, 4))
    lag_thrusts(ref, w0, up, down, p.k_thrust, thrusts, speeds, mean)
    want = lag_speeds(p, w0, ref, times)  # (K + 1, 5, 4)
    # the kernel and the numpy closed form: two implementations of one formula (tests/_tolerance.py)
    assert_same_law(speeds, want[-1], what="end speeds")
    assert_same_law(thrusts[:, :, :4], np.swapaxes(p.k_thrust * want[:-1] ** 2, 0, 1), what="substep thrusts")
    assert_same_law(mean, (p.k_thrust * want[:-1] ** 2).mean(axis=0), what="mean thrust")
    assert np.all(thrusts[:, :, 4:] == 0.0)  # only the rotor columns of a wider control array are written
    for i in range(5):
        t1, s1, m1 = np.zeros((1, 5, 4)), np.empty((1, 4)), np.empty((1, 4))
        lag_thrusts(ref[i:i + 1], w0[i:i + 1], up, down, p.k_thrust, t1, s1, m1)
        np.testing.assert_array_equal(t1[0], thrusts[i, :, :4])
        np.testing.assert_array_equal(s1[0], speeds[i])
        np.testing.assert_array_equal(m1[0], mean[i])
