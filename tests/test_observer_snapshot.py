"""Observer.snapshot / restore: an update taken back leaves the observer as if it never happened (bitwise)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.observers.base import make_observer, observer_names

MASS, INERTIA = 1.2, np.diag([0.03, 0.03, 0.06])


@pytest.mark.filterwarnings("ignore:QB gain")
@pytest.mark.parametrize("name", observer_names())
@pytest.mark.parametrize("n", [1, 3])
def test_an_update_taken_back_changes_nothing(name, n):
    env = HoverBatchEnv(n, wind="fawt-50", sensors="mocap_imu")
    _, info = env.reset(seed=2)
    infos = [copy.deepcopy(info)]
    for _ in range(4):
        *_, info = env.step(env.hover_action())
        infos.append(copy.deepcopy(info))
    a, b = make_observer(name, MASS, INERTIA), make_observer(name, MASS, INERTIA)
    a.reset(infos[0]["measurement"])
    b.reset(infos[0]["measurement"])

    def update(obs, info):
        est = obs.update(info["measurement"], info["applied"]["thrust"], info["applied"]["torque"], env.dt)
        return [np.array(v, copy=True) for v in (est.force, est.torque) if v is not None]

    update(a, infos[1]), update(b, infos[1])
    snap = a.snapshot()
    update(a, infos[2])  # taken back
    a.restore(snap)
    for k in (2, 3, 4):
        for x, y in zip(update(a, infos[k]), update(b, infos[k]), strict=True):
            np.testing.assert_array_equal(x, y)
