"""Agents' bad input: one-line ValueErrors naming the bad value and what is allowed, the same text at every N,
and a refused call changes nothing (audit of issue 14: D4, D9-agent)."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.agents.px4_agent import PX4Agent, PX4ObserverAgent
from fawtgym.agents.spec import make_agent
from fawtgym.core.checks import shown
from fawtgym.envs.hover_batch_env import HoverBatchEnv

FLAGS = ("force_ff", "torque_ff")
STAND_INS = [("False", "'False' (str)"), ("True", "'True' (str)"), (-1, "-1 (int)"), (0, "0 (int)"), (1, "1 (int)"),
             (1.0, "1.0 (float)"), (None, "None (NoneType)"), ("no", "'no' (str)")]


# ---- D4: Boolean options are booleans ---------------------------------------------------------------------------
@pytest.mark.parametrize("flag", FLAGS)
@pytest.mark.parametrize("value, shown", STAND_INS)
def test_observer_agent_refuses_truthy_stand_ins(flag: str, value: object, shown: str) -> None:
    with pytest.raises(ValueError) as exc:
        PX4ObserverAgent(observer="leso", **{flag: value})
    assert str(exc.value) == f"{flag} must be True or False, got {shown}"


@pytest.mark.parametrize("flag", FLAGS)
@pytest.mark.parametrize("value", [True, False, np.bool_(True), np.bool_(False)])
def test_observer_agent_takes_python_and_numpy_booleans(flag: str, value: object) -> None:
    agent = PX4ObserverAgent(observer="ffts_eso", **{flag: value})
    assert getattr(agent, flag) is bool(value)


def test_a_channel_the_observer_lacks_is_never_fed_forward() -> None:
    from fawtgym.observers.base import observer_class

    name = next(n for n in ("leso", "geso", "ffts_eso") if "force" in observer_class(n).channels)
    agent = PX4ObserverAgent(observer=name, force_ff=True, torque_ff=False)
    assert agent.force_ff is True and agent.torque_ff is False


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("flag", FLAGS)
def test_agent_spec_refuses_a_string_flag(n: int, flag: str) -> None:
    env = HoverBatchEnv(n)
    spec = f"px4+ffts_eso({flag}='False')"
    with pytest.raises(ValueError) as exc:
        make_agent(spec, env)
    assert str(exc.value) == f"agent {spec!r}: {flag} must be True or False, got 'False' (str)"
    assert getattr(make_agent(f"px4+ffts_eso({flag}=False)", env), flag) is False


# ---- D9-agent: PX4Agent (no observer) refuses a measurement it cannot use, as the observers do -------------------
def _agent_and_info(n: int, **kwargs: object) -> tuple[PX4Agent, dict]:
    """A PX4Agent after one act, and the next step's info: N copies of one vehicle's (so only N differs)."""
    env = HoverBatchEnv(1, sensors="mocap_imu")
    infos = [env.reset(seed=0)[1], env.step(env.hover_action())[4]]
    infos = [{part: {k: np.repeat(np.asarray(v), n, axis=0) for k, v in one[part].items()}
              for part in ("measurement", "applied")} for one in infos]
    agent = PX4Agent.for_env(env, **kwargs)
    agent.reset(infos[0])
    agent.act(None, infos[0])
    env.close()
    return agent, infos[1]


def _bad(info: dict, case: str) -> dict:
    """``info`` with row 0 of its measurement spoilt by ``case`` (a key missing, an attitude that is not a rotation,
    a non-finite entry)."""
    meas = dict(info["measurement"])
    if case.startswith("no "):
        for key in case[3:].split("+"):
            del meas[key]
    elif case.startswith("attitude "):
        att = meas["attitude"].copy()
        att[0] = {"reflection": np.diag([1.0, 1.0, -1.0]), "2I": 2 * np.eye(3), "-I": -np.eye(3),
                  "1.001R": 1.001 * att[0], "nan": np.full((3, 3), np.nan)}[case[9:]]
        meas["attitude"] = att
    else:  # "nan <key>"
        key = case[4:]
        meas[key] = meas[key].copy()
        meas[key][0, 1] = np.inf if key == "velocity" else np.nan
    return {**info, "measurement": meas}


def _observer_text(info: dict, keys: tuple[str, ...], n: int) -> str:
    """The observers' own check on the same measurement (the text PX4Agent must give, with its name)."""
    from fawtgym.observers.base import check_measurement

    with pytest.raises(ValueError) as exc:
        check_measurement(info["measurement"], keys, n, "PX4Agent")
    return str(exc.value)


