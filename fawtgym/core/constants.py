"""Physical constants every package shares, defined once (envs, observers, agents, eval import them from here).

``GRAVITY``: standard gravity g [m/s^2], PX4's ``CONSTANTS_ONE_G`` (9.80665, the CGPM's standard acceleration of
free fall); the world is NED, so gravity is +g e3 (Wang et al. (2024) eq. 38: m v' = m g e3 - f R e3 + phi_D).

``EARTH_FIELD_NED``: the Earth magnetic field the simulated magnetometer measures, world NED [gauss]
(mid-latitude, ~60 deg dip), also the observers' default reference vector.
"""

from __future__ import annotations

import numpy as np

#: standard gravity [m/s^2] (PX4's CONSTANTS_ONE_G)
GRAVITY = 9.80665
#: Earth magnetic field used by the simulated magnetometer, world NED [gauss] (mid-latitude, ~60 deg dip)
EARTH_FIELD_NED = np.array([0.22, 0.0, 0.42])
