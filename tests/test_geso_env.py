"""GESO with the hover env's measurements at its control rate (both channels, default gains)."""

from __future__ import annotations

import numpy as np
from _env_helpers import run_hover_with_observers as _run


def test_geso_tracks_the_env_disturbance_wrench():
    rows = _run(["geso"])
    for est, truth in rows[100:]:  # after 1 s at 100 Hz, w_b = 20 rad/s
        assert np.abs(est["geso"].force[0] - truth["force"]).max() < 0.01  # external 0.5 N plus aero drag
        assert np.abs(est["geso"].torque[0] - truth["torque"]).max() < 5e-4
    # the estimate really moved from its zero start towards the applied wrench
    assert np.abs(rows[0][0]["geso"].force[0]).max() < 0.2