CASES = {
    "no velocity": "PX4Agent: measurement needs the keys ['position', 'velocity', 'attitude', 'angular_velocity']; "
                   "missing ['velocity']",
    "no position+attitude": "PX4Agent: measurement needs the keys ['position', 'velocity', 'attitude', "
                            "'angular_velocity']; missing ['position', 'attitude']",
    "no angular_velocity": "PX4Agent: measurement needs the keys ['position', 'velocity', 'attitude', "
                           "'angular_velocity']; missing ['angular_velocity']",
    "attitude reflection": "PX4Agent: measurement['attitude'] row 0 is not a rotation matrix (allowed: "
                           "max |R^T R - I| <= 1e-06 and det R = +1; got max |R^T R - I| = 0, det R = -1)",
    "attitude 2I": "PX4Agent: measurement['attitude'] row 0 is not a rotation matrix (allowed: max |R^T R - I| <= "
                   "1e-06 and det R = +1; got max |R^T R - I| = 3, det R = 8)",
    "attitude -I": "PX4Agent: measurement['attitude'] row 0 is not a rotation matrix (allowed: max |R^T R - I| <= "
                   "1e-06 and det R = +1; got max |R^T R - I| = 0, det R = -1)",
    "attitude 1.001R": "PX4Agent: measurement['attitude'] row 0 is not a rotation matrix (allowed: max |R^T R - I| "
                       "<= 1e-06 and det R = +1; got max |R^T R - I| = 0.002, det R = 1.003)",
    "attitude nan": "PX4Agent: measurement['attitude'] has a non-finite entry in row 0: "
                    "[[nan, nan, nan], [nan, nan, nan], [nan, nan, nan]]",
    "nan position": "PX4Agent: measurement['position'] has a non-finite entry in row 0: [",
    "nan velocity": "PX4Agent: measurement['velocity'] has a non-finite entry in row 0: [",
    "nan angular_velocity": "PX4Agent: measurement['angular_velocity'] has a non-finite entry in row 0: [",
    "nan specific_force": "PX4Agent: measurement['specific_force'] has a non-finite entry in row 0: [",
}


@pytest.mark.parametrize("case", CASES)
def test_px4_agent_refuses_a_bad_measurement_as_the_observers_do(case: str) -> None:
    """The same one-line ValueError at N = 1 and N = 3, the observers' text (their check run on the same input),
    and the refused act changes nothing: the agent then flies bitwise as a twin that never saw it."""
    texts = []
    for n in (1, 3):
        agent, info = _agent_and_info(n)
        twin, _ = _agent_and_info(n)
        bad = _bad(info, case)
        with pytest.raises(ValueError) as exc:
            agent.act(None, bad)
        texts.append(str(exc.value))
        assert "\n" not in texts[-1]
        for _ in range(3):
            np.testing.assert_array_equal(agent.act(None, info), twin.act(None, info))
        np.testing.assert_array_equal(agent.position_control.state, twin.position_control.state)
        np.testing.assert_array_equal(agent.rate_control.state, twin.rate_control.state)
        np.testing.assert_array_equal(agent.hover_thrust_estimator.state, twin.hover_thrust_estimator.state)
    assert texts[0] == texts[1]
    assert texts[0].startswith(CASES[case]), texts[0]
    keys = ("position", "velocity", "attitude", "angular_velocity", "specific_force")
    assert texts[1] == _observer_text(bad, keys if not case.startswith("no ") else keys[:4], 3)


@pytest.mark.parametrize("case", ["no velocity", "attitude reflection", "nan position"])
def test_a_delayed_pose_is_checked_when_it_arrives(case: str) -> None:
    """With ``pose_latency`` the cascade sees the pose steps later: it is refused at once, and the delay line is
    left as it was (the agent flies on bitwise as its twin)."""
    agent, info = _agent_and_info(1, pose_latency=0.02)
    twin, _ = _agent_and_info(1, pose_latency=0.02)
    with pytest.raises(ValueError, match=r"^PX4Agent: measurement"):
        agent.act(None, _bad(info, case))
    for _ in range(4):
        np.testing.assert_array_equal(agent.act(None, info), twin.act(None, info))


def test_a_single_env_info_is_refused_alike() -> None:
    """Unbatched (3,) / (3, 3) measurements of the single env: the same text as the N = 1 batch."""
    agent, info = _agent_and_info(1)
    single = {**info, "measurement": {k: v[0] for k, v in info["measurement"].items()}}
    bad = {**single, "measurement": {**single["measurement"], "attitude": np.diag([1.0, 1.0, -1.0])}}
    with pytest.raises(ValueError) as exc:
        agent.act(None, bad)
    assert str(exc.value) == CASES["attitude reflection"]


def test_the_cascade_and_the_observers_share_the_rotation_tolerance() -> None:
    """The cascade refuses an attitude by core's ROTATION_TOL and words it with the observers' check: they must agree
    (else the cascade's fallback text would show); observers/_checks.py should import it from core."""
    from fawtgym.core.so3_kernels import ROTATION_TOL
    from fawtgym.observers import _checks

    assert _checks.ROTATION_TOL == ROTATION_TOL


# ---- options the cascade reads every step: refused at construction (a NaN heading made every action NaN) ----------
@pytest.mark.parametrize("value", [float("nan"), float("inf"), "0.5", True, np.bool_(False), 1j, None, 10**400, 1e300])
def test_yaw_setpoint_is_a_finite_heading(value: object) -> None:
    with pytest.raises(ValueError) as exc:
        PX4Agent(yaw_setpoint=value)
    assert str(exc.value) == (f"yaw_setpoint must be a finite real number in [-1000, 1000] rad (a heading), got "
                              f"{shown(value)} ({type(value).__name__})")


