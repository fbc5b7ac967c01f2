"""The PX4 cascade kernel (agents/px4_cascade.py): rows are independent, N = 1 is a batch of one, and the
agent's errors read the same at every N."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from _env_helpers import record_px4_batch
from _tolerance import assert_same_law

from fawtgym.agents.px4_agent import PX4Agent, PX4ObserverAgent
from fawtgym.agents.px4_allocation import QuadXAllocation
from fawtgym.agents.spec import make_agent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.motors import thrust_to_command
from fawtgym.envs.vehicles import make_vehicle
from fawtgym.observers.base import Observer, ObserverEstimate

STEPS = 40


def _rows(info: Mapping[str, Any], idx: list[int]) -> dict[str, Any]:
    """The rows ``idx`` of a batched info dict (nested dicts of (N, ...) arrays)."""
    return {k: _rows(v, idx) if isinstance(v, Mapping) else (v[idx] if isinstance(v, np.ndarray) and v.ndim else v)
            for k, v in info.items()}


@pytest.fixture(scope="module")
def recorded() -> list[dict[str, Any]]:
    """Infos of a 3-row env flown by PX4 in FAWT-50 wind (fan on at 0.02 s), motion capture + IMU, rows perturbed."""
    return record_px4_batch([7, 8, 9], on_time=0.02, steps=STEPS)


def _batch_and_singles(spec: str, first: dict[str, Any]) -> tuple[HoverBatchEnv, Any, list[Any]]:
    """A 3-row env, an agent ``spec`` for all its rows and one per row, reset on the recorded ``first`` info (the
    single agents on their row)."""
    env = HoverBatchEnv(num_envs=3, sensors="mocap_imu", control_rate=200.0)
    batch = make_agent(spec, env)
    singles = [make_agent(spec, env) for _ in range(3)]
    batch.reset(first)
    for i, agent in enumerate(singles):
        agent.reset(_rows(first, [i]))
    return env, batch, singles

def test_each_row_flies_as_a_batch_of_one(recorded: list[dict[str, Any]]) -> None:
    """A row of the 3-row batch gets, bitwise, the actions of an agent holding that row alone: one kernel loops
    over rows with nothing shared between them (the same code path, so equality is exact)."""
    env, batch, singles = _batch_and_singles("px4", recorded[0])
    for k, info in enumerate(recorded):
        actions = batch.act(None, info)
        for i, agent in enumerate(singles):
            np.testing.assert_array_equal(actions[i], agent.act(None, _rows(info, [i]))[0], err_msg=f"row {i} step {k}")
    np.testing.assert_array_equal(batch.position_control.state[1], singles[1].position_control.state[0])
    np.testing.assert_array_equal(batch.hover_thrust_estimator.state[2], singles[2].hover_thrust_estimator.state[0])
    env.close()


def test_rows_with_an_observer_match_batches_of_one(recorded: list[dict[str, Any]]) -> None:
    """With the FFTS-ESO feedforward: the observer is one row kernel too, so a batch's rows are its batches of one,
    bit for bit (the same code path on the same inputs: tests/_tolerance.py)."""
    env, batch, singles = _batch_and_singles("px4+ffts_eso", recorded[0])
    for k, info in enumerate(recorded):
        actions = batch.act(None, info)
        got = np.concatenate([agent.act(None, _rows(info, [i])) for i, agent in enumerate(singles)])
        np.testing.assert_array_equal(actions, got, err_msg=f"step {k}")
    env.close()


class _Diverging(Observer):
    """An observer whose force estimate of row 0 is NaN while ``poisoned`` (test helper); zero otherwise."""

    name = "diverging"
    poisoned = False

    def reset(self, measurement, force=None, torque=None, *, rows=None, **options):
        pass

    def update(self, measurement, thrust, torque, dt):
        n = np.asarray(thrust).shape[0]
        force = np.zeros((n, 3))
        if self.poisoned:
            force[0, 1] = np.nan
        return ObserverEstimate(force, np.zeros((n, 3)))


def _error_text(n: int, case: str) -> tuple[type, str]:
    """The error of ``case`` for N rows, all copies of one vehicle's info (so only N differs); the bad value is in
    row 0."""
    env = HoverBatchEnv(num_envs=1, sensors="mocap_imu", control_rate=200.0)
    _, one = env.reset(seed=0)
    info = {part: {k: np.repeat(np.asarray(v), n, axis=0) for k, v in one[part].items()}
            for part in ("measurement", "applied")}
    p = env.preset
    agent = PX4ObserverAgent.for_env(env, observer=_Diverging(p.mass, p.inertia_matrix)) if case == "estimate" \
        else PX4Agent.for_env(env)
    if case != "before reset":
        agent.reset(info)
        agent.act(None, info)
    if case == "estimate":
        agent.observer.poisoned = True
    if case == "measurement":
        gyro = info["measurement"]["angular_velocity"].copy()
        gyro[0] = np.nan
        info = {**info, "measurement": {**info["measurement"], "angular_velocity": gyro}}
    with pytest.raises((ValueError, RuntimeError, FloatingPointError)) as exc:
        agent.act(None, info)
    env.close()
    return exc.type, str(exc.value)


@pytest.mark.parametrize("case", ["estimate", "measurement", "before reset"])
def test_errors_read_the_same_at_every_n(case: str) -> None:
    kind, text = _error_text(1, case)
    assert (kind, text) == _error_text(3, case)
    expected = {"estimate": (FloatingPointError, "observer 'diverging' returned a non-finite estimate (row 0)"),
                "measurement": (ValueError, "PX4Agent: measurement['angular_velocity'] has a non-finite entry in "
                                            "row 0: [nan, nan, nan]"),
                "before reset": (RuntimeError, "act() before reset()")}[case]
    assert kind is expected[0] and expected[1] in text, text


def test_a_diverging_estimate_changes_no_state() -> None:
    """The kernel checks the estimates before it touches any state: after the error the agent flies on exactly
    as a twin that never saw the bad estimate (the same code path: bitwise)."""
    env = HoverBatchEnv(num_envs=2, sensors="mocap_imu", control_rate=200.0)
    _, info = env.reset(seed=0)
    p = env.preset
    agent, twin = (PX4ObserverAgent.for_env(env, observer=_Diverging(p.mass, p.inertia_matrix)) for _ in range(2))
    for a in (agent, twin):
        a.reset(info)
        a.act(None, info)
    agent.observer.poisoned = True
    with pytest.raises(FloatingPointError, match="diverging"):
        agent.act(None, info)
    agent.observer.poisoned = False
    for _ in range(3):
        np.testing.assert_array_equal(agent.act(None, info), twin.act(None, info))
    np.testing.assert_array_equal(agent.position_control.state, twin.position_control.state)
    np.testing.assert_array_equal(agent.attitude_setpoint, twin.attitude_setpoint)
    env.close()


def test_controller_thrust_curve_is_the_env_rotor_map() -> None:
    """The controller's thrust curve (rotor_command_row) is the exact inverse of the env's steady-state rotor map,
    clipping included (PX4's THR_MDL_FAC tuned to the rotor)."""
    for name in ("s500", "x500"):
        alloc = QuadXAllocation(make_vehicle(name))
        rotor = np.array([[-0.1, 0.0, 0.3, 0.7], [1.0, 1.2, 0.05, 0.5]])
        assert_same_law(alloc.motor_commands(rotor), thrust_to_command(alloc.preset, rotor * alloc.max_rotor_thrust),
                        scale=1.0, what=f"{name} motor commands")
