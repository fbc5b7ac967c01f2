"""The agent's input path (agents/base.py, fawtgym/core/measurement.py, agents/px4_cascade.pack_constants,
observers/base.BufferStates): the single env's unbatched info becomes (1, ...) views without copies, the same
values a batched info gives; a PX4 law's parameter changed in place reaches the cascade kernel (also after a deep
copy or pickling); an estimate's lazily built states read like a dict."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from fawtgym.agents.base import applied_from_info, measurement_from_info
from fawtgym.agents.px4_agent import PX4ObserverAgent
from fawtgym.core.measurement import batch_measurement
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.eval.bench.observers import hover_measurement
from fawtgym.observers import make_observer


def _unbatched_measurement(rng: np.random.Generator) -> dict[str, object]:
    """An unbatched measurement, as the single env reports it (time a numpy scalar)."""
    meas: dict[str, object] = {k: v[0] for k, v in hover_measurement(1, rng).items()}
    meas["time"] = np.float64(0.25)
    return meas


def test_unbatched_float64_arrays_become_one_row_views() -> None:
    raw = _unbatched_measurement(np.random.default_rng(0))
    out = batch_measurement(raw)
    for key, value in raw.items():
        assert out[key].shape == (1, *np.shape(value)), key
        assert out[key].dtype == np.float64
        np.testing.assert_array_equal(out[key][0], value)
        if isinstance(value, np.ndarray):
            assert np.shares_memory(out[key], value), key    # a view, not a copy


def test_batched_and_converted_inputs() -> None:
    batched = hover_measurement(3, np.random.default_rng(1))
    out = batch_measurement(batched)
    assert all(out[k] is batched[k] for k in batched)          # batched float64: passed on as is
    ints = batch_measurement({"position": [1, 2, 3], "velocity": np.array([[1, 2, 3]], dtype=np.int32)})
    assert ints["position"].dtype == np.float64 and ints["position"].shape == (1, 3)
    assert ints["velocity"].dtype == np.float64 and ints["velocity"].shape == (1, 3)
    for bad in (np.zeros(4), np.zeros((2, 4)), np.zeros(())):
        with pytest.raises(ValueError, match=r"measurement\['position'\] must have shape \(3,\) or \(N, \*\(3,\)\)"):
            batch_measurement({"position": bad})


def test_keys_subset() -> None:
    raw = _unbatched_measurement(np.random.default_rng(2))
    out = batch_measurement(raw, ("attitude", "position", "absent"))
    assert list(out) == ["attitude", "position"]
    meas, batched = measurement_from_info({"measurement": raw}, ("position",))
    assert list(meas) == ["position"] and not batched
    with pytest.raises(ValueError, match="info\\['measurement'\\] mapping"):
        measurement_from_info({"measurement": 5}, ("position",))


def test_applied_from_info_single_and_batched() -> None:
    thrust, torque = applied_from_info({"applied": {"thrust": 14.7, "torque": np.array([0.1, 0.2, 0.3])}}, 1, 1.0)
    assert thrust.shape == (1,) and thrust[0] == 14.7 and torque.shape == (1, 3)
    thrust, torque = applied_from_info({"applied": {"thrust": np.array([1.0, 2.0]), "torque": [0.0, 0.0, 1.0]}},
                                       2, 1.0)
    np.testing.assert_array_equal(thrust, [1.0, 2.0])
    np.testing.assert_array_equal(torque, [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    thrust, torque = applied_from_info({}, 2, 9.0)
    np.testing.assert_array_equal(thrust, [9.0, 9.0])
    np.testing.assert_array_equal(torque, np.zeros((2, 3)))


def _fly(agent: PX4ObserverAgent, steps: int = 30) -> list[np.ndarray]:
    env = HoverEnv(wind={"name": "fawt-50", "on_time": 0.02}, sensors="mocap_imu", control_rate=200.0)
    obs, info = env.reset(seed=3)
    agent.reset(info)
    actions = []
    for _ in range(steps):
        action = agent.act(obs, info)
        actions.append(action)
        obs, _, _, _, info = env.step(action)
    env.close()
    return actions


@pytest.mark.parametrize("clone", [lambda a: a, copy.deepcopy, lambda a: pickle.loads(pickle.dumps(a))],
                         ids=["original", "deepcopy", "pickle"])
def test_a_law_parameter_changed_in_place_reaches_the_cascade(clone) -> None:  # type: ignore[no-untyped-def]
    """The cascade kernel reads one packed constants vector; the laws' parameter arrays are views of it, also in a
    deep copy or an unpickled agent: a gain changed in place changes the flight of that agent only."""
    base = _fly(PX4ObserverAgent(observer="ffts_eso", control_rate=200.0))
    agent = clone(PX4ObserverAgent(observer="ffts_eso", control_rate=200.0))
    np.testing.assert_array_equal(np.array(_fly(agent)), np.array(base))
    changed = clone(PX4ObserverAgent(observer="ffts_eso", control_rate=200.0))
    untouched = copy.deepcopy(changed)
    changed.attitude_control.params[:3] *= 0.5      # roll/pitch/yaw attitude gains halved, in place
    assert not np.array_equal(np.array(_fly(changed)), np.array(base))
    np.testing.assert_array_equal(np.array(_fly(untouched)), np.array(base))   # its copy keeps its own gains


def test_buffer_states_read_like_a_dict() -> None:
    obs = make_observer("ffts_eso", 1.5, np.diag([0.03, 0.03, 0.05]))
    meas = hover_measurement(2, np.random.default_rng(4))
    obs.reset(meas)
    est = obs.update(meas, np.full(2, 14.7), np.zeros((2, 3)), 1e-3)
    states = est.states
    assert list(states) == ["position", "velocity", "attitude", "angular_velocity"] and len(states) == 4
    assert dict(states)["attitude"].shape == (2, 3, 3) and states["velocity"].shape == (2, 3)
    assert "gibbs" not in states and states.get("gibbs") is None
    # views of the estimate's buffer (not of the observer's state: the next update leaves them as they are)
    before = {k: v.copy() for k, v in states.items()}
    obs.update(meas, np.full(2, 14.7), np.zeros((2, 3)), 1e-3)
    for k, v in states.items():
        np.testing.assert_array_equal(v, before[k])


def test_an_array_assigned_to_a_law_parameter_reaches_the_cascade() -> None:
    """Assigning a new parameter array to a law (InPlaceArray) writes it into the packed vector the cascade kernel
    reads -- it must not rebind the law to an array the kernel never sees; a wrong shape is a one-line error."""
    base = _fly(PX4ObserverAgent(observer="ffts_eso", control_rate=200.0))
    agent = PX4ObserverAgent(observer="ffts_eso", control_rate=200.0)
    agent.rate_control.params = agent.rate_control.params * 3.0
    assert not np.array_equal(np.array(_fly(agent)), np.array(base))
    again = PX4ObserverAgent(observer="ffts_eso", control_rate=200.0)
    pc = again.position_control
    pc.gain_pos_p = pc.gain_pos_p * 5.0
    pc.params = pc.parameters()
    assert not np.array_equal(np.array(_fly(again)), np.array(base))
    with pytest.raises(ValueError, match=r"RateControl.params must keep its shape \(\d+,\)"):
        again.rate_control.params = np.zeros(3)


def test_subclass_overrides_of_the_input_hooks_run() -> None:
    """A subclass's known_inputs runs with the default observer_inputs="applied" (the shortcut is for the base's own);
    an observer that states no required_keys gets every measurement key."""
    from fawtgym.envs.vehicles import make_vehicle
    from fawtgym.observers.base import Observer, ObserverEstimate

    calls = []

    class Counting(PX4ObserverAgent):
        def known_inputs(self, info):  # type: ignore[no-untyped-def]
            calls.append(1)
            return super().known_inputs(info)

    class ReadsMagnetometer(Observer):  # overrides update and reads a key the cascade does not
        def _reset(self, measurement, force, torque, rows):  # type: ignore[no-untyped-def]
            return None

        def update(self, measurement, thrust, torque, dt):  # type: ignore[no-untyped-def]
            m = np.asarray(measurement["magnetometer"]).reshape(-1, 3)
            return ObserverEstimate(np.zeros((m.shape[0], 3)), np.zeros((m.shape[0], 3)))

    env = HoverEnv(sensors="mocap_imu")
    agent = Counting.for_env(env, observer="ffts_eso")
    obs, info = env.reset(seed=0)
    agent.reset(info)
    agent.act(obs, info)
    assert calls == [1]
    p = make_vehicle("s500")
    mag = PX4ObserverAgent.for_env(env, observer=ReadsMagnetometer(p.mass, p.inertia_matrix))
    mag.reset(info)
    assert np.all(np.isfinite(mag.act(obs, info)))
    env.close()
