"""``fawtgym replay``: fly an agent of the agent grammar through a real autopilot over MAVLink.

The companion-computer side of an OFFBOARD flight, one thread, every wait bounded:

1. connect (``udp:HOST:PORT`` listens, as PX4 SITL's offboard link sends to 14540; ``tcp:``/``udpout:``/serial
   as pymavlink accepts) and wait for the autopilot's HEARTBEAT (``connect_timeout``);
2. ask for ATTITUDE_QUATERNION, LOCAL_POSITION_NED and HIGHRES_IMU at the setpoint rate (SET_MESSAGE_INTERVAL)
   and wait for them;
3. stream SET_ATTITUDE_TARGET (level at the current heading, zero thrust) for ``prestream`` > 1 s, switch to
   OFFBOARD (PX4: MAV_CMD_DO_SET_MODE, custom main mode 6) or GUIDED_NOGPS (ArduPilot: custom mode 20), arm
   (MAV_CMD_COMPONENT_ARM_DISARM), each confirmed by the HEARTBEAT;
4. climb: the agent flies a set point moving from the start to the hover point at ``climb_speed``, then holds
   it ``settle`` seconds; 5. hover: the agent flies ``duration`` seconds at the hover point;
6. land (MAV_CMD_NAV_LAND, streaming stops) and wait until the autopilot disarms (a disarm command once it
   reports it is on the ground).

Each tick (``rate`` Hz, >= 50) turns the latest telemetry into our measurement mapping (:func:`.convert.
measurement_from_telemetry`: the same keys, units and frames as ``info["measurement"]`` of the env) and hands it
to :meth:`Replay.command`, which calls ``agent.act`` exactly as the runner does in simulation (the observer
inside the agent updates on it, with the known inputs of the last command, :attr:`Replay.known_inputs`) and
returns the SET_ATTITUDE_TARGET sent: attitude + thrust for agents that expose an attitude set point (the PX4
cascade, ``px4`` / ``px4+<observer>``: R_d and its collective thrust set point), body rates + thrust for ``ctbr``
agents.  The torque feedforward of ``px4+<observer>`` acts
on our side of the rate loop only; SET_ATTITUDE_TARGET carries no torque, so the autopilot's own rate loop
flies without it.

Trained policies (``sb3:RUN``) get the env's observation, built from the same telemetry measurement by the
env's own law (:func:`fawtgym.envs.observation.hover_observation`; its last-action entries are the policy's
last action, the hover action before the first tick).  A ``ctbr`` policy sends body rates + thrust; a
``residual`` policy on a PX4 base agent sends the base agent's attitude set point with the base's collective
thrust set point plus the residual's change of the motors' collective: the residual's torque, like the
feedforward above, does not reach the autopilot.  A ``motors`` policy (no attitude set point) is refused, and
so is a run trained for another vehicle than the replay's (``vehicle``; the run's vehicle is its training
scenario's, :func:`fawtgym.agents.sb3_agent.run_scenario`).

Safety: heartbeat loss (a heartbeat more than ``heartbeat_timeout``, 1 s, overdue: no HEARTBEAT for
:data:`HEARTBEAT_PERIOD` + ``heartbeat_timeout``; PX4 sends HEARTBEAT at a fixed 1 Hz and refuses
SET_MESSAGE_INTERVAL for it, so a bare 1 s limit aborted a healthy hover against PX4 v1.14.0 SITL on gaps of
1.000-1.011 s), telemetry older than ``telemetry_timeout`` (the fast check of a dead link), Ctrl-C or
any exception stop the setpoint stream, command LAND if the vehicle may be airborne (else disarm) and raise
:class:`~fawtgym.eval.sitl.mavio.SitlError` with the one-line reason.  Everything sent and received goes to
the ``.tlog``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M
from fawtgym.core.checks import check_number, shown
from fawtgym.core.constants import GRAVITY
from fawtgym.core.frames import FAWT_HOVER_POINT_NED, euler_to_rot, rot_to_euler
from fawtgym.envs.ctbr import MAX_RATES
from fawtgym.envs.observation import hover_observation
from fawtgym.envs.options import CONTROL_RATE_RANGE, MAX_EPISODE_SECONDS

from . import convert as C
from .airframe import iris
from .mavio import SitlError, TlogWriter, mavlink_dialect
from .plant import ground_start

MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_PX4, MAV_AUTOPILOT_INVALID = 3, 12, 8
MAV_TYPE_GCS = 6
PX4_MAIN_OFFBOARD = 6
ARDUCOPTER_GUIDED_NOGPS = 20
MAV_CMD_DO_SET_MODE, MAV_CMD_COMPONENT_ARM_DISARM, MAV_CMD_NAV_LAND = 176, 400, 21
MAV_CMD_SET_MESSAGE_INTERVAL = 511
MSG_IDS = {"ATTITUDE_QUATERNION": 31, "LOCAL_POSITION_NED": 32, "HIGHRES_IMU": 105}
#: MAVLink's nominal heartbeat period [s]: PX4 v1.14 sends HEARTBEAT at a constant 1 Hz (mavlink_main.cpp
#: "HEARTBEAT is constant rate stream"; MavlinkReceiver::set_message_interval rejects message 0)
HEARTBEAT_PERIOD = 1.0
ARMED_FLAG, CUSTOM_MODE_FLAG = 128, 1
MAV_LANDED_STATE_ON_GROUND = 1


class SetpointCommand(NamedTuple):
    """One SET_ATTITUDE_TARGET of the replay: ``attitude`` set point R_d (3, 3) body -> NED (None: ignored),
    ``body_rates`` (3,) [rad/s] FRD (None: ignored), ``thrust`` PX4's normalized collective thrust in [0, 1]."""

    attitude: NDArray[np.float64] | None
    body_rates: NDArray[np.float64] | None
    thrust: float


