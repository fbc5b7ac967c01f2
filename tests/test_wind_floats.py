"""The single env's float interface of every wind model equals its array ``step`` (N = 1)."""

import numpy as np
import pytest
from _tolerance import assert_same_law

from fawtgym.envs.wind import make_wind, wind_names
from fawtgym.envs.wind.base import WindModel


@pytest.mark.parametrize("name", wind_names())
def test_step_floats_equals_step(name):
    a, b = make_wind(name), make_wind(name)
    a.reset(1, seed=5)
    b.reset(1, seed=5)
    rng = np.random.default_rng(1)
    for k in range(60):
        pts = np.array([1.5, 0.0, -1.5]) + rng.normal(0.0, 0.3, (1, 5, 3))
        vel = rng.normal(0.0, 1.0, (1, 3))
        t = (k + 1) * 0.01
        wa = np.array(a.step_floats(t, 0.01, pts.ravel().tolist(), vel[0].tolist())).reshape(1, 5, 3)
        wb = b.step(t, 0.01, pts, vel)
        # two implementations of one law (tests/_tolerance.py), at the scale of the wind speeds
        assert_same_law(wa, wb, scale=np.abs(wb).max(), steps=k + 1, what=f"{name} step {k}")


def test_default_step_floats_goes_through_step():
    class Uniform(WindModel):
        def reset(self, n, seed=None):
            self.n = n

        def step(self, t, dt, points_ned, vehicle_velocity_ned):
            out = np.zeros(points_ned.shape)
            out[..., 0] = t
            return out

    w = Uniform()
    w.reset(1)
    assert w.step_floats(2.0, 0.01, [0.0] * 6, [0.0, 0.0, 0.0]) == [2.0, 0.0, 0.0, 2.0, 0.0, 0.0]


def test_fawt_step_floats_rejects_bad_points():
    w = make_wind("fawt-50")
    w.reset(1, seed=0)
    with pytest.raises(ValueError, match="finite"):
        w.step_floats(0.01, 0.01, [1.5, 0.0, float("nan")], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="3 K"):
        w.step_floats(0.01, 0.01, [1.5, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="dt"):
        w.step_floats(0.01, 0.0, [1.5, 0.0, -1.5], [0.0, 0.0, 0.0])
