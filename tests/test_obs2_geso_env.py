"""GESO with the hover env's measurements at its control rate (both channels, default gains)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import fawtgym  # noqa: F401  (registers the env ids)
from fawtgym.observers import make_observer

EXT_FORCE = np.array([0.5, -0.3, 0.2])
EXT_TORQUE = np.array([0.02, -0.01, 0.005])


def _run(names, steps=150, sensors="none"):
    env = gym.make("fawtgym/Hover-v0", wind="calm", sensors=sensors, init_noise=0.0, action_type="ctbr",
                   control_rate=100.0)
    u = env.unwrapped
    _, info = env.reset(seed=0)
    u.set_external_wrench(EXT_FORCE, EXT_TORQUE)
    p = u.preset
    action = np.array([p.mass * 9.80665 / (4 * p.max_thrust_per_rotor), 0.0, 0.0, 0.0])
    observers = {n: make_observer(n, p.mass, p.inertia_matrix) for n in names}
    for o in observers.values():
        o.reset(info["measurement"])
    rows = []
    for _ in range(steps):
        _, _, term, _, info = env.step(action)
        assert not term, info["failure"]
        ap = info["applied"]
        est = {n: o.update(info["measurement"], ap["thrust"], ap["torque"], u.dt) for n, o in observers.items()}
        rows.append((est, info["truth"]))
    env.close()
    return rows


def test_geso_tracks_the_env_disturbance_wrench():
    rows = _run(["geso"])
    for est, truth in rows[100:]:  # after 1 s at 100 Hz, w_b = 20 rad/s
        assert np.abs(est["geso"].force[0] - truth["force"]).max() < 0.01  # external 0.5 N plus aero drag
        assert np.abs(est["geso"].torque[0] - truth["torque"]).max() < 5e-4
    # the estimate really moved from its zero start towards the applied wrench
    assert np.abs(rows[0][0]["geso"].force[0]).max() < 0.2