def resolve_agent(name: str, results: str | Path | None = None) -> str:
    """``best`` -> the leaderboard winner of ``results`` (as ``fawtgym leaderboard RESULTS --best``); any other
    name is returned as given (checked by the agent grammar)."""
    if name != "best":
        return name
    if results is None:
        raise ValueError("--agent best needs --results RESULTS (a folder of 'fawtgym eval --out')")
    from fawtgym.eval.leaderboard import best, leaderboard

    return best(leaderboard(Path(results)))


class Replay:
    """One OFFBOARD flight of an agent through an autopilot (see the module docstring).

    Args:
        connect: pymavlink connection string (``udp:127.0.0.1:14540`` listens there).
        agent: an agent-grammar name (``px4``, ``px4+ffts_eso``, ``module:Class``, ``sb3:RUN``).
        vehicle: preset the agent is built for (default ``iris``, the PX4 ``none_iris`` Iris of
            :mod:`.airframe`; or any vehicle preset name, mapping or file); an ``sb3:`` run must have been
            trained for it.
        hover_point: NED set point of the hover, our world frame [m].
        origin: our NED coordinates of the autopilot's local origin [m] (default where ``fawtgym sitl px4``
            starts the vehicle, on the ground below the FAWT hover point).
        rate: setpoint rate [Hz], >= 50; it must divide 1000 (the agent's env physics rate).
    """

    def __init__(self, connect: str, agent: str, *, vehicle: Any = None, hover_point: ArrayLike | None = None,
                 origin: ArrayLike | None = None, rate: float = 100.0, duration: float = 10.0,
                 prestream: float = 1.5, climb_speed: float = 0.5, settle: float = 2.0,
                 heartbeat_timeout: float = 1.0, telemetry_timeout: float = 0.5, connect_timeout: float = 10.0,
                 command_timeout: float = 5.0, land_timeout: float = 30.0, tlog: str | Path | None = None,
                 log: Callable[[str], None] | None = None) -> None:
        from fawtgym.agents.spec import agent_action_type, make_agent, parse_agent
        from fawtgym.envs.hover_env import HoverEnv
        from fawtgym.envs.vehicles import make_vehicle

        rate = check_number(rate, "rate (--rate)", minimum=50.0, inclusive_minimum=True,
                            maximum=CONTROL_RATE_RANGE[1], note="Hz (the SET_ATTITUDE_TARGET stream)")
        prestream = check_number(prestream, "prestream", minimum=1.0, maximum=MAX_EPISODE_SECONDS,
                                 note="s (PX4 wants setpoints before OFFBOARD)")
        for name, value in (("duration (--duration)", duration), ("climb_speed (--climb-speed)", climb_speed),
                            ("heartbeat_timeout (--heartbeat-timeout)", heartbeat_timeout),
                            ("telemetry_timeout (--telemetry-timeout)", telemetry_timeout),
                            ("connect_timeout (--connect-timeout)", connect_timeout),
                            ("command_timeout", command_timeout), ("land_timeout", land_timeout)):
            check_number(value, name, minimum=0.0, maximum=MAX_EPISODE_SECONDS)
        settle = check_number(settle, "settle", minimum=0.0, inclusive_minimum=True, maximum=MAX_EPISODE_SECONDS,
                              note="s")
        self.preset = iris() if vehicle in (None, "iris") else make_vehicle(vehicle)
        self.hover_point = np.array(FAWT_HOVER_POINT_NED if hover_point is None else hover_point, dtype=float)
        self.origin = np.array(ground_start(self.preset) if origin is None else origin, dtype=float)
        for label, v in (("hover_point", self.hover_point), ("origin", self.origin)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"{label} must be 3 finite NED coordinates, got {v.tolist()}")
        spec = parse_agent(agent)
        self.agent_name = spec.name
        self.action_type = agent_action_type(spec)
        self.policy = spec.kind == "sb3"
        if self.policy:
            from fawtgym.agents.sb3_agent import run_scenario

            if spec.target is None:
                raise ValueError(f"agent {shown(spec.name)} names no training run (sb3:RUN)")
            scenario = run_scenario(spec.target)
            trained, self.trained_rate = str(scenario.vehicle), float(scenario.control_rate)
            if trained != self.preset.name:
                raise ValueError(f"agent {shown(spec.name)} was trained for vehicle {shown(trained)}; this replay "
                                 f"flies {shown(self.preset.name)} (--vehicle {trained} with an autopilot flying that "
                                 f"vehicle)")
        self.env = HoverEnv(vehicle=self.preset, action_type=self.action_type, control_rate=rate,
                            setpoint=self.hover_point, sensors="none")
        self.agent = make_agent(spec, self.env)
        # who gives the attitude set point and collective thrust of a motors agent: the PX4 cascade, or a residual
        # policy's PX4 base
        # duck-typed (checked below): a PX4 cascade or a residual policy's PX4 base
        self._attitude_agent: Any = self.agent if hasattr(type(self.agent), "attitude_setpoint") else \
            getattr(self.agent, "base", None)
        if self.action_type != "ctbr" and not (hasattr(type(self._attitude_agent), "attitude_setpoint")
                                                and hasattr(type(self._attitude_agent), "collective_thrust")):
            raise ValueError(f"agent {shown(spec.name)} commands motors and exposes no attitude set point; replay "
                             f"sends SET_ATTITUDE_TARGET, so it flies PX4-cascade agents (px4, px4+<observer>), ctbr "
                             "agents and policies (ctbr, or residual on a PX4 base)")
        obs_space = self.env.observation_space
        if not isinstance(obs_space, spaces.Box):
            raise ValueError(f"the env's observation space must be a Box, got {type(obs_space).__name__}")
        self._obs_low = obs_space.low.astype(float)
        self._obs_high = obs_space.high.astype(float)
        # one step on the env's own start state before any link is open: the first call of a policy (torch's lazy
        # initialisation) or an observer took ~0.4 s, a hole in the setpoint stream when the agent takes over; the
        # first telemetry tick resets the agent again
        warm_obs, warm_info = self.env.reset(seed=0)
        self.agent.reset(warm_info, seed=0)
        self.agent.act(warm_obs, warm_info)
        self.begin_flight()
        self.connect, self.rate, self.dt = connect, float(rate), self.env.dt
        self.duration, self.prestream, self.climb_speed, self.settle = duration, prestream, climb_speed, settle
        self.heartbeat_timeout, self.telemetry_timeout = heartbeat_timeout, telemetry_timeout
        self.connect_timeout, self.command_timeout, self.land_timeout = connect_timeout, command_timeout, land_timeout
        self.tlog_path = Path(tlog) if tlog else None
        self.log = log or (lambda text: None)
        self.sent_setpoints: list[float] = []  # monotonic send times
        self.autopilot = MAV_AUTOPILOT_PX4
        self.imu_type = "HIGHRES_IMU"
        self.phase = "connect"
        self.bad_bytes = 0

    # ---- messages -----------------------------------------------------------------------------------------
    def _open(self) -> None:
        os.environ.setdefault("MAVLINK20", "1")
        mavlink_dialect()
        from pymavlink import mavutil

        try:
            self.conn = mavutil.mavlink_connection(self.connect, source_system=245, source_component=191,
                                                   dialect="common", autoreconnect=False)
        except Exception as exc:  # pymavlink raises bare Exceptions/OSErrors for bad addresses
            raise SitlError(f"cannot open {shown(self.connect)}: {exc}") from None
        self.tlog = TlogWriter(self.tlog_path) if self.tlog_path else None
        self.last: dict[str, Any] = {}
        self.last_time: dict[str, float] = {}
        self.target: tuple[int, int] | None = None
        self.acks: dict[int, int] = {}

    def _send(self, msg: Any) -> None:
        self.conn.mav.send(msg)
        if self.tlog is not None:
            self.tlog.write(msg)

    def _pump(self) -> None:
        """Read every message waiting (non-blocking), remember the latest of each type, record to the tlog."""
        while True:
            msg = self.conn.recv_match(blocking=False)
            if msg is None:
                return
            kind = msg.get_type()
            if kind == "BAD_DATA":
                self.bad_bytes += len(msg.get_msgbuf() or b"")
                continue
            if self.tlog is not None:
                self.tlog.write(msg)
            if kind == "HEARTBEAT":
                if msg.type == MAV_TYPE_GCS or msg.autopilot == MAV_AUTOPILOT_INVALID:
                    continue
                if self.target is None:
                    self.target = (msg.get_srcSystem(), msg.get_srcComponent())
                    self.autopilot = int(msg.autopilot)
                elif (msg.get_srcSystem(), msg.get_srcComponent()) != self.target:
                    continue
            elif kind == "COMMAND_ACK":
                self.acks[msg.command] = msg.result
            self.last[kind] = msg
            self.last_time[kind] = time.monotonic()

    def _autopilot(self) -> tuple[int, int]:
        """(system, component) ids of the autopilot; SitlError before its first heartbeat."""
        if self.target is None:
            raise SitlError("no heartbeat from an autopilot yet")
        return self.target

    def _command(self, command: int, *params: float) -> None:
        p = [float(x) for x in params] + [0.0] * (7 - len(params))
        sysid, compid = self._autopilot()
        self._send(self.conn.mav.command_long_encode(sysid, compid, command, 0, *p))

    def _garbage_note(self) -> str:
        return f" ({self.bad_bytes} bytes received were not valid MAVLink)" if self.bad_bytes else ""

    # ---- state of the autopilot ---------------------------------------------------------------------------
    @property
    def armed(self) -> bool:
        hb = self.last.get("HEARTBEAT")
        return bool(hb is not None and hb.base_mode & ARMED_FLAG)

    @property
    def in_offboard(self) -> bool:
        hb = self.last.get("HEARTBEAT")
        if hb is None or not hb.base_mode & CUSTOM_MODE_FLAG:
            return False
        if self.autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA:
            return hb.custom_mode == ARDUCOPTER_GUIDED_NOGPS
        return (hb.custom_mode >> 16) & 0xFF == PX4_MAIN_OFFBOARD

    def _check_health(self) -> None:
        now = time.monotonic()
        age = now - self.last_time.get("HEARTBEAT", now)
        if age > HEARTBEAT_PERIOD + self.heartbeat_timeout:
            raise SitlError(f"heartbeat lost: none from the autopilot for {age:.1f} s (its {HEARTBEAT_PERIOD:g} s "
                            f"period + {self.heartbeat_timeout:g} s) during {self.phase}{self._garbage_note()}")
        if self.phase in ("prestream", "climb", "hover"):
            for kind in ("ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", self.imu_type):
                age = now - self.last_time.get(kind, now)
                if age > self.telemetry_timeout:
                    raise SitlError(f"telemetry timeout: no {kind} for {age:.2f} s (limit "
                                    f"{self.telemetry_timeout:g} s) during {self.phase}")

    # ---- the flight ---------------------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        """Fly; returns a summary.  Raises SitlError (after stopping the stream and commanding LAND or disarm)."""
        self._open()
        try:
            self._fly()
        except KeyboardInterrupt:
            self._abort("interrupted (Ctrl-C)")
        except SitlError as exc:
            self._abort(str(exc))
        except Exception as exc:  # an agent or conversion error: stop the vehicle safely, then report
            self._abort(f"{type(exc).__name__}: {' '.join(str(exc).split())}")
        finally:
            if self.tlog is not None:
                self.tlog.close()
            self.conn.close()
        sent = np.asarray(self.sent_setpoints)
        gaps = np.diff(sent) if sent.size > 1 else np.array([0.0])
        return {"agent": self.agent_name, "setpoints": int(sent.size),
                "setpoint_rate_hz": float((sent.size - 1) / (sent[-1] - sent[0])) if sent.size > 1 else 0.0,
                "max_gap_s": float(gaps.max()), "final_position_error": self.final_error,
                "tlog": str(self.tlog_path) if self.tlog_path else None}

    def _abort(self, reason: str) -> None:
        phase = self.phase
        self.phase = "abort"
        try:
            if self.target is not None and phase in ("climb", "hover", "land"):
                for _ in range(3):
                    self._command(MAV_CMD_NAV_LAND)
                    time.sleep(0.05)
                action = "LAND commanded"
            elif self.target is not None and phase in ("prestream", "arm"):
                self._command(MAV_CMD_COMPONENT_ARM_DISARM, 0.0)
                action = "disarm commanded"
            else:
                action = "nothing was armed"
        except Exception as exc:  # the link itself may be gone; the reason below still stands
            action = f"could not command LAND/disarm ({exc})"
        raise SitlError(f"replay aborted: {reason}; setpoint stream stopped, {action}")

    def _wait(self, what: str, timeout: float, done: Callable[[], bool]) -> None:
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                raise SitlError(f"{what} within {timeout:g} s{self._garbage_note()}")
            self._pump()
            if self.target is not None:
                self._check_health()
            time.sleep(0.005)

    def _fly(self) -> None:
        self._wait(f"no heartbeat from an autopilot on {self.connect}", self.connect_timeout,
                   lambda: self.target is not None)
        sysid, compid = self._autopilot()
        self.log(f"autopilot {sysid}/{compid} ({'ArduPilot' if self.autopilot == 3 else 'PX4'})")
        if self.policy and self.trained_rate != self.rate:
            self.log(f"note: the policy was trained at {self.trained_rate:g} Hz and flies at {self.rate:g} Hz "
                     f"(--rate)")
        for msg_id in MSG_IDS.values():
            self._command(MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / self.rate)
        self.phase = "telemetry"
        self._wait("no ATTITUDE_QUATERNION, LOCAL_POSITION_NED and HIGHRES_IMU/SCALED_IMU telemetry",
                   self.command_timeout, lambda: self._telemetry_ready())
        self.imu_type = "HIGHRES_IMU" if "HIGHRES_IMU" in self.last else "SCALED_IMU"
        yaw = float(rot_to_euler(self._measurement()["attitude"])[2])
        neutral = SetpointCommand(euler_to_rot(0.0, 0.0, yaw), None, 0.0)
        self.phase = "prestream"
        self._stream(self.prestream, lambda t: neutral)
        mode = "GUIDED_NOGPS" if self.autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA else "OFFBOARD"
        custom = ARDUCOPTER_GUIDED_NOGPS if self.autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA else PX4_MAIN_OFFBOARD
        self._stream(self.command_timeout, lambda t: neutral, until=lambda: self.in_offboard,
                     every=(0.5, lambda: self._command(MAV_CMD_DO_SET_MODE, CUSTOM_MODE_FLAG, custom)),
                     fail=f"the autopilot did not switch to {mode}")
        self.phase = "arm"
        self._stream(self.command_timeout, lambda t: neutral, until=lambda: self.armed,
                     every=(0.5, lambda: self._command(MAV_CMD_COMPONENT_ARM_DISARM, 1.0)),
                     fail="the autopilot did not arm")
        self.log(f"{mode}, armed; climbing to {self.hover_point.tolist()}")
        self.phase = "climb"
        start = self._measurement()["position"].copy()
        distance = float(np.linalg.norm(self.hover_point - start))
        ramp = distance / self.climb_speed
        self.begin_flight()

        def climb_sp(t: float) -> NDArray[np.float64]:
            return start + (self.hover_point - start) * min(1.0, t / ramp) if ramp > 0 else self.hover_point

        self._stream(ramp + self.settle, lambda t: self.command(self._measurement(), climb_sp(t)))
        self.phase = "hover"
        self._stream(self.duration, lambda t: self.command(self._measurement(), self.hover_point))
        self.final_error = float(np.linalg.norm(self._measurement()["position"] - self.hover_point))
        self.phase = "land"
        self.log(f"landing (position error at the end of the hover {self.final_error:.3f} m)")
        self._land()

    final_error: float | None = None

    def _telemetry_ready(self) -> bool:
        return all(k in self.last for k in ("ATTITUDE_QUATERNION", "LOCAL_POSITION_NED")) and \
            ("HIGHRES_IMU" in self.last or "SCALED_IMU" in self.last)

    def _measurement(self) -> dict[str, NDArray[np.float64]]:
        return C.measurement_from_telemetry(self.last["ATTITUDE_QUATERNION"], self.last["LOCAL_POSITION_NED"],
                                            self.last[self.imu_type], self.origin, time.monotonic())

    def _stream(self, seconds: float, target: Callable[[float], SetpointCommand],
                until: Callable[[], bool] | None = None, every: tuple[float, Callable[[], None]] | None = None,
                fail: str | None = None) -> None:
        """Send setpoints at ``rate`` for ``seconds`` (or until ``until()``; then ``fail`` if it never held)."""
        t0 = time.monotonic()
        next_every = t0
        k = 0
        while True:
            self._pump()
            self._check_health()
            now = time.monotonic()
            if until is not None and until():
                return
            if now - t0 >= seconds:
                if until is not None:
                    raise SitlError(f"{fail} within {seconds:g} s (last COMMAND_ACK results: {self.acks or 'none'})")
                return
            if every is not None and now >= next_every:
                every[1]()
                next_every = now + every[0]
            attitude, rates, thrust = target(k * self.dt)
            boot_ms = int((now - t0) * 1000)
            fields = C.attitude_target_fields(attitude=attitude, body_rates=rates, thrust=thrust,
                                              time_boot_ms=boot_ms, target_system=self._autopilot()[0],
                                              target_component=self._autopilot()[1])
            self._send(self.conn.mav.set_attitude_target_encode(**fields))
            self.sent_setpoints.append(now)
            k += 1
            sleep = t0 + k * self.dt - time.monotonic()
            if sleep > 0:
                time.sleep(sleep)

    def observation(self, measurement: Mapping[str, Any], setpoint: ArrayLike, last_action: ArrayLike
                    ) -> NDArray[np.float32]:
        """The env observation (19,) of a policy for one telemetry measurement (:func:`~fawtgym.envs.observation.
        hover_observation`, the env's law and bounds); ``last_action``: the policy's last action (the box clips it
        to the action space, as the env clips what it applies)."""
        rows = {k: np.asarray(measurement[k], dtype=float)[None] for k in (M.POSITION, M.VELOCITY, M.ATTITUDE,
                                                                          M.ANGULAR_VELOCITY)}
        return hover_observation(rows, np.asarray(setpoint, dtype=float)[None],
                                 np.asarray(last_action, dtype=float).reshape(1, 4), self._obs_low, self._obs_high)[0]

    def begin_flight(self) -> None:
        """Start a new flight of the agent: the next :meth:`command` resets it on its measurement, with the
        hover thrust and no torque as its known inputs and the hover action as a policy's last action."""
        self._first = True
        self._known: tuple[float, NDArray[np.float64]] | None = None
        self._last_action = np.asarray(self.env.hover_action(), dtype=float)

    @property
    def known_inputs(self) -> dict[str, Any]:
        """The known inputs ``{"thrust": collective [N], "torque": (3,) [N m]}`` (the env's ``info["applied"]``)
        the agent's observer gets with the next :meth:`command`: those of the last command sent (the thrust
        sent, our rate loop's torque), or the hover thrust and no torque at the start of a flight."""
        if self._known is None:
            return {"thrust": self.preset.mass * GRAVITY, "torque": np.zeros(3)}
        return {"thrust": self._known[0], "torque": self._known[1].copy()}

    def command(self, measurement: Mapping[str, Any], setpoint: ArrayLike) -> SetpointCommand:
        """One agent step: the measurement of one telemetry tick (:func:`.convert.measurement_from_telemetry`)
        and the NED set point [m] -> the SET_ATTITUDE_TARGET the replay sends for it.  The flight loop calls it
        on every tick of the climb and the hover (after :meth:`begin_flight`)."""
        meas = dict(measurement)
        applied = self.known_inputs
        setpoint_ned = np.asarray(setpoint, dtype=float)
        info = {"measurement": meas, "applied": applied, "setpoint": setpoint_ned}
        if self._first:
            self.agent.reset(info, seed=0)
            self._first = False
        obs = self.observation(meas, setpoint_ned, self._last_action) if self.policy else None
        action = np.asarray(self.agent.act(obs, info), dtype=float).reshape(-1)
        if not np.all(np.isfinite(action)):
            raise SitlError(f"agent {shown(self.agent_name)} returned a non-finite action {action.tolist()}")
        self._last_action = action
        if self.action_type == "ctbr":
            collective = float(np.clip(action[0], 0.0, 1.0)) * 4.0 * self.preset.max_thrust_per_rotor
            self._known = (collective, np.zeros(3))
            return SetpointCommand(None, np.clip(action[1:4], -1.0, 1.0) * MAX_RATES,
                                   C.px4_thrust(self.preset, collective))
        # The thrust sent is the cascade's collective set point, not the collective of its motor commands: those
        # come from its own rate loop and allocator, which cut the collective when the torque saturates (PX4's
        # allocator does the same on PX4's side).  In the hand test against PX4 v1.14.0 the observer's torque
        # estimate saturated our (unused) rate loop, pinned the motor-derived thrust at 0.68 and the vehicle sank
        # 1.3 m while the set point asked for full thrust.  The torque of our rate loop stays the observer's known
        # torque input (PX4 flies its own rate loop; SET_ATTITUDE_TARGET carries no torque).
        collective = float(np.asarray(self._attitude_agent.collective_thrust, dtype=float).reshape(-1)[0])
        base_action = getattr(self.agent, "last_base_action", None)
        if base_action is not None:  # a residual policy: its change of the motors' collective rides on the set point
            collective += C.applied_from_motors(self.preset, action)[0] - \
                C.applied_from_motors(self.preset, np.asarray(base_action, dtype=float).reshape(-1))[0]
        _, torque = C.applied_from_motors(self.preset, action)
        self._known = (collective, np.asarray(torque, dtype=float))
        attitude = np.asarray(self._attitude_agent.attitude_setpoint, dtype=float).reshape(-1, 3, 3)[0]
        return SetpointCommand(attitude, None, C.px4_thrust(self.preset, collective))

    def _land(self) -> None:
        t0 = time.monotonic()
        next_command = 0.0
        while self.armed:
            now = time.monotonic()
            if now - t0 > self.land_timeout:
                raise SitlError(f"the autopilot was still armed {self.land_timeout:g} s after LAND")
            self._pump()
            self._check_health()
            if now >= next_command:
                ext = self.last.get("EXTENDED_SYS_STATE")
                if ext is not None and ext.landed_state == MAV_LANDED_STATE_ON_GROUND and now - t0 > 1.0:
                    self._command(MAV_CMD_COMPONENT_ARM_DISARM, 0.0)
                elif self.acks.get(MAV_CMD_NAV_LAND) != 0:
                    self._command(MAV_CMD_NAV_LAND)
                next_command = now + 0.5
            time.sleep(0.01)
        self.log("disarmed")
