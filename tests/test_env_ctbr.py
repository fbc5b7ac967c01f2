"""The ctbr inner rate loop: float law (single env) == vectorized law (batch env), incl. saturation."""

import numpy as np
from _tolerance import assert_same_law

from fawtgym.envs.ctbr import RateLoop
from fawtgym.envs.hover_batch_env import BatchRateLoop
from fawtgym.envs.vehicles import make_vehicle


def test_rate_loop_float_law_equals_batched_law():
    p = make_vehicle("s500")
    n = 4
    loops = [RateLoop(p, 0.001) for _ in range(n)]
    batch = BatchRateLoop(loops[0], n)
    rng = np.random.default_rng(0)
    saturated = 0
    for k in range(300):
        collective = rng.uniform(0.1, 1.0, n) * 4 * p.max_thrust_per_rotor
        rate_sp = rng.normal(0.0, 3.0 if k % 10 == 0 else 0.3, (n, 3))
        rate = rng.normal(0.0, 0.5, (n, 3))
        want = batch.rotor_thrusts(collective, rate_sp, rate)
        got = np.array([loop.rotor_thrusts(collective[i], rate_sp[i], rate[i]) for i, loop in enumerate(loops)])
        # two implementations of one law (tests/_tolerance.py), at the scale of the rotor thrusts
        assert_same_law(got, want, scale=p.max_thrust_per_rotor, steps=k + 1, what=f"step {k} rotor thrusts")
        saturated += int(np.isclose(want, p.max_thrust_per_rotor).any())
    assert saturated > 10  # the comparison covered saturated steps (frozen integrator, scaled torque)
    assert_same_law(np.array([loop.integral for loop in loops]), batch.integral, steps=300, what="rate integrals")
    assert np.abs(batch.integral).max() > 0.0