@pytest.mark.parametrize("value", [float("nan"), "0.5", True, 1j])
def test_set_setpoint_refuses_a_bad_heading_and_changes_nothing(value: object) -> None:
    agent, info = _agent_and_info(1)
    twin, _ = _agent_and_info(1)
    with pytest.raises(ValueError) as exc:
        agent.set_setpoint([0.0, 0.0, -1.0], yaw=value)
    assert str(exc.value) == (f"yaw_setpoint must be a finite real number in [-1000, 1000] rad (a heading), got "
                              f"{value!r} ({type(value).__name__})")
    assert agent.yaw_setpoint == 0.0
    for _ in range(3):  # neither the position setpoint nor the override took effect: it flies as its twin
        np.testing.assert_array_equal(agent.act(None, info), twin.act(None, info))


@pytest.mark.parametrize("value", [0.5, -3, np.float32(1.0), np.int64(2)])
def test_yaw_setpoint_takes_real_numbers(value: object) -> None:
    assert PX4Agent(yaw_setpoint=value).yaw_setpoint == float(value)


@pytest.mark.parametrize("value", ["gyr0", "magnetometer", "position", 3, None])
def test_gyro_key_names_a_gyro(value: object) -> None:
    """A misspelt key used to fall back silently to angular_velocity."""
    with pytest.raises(ValueError) as exc:
        PX4Agent(gyro_key=value)
    assert str(exc.value) == f"gyro_key must be one of ['angular_velocity', 'gyro'], got {value!r}"


# ---- the constructor's numbers: numpy scalars accepted, huge / bool / non-real refused with one line -----------------
@pytest.mark.parametrize("kwargs", [dict(control_rate=np.float32(100.0)), dict(control_rate=np.int16(250)),
                                    dict(position_rate=np.float32(50.0)), dict(pose_latency=np.float32(0.004)),
                                    dict(thrust_model_error=np.float32(0.1)), dict(hover_thrust=np.float64(0.5)),
                                    dict(setpoint=np.array([0, 0, -1], dtype=np.int8)),
                                    dict(params={"MPC_XY_P": np.float32(0.9)})])
def test_numpy_real_scalars_are_taken(kwargs: dict) -> None:
    PX4Agent(**kwargs)


@pytest.mark.parametrize("kwargs, text", [
    (dict(control_rate=10**400), "control_rate must be a finite real number in [1, 100000] Hz, got an int of about 401 "
                                  "digits (int)"),
    (dict(control_rate=True), "control_rate must be a finite real number in [1, 100000] Hz, got True (bool)"),
    (dict(control_rate=5e-324), "control_rate must be a finite real number in [1, 100000] Hz, got 5e-324"),
    (dict(position_rate=10**400), "position_rate must be a finite real number in (0, 250] Hz (control_rate: 250 Hz)"),
    (dict(pose_latency=1e300), "pose_latency must be a finite real number in [0, 1] s, got 1e+300 (float)"),
    (dict(pose_latency=10**400), "pose_latency must be a finite real number in [0, 1] s, got an int of about 401 "
                                  "digits"),
    (dict(thrust_model_error=10**400), "thrust_model_error must be a finite real number in (-0.5, 0.5) (a relative"),
    (dict(hover_thrust="a"), "hover_thrust must be a finite real number in (0, 1) (normalized collective thrust), "
                             "got 'a' (str)"),
    (dict(setpoint=[True, False, True]), "setpoint must be real NED coordinates [m] of shape (3,) or (N, 3), each "
                                         "within 10000 m, got [True, False, True]"),
    (dict(setpoint=[0, 0, 1e300]), "setpoint must be real NED coordinates [m] of shape (3,) or (N, 3), each within "
                                   "10000 m, got [0, 0, 1e+300]"),
    (dict(setpoint=np.array([0, 0, -1.0], dtype=object)), "setpoint must be real NED coordinates [m]"),
    (dict(params={"MPC_XY_P": 10**400}), "PX4 parameter MPC_XY_P must be finite, got an int of about 401 digits"),
    (dict(params={"MPC_XY_P": True}), "PX4 parameter MPC_XY_P must be a number, got True"),
    (dict(params={"IMU_GYRO_CUTOFF": 5e-324}), "PX4 parameter IMU_GYRO_CUTOFF=4.94066e-324 must be 0 (filter off) or "
                                               "in [0.01, 1000] Hz"),
])
def test_bad_constructor_numbers_give_one_line(kwargs: dict, text: str | None) -> None:
    with pytest.raises(ValueError) as exc:
        PX4Agent(**kwargs)
    message = str(exc.value)
    assert "\n" not in message
    if text is not None:
        assert message.startswith(text)


def test_observer_kwargs_must_be_a_mapping() -> None:
    from fawtgym.agents.px4_agent import PX4ObserverAgent

    with pytest.raises(ValueError) as exc:
        PX4ObserverAgent(observer="leso", observer_kwargs=5)
    assert str(exc.value) == "observer_kwargs must be None or a mapping of the observer's options, got 5"
