"""pdt_sta: a row whose vectors give no attitude (free fall) gets no correction, not a kick."""

import numpy as np

from fawtgym.core.measurement import EARTH_FIELD_NED
from fawtgym.core.so3 import exp_so3
from fawtgym.observers import make_observer


def test_invalid_accelerometer_row_is_not_corrected():
    r = exp_so3(np.array([0.3, -0.2, 0.9]))
    meas = {"position": np.zeros(3), "velocity": np.zeros(3), "attitude": r, "angular_velocity": np.zeros(3),
            "specific_force": r.T @ np.array([0.0, 0.0, -9.80665]), "gyro": np.zeros(3),
            "magnetometer": r.T @ EARTH_FIELD_NED, "time": 0.0}
    obs = make_observer("pdt_sta", 1.0, [0.03, 0.03, 0.06])
    obs.reset(meas)
    for _ in range(400):  # settle at rest
        obs.update(meas, 9.8, np.zeros(3), 0.01)
    x1, x2 = obs.core.x1.copy(), obs.core.omega.copy()
    free_fall = {**meas, "specific_force": np.zeros(3)}
    obs.update(free_fall, 0.0, np.zeros(3), 0.01)
    assert not obs.quest_valid[0]
    # at rest with no correction the estimate can only drift by its own rate estimate over one step
    assert np.abs(obs.core.x1 - x1).max() <= 0.01 * np.abs(x2).max() + 1e-12
