"""Command lines of the SITL hook: ``fawtgym sitl px4`` (the bridge) and ``fawtgym replay`` (the OFFBOARD client).

Usage errors are one line and exit 2 (:class:`fawtgym.cli_parser.ArgumentParser`); a run that stops (no PX4,
a disconnect, heartbeat loss, an abort) prints one line ``<prog>: <reason>`` on stderr and exits 1.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

from fawtgym.cli_parser import (
    ArgumentParser,
    bounded_int,
    check_output_dir,
    check_output_file,
    nonnegative_float,
    seed,
)
from fawtgym.core.checks import shown

from .mavio import SitlError

DEFAULT_CONNECT = "udp:127.0.0.1:14540"


def _vector(text: str, what: str) -> list[float]:
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 3 or not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be three numbers N,E,D [m], got {shown(text)}")
    return v


def _wind_spec(name: str) -> Any:
    """A wind preset name, or a scenario name whose wind (with its fan schedule) is used."""
    from fawtgym.envs.wind import wind_names
    from fawtgym.eval.scenarios import get_scenario, scenario_names

    if name in wind_names():
        return name
    if name in scenario_names():
        return get_scenario(name).wind
    raise ValueError(f"unknown --wind {shown(name)}; wind presets: {', '.join(wind_names())}; or a scenario: "
                     f"{', '.join(scenario_names())}")


_LINK_KINDS = ("udp", "udpin", "udpout", "udpbcast", "tcp", "tcpin")


def connect_address(text: str) -> str:
    """A pymavlink connection string: ``KIND:HOST:PORT`` (KIND one of :data:`_LINK_KINDS`) or a serial device."""
    kind, _, rest = text.partition(":")
    if kind in _LINK_KINDS:
        host, _, port = rest.rpartition(":")
        if host and port.isdigit() and 0 < int(port) < 65536:
            return text
    elif text.startswith("/dev/") or text.upper().startswith("COM"):
        return text
    raise argparse.ArgumentTypeError(f"expected {', '.join(k + ':HOST:PORT' for k in _LINK_KINDS)} or a serial device "
                                     f"(/dev/..., COMn), got {shown(text)}")


def _replay_args(parser: ArgumentParser, connect_default: str | None) -> None:
    g = parser.add_argument_group("replay (OFFBOARD agent)")
    g.add_argument("--connect", default=connect_default, type=connect_address,
                   help=f"autopilot MAVLink address, pymavlink syntax (default {DEFAULT_CONNECT}: PX4 SITL's offboard "
                        "link; udp: listens)")
    g.add_argument("--agent", default=None, required=connect_default is not None,
                   help="agent-grammar name (px4, px4+ffts_eso, ...) or 'best' (the winner of --results)")
    g.add_argument("--results", default=None, help="results folder of 'fawtgym eval' (for --agent best)")
    g.add_argument("--duration", type=float, default=10.0, help="hover time at the hover point [s] (default 10)")
    g.add_argument("--rate", type=float, default=100.0, help="SET_ATTITUDE_TARGET rate [Hz], >= 50 (default 100)")
    g.add_argument("--hover-point", default=None, metavar="N,E,D",
                   help="hover set point in our NED frame [m] (default the FAWT hover point 1.5,0,-1.5)")
    g.add_argument("--origin", default=None, metavar="N,E,D",
                   help="our NED coordinates of the autopilot's local origin (default: where 'sitl px4' starts "
                        "the vehicle)")
    g.add_argument("--climb-speed", type=float, default=0.5, help="set point speed from the start to the hover "
                                                                   "point [m/s] (default 0.5)")
    g.add_argument("--tlog", default="replay.tlog", help="MAVLink log of the replay (default replay.tlog)")
    g.add_argument("--heartbeat-timeout", type=float, default=1.0, help="abort when a heartbeat is this much "
                   "overdue [s], i.e. none for 1 s (MAVLink's heartbeat period, fixed in PX4) + this (default 1)")
    g.add_argument("--telemetry-timeout", type=float, default=0.5, help="abort after this long without telemetry "
                                                                       "[s] (default 0.5)")
    g.add_argument("--connect-timeout", type=float, default=30.0, help="wait this long for the first heartbeat "
                                                                      "[s] (default 30)")


def _make_replay(parser: ArgumentParser, ns: Any, connect: str, log: Any) -> Any:
    from .replay import Replay, resolve_agent

    try:
        agent = resolve_agent(ns.agent, ns.results)
        return Replay(connect, agent, vehicle=getattr(ns, "vehicle", None),  # sitl px4 flies the Iris only
                      hover_point=None if ns.hover_point is None else _vector(ns.hover_point, "--hover-point"),
                      origin=None if ns.origin is None else _vector(ns.origin, "--origin"),
                      rate=ns.rate, duration=ns.duration, climb_speed=ns.climb_speed, tlog=ns.tlog or None,
                      heartbeat_timeout=ns.heartbeat_timeout, telemetry_timeout=ns.telemetry_timeout,
                      connect_timeout=ns.connect_timeout, log=log)
    except (ValueError, ImportError) as exc:
        parser.error(" ".join(str(exc).split()))


def replay_main(argv: Sequence[str]) -> int:
    """``fawtgym replay``: fly an agent through an autopilot in OFFBOARD (see fawtgym.eval.sitl.replay)."""
    parser = ArgumentParser(prog="fawtgym replay", description="Fly an agent (or the leaderboard winner) through a "
                            "real autopilot over MAVLink: OFFBOARD, arm, climb, hover on SET_ATTITUDE_TARGET, land; "
                            "everything in a .tlog.")
    _replay_args(parser, DEFAULT_CONNECT)
    parser.add_argument("--vehicle", default="iris", help="vehicle preset the agent is built for (default iris, "
                        "the PX4 none_iris Iris that 'fawtgym sitl px4' flies; s500, x500, ... or a .yaml/.json "
                        "file for an autopilot flying that vehicle); an sb3: policy must have been trained for it")
    ns = parser.parse_args(list(argv))
    check_output_file(parser, "--tlog", ns.tlog or None, (".tlog",))  # before the wait for the autopilot
    log = lambda text: print(f"replay: {text}", flush=True)
    replay = _make_replay(parser, ns, ns.connect, log)
    log(f"agent {replay.agent_name} on {ns.connect}, hover point {replay.hover_point.tolist()}, "
        f"{ns.rate:g} Hz setpoints, tlog {ns.tlog}")
    try:
        summary = replay.run()
    except SitlError as exc:
        print(f"fawtgym replay: {exc}", file=sys.stderr)
        return 1
    log(json.dumps(summary))
    return 0


def sitl_main(argv: Sequence[str]) -> int:
    """``fawtgym sitl px4``: our env as PX4's simulator (see fawtgym.eval.sitl.bridge)."""
    parser = ArgumentParser(prog="fawtgym sitl", description="Our env as an autopilot's simulator over MAVLink. "
                            "'px4': PX4's simulator_mavlink TCP interface (HIL_SENSOR/HIL_GPS out, "
                            "HIL_ACTUATOR_CONTROLS in, lockstep); airframe 10016 none_iris. See docs/sitl.md.")
    parser.add_argument("autopilot", choices=["px4"], help="the autopilot to simulate for")
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    parser.add_argument("--port", type=bounded_int(0, 65535), default=4560,
                        help="TCP port PX4 connects to (default 4560)")
    parser.add_argument("--wind", default="calm", help="wind preset (fawt-50, dryden-moderate, ...) or a scenario "
                                                       "name whose wind and fan schedule are used (table4-50, ...)")
    parser.add_argument("--sensors", default="seed000", help="env sensor preset for the IMU/GPS noise (default "
                                                             "seed000; its pose rate must divide 250 Hz)")
    parser.add_argument("--seed", type=seed, default=0, help="seed of the wind and sensor noise (default 0)")
    parser.add_argument("--baro-noise", type=nonnegative_float, default=None, metavar="PA",
                        help="barometer white noise [Pa RMS] (default 1, as Gazebo; 0 makes PX4 flag it STALE)")
    parser.add_argument("--home", default=None, metavar="LAT,LON,ALT",
                        help="where our NED origin is (default PX4's SITL home 47.397742,8.545594,488)")
    parser.add_argument("--start", default=None, metavar="N,E,D",
                        help="initial CoM position [m] (default on the ground below the FAWT hover point)")
    parser.add_argument("--realtime", action="store_true", help="pace the simulation to the wall clock (default: "
                                                                "as fast as both sides go)")
    parser.add_argument("--sim-duration", type=float, default=None, help="stop after this many simulated seconds")
    parser.add_argument("--bridge-tlog", default=None, help="write the bridge's MAVLink traffic to this .tlog")
    parser.add_argument("--log", default=None, metavar="DIR", help="write config.json and truth.csv here")
    parser.add_argument("--accept-timeout", type=float, default=300.0,
                        help="wait this long for PX4 to connect [s] (default 300)")
    parser.add_argument("--actuator-timeout", type=float, default=5.0,
                        help="in lockstep, wait this long for PX4's answer to a sample [s] (default 5)")
    _replay_args(parser, None)
    ns = parser.parse_args(list(argv))
    for flag, path in (("--bridge-tlog", ns.bridge_tlog), ("--tlog", ns.tlog if ns.agent is not None else None)):
        check_output_file(parser, flag, path or None, (".tlog",))  # before the wait for PX4
    check_output_dir(parser, "--log", ns.log)
    from .bridge import Px4Bridge, check_sim_duration
    from .convert import BARO_NOISE_PA, Home, parse_home
    from .plant import SitlVehicle

    log = lambda text: print(f"sitl px4: {text}", flush=True)
    try:
        if ns.sim_duration is not None:
            check_sim_duration(ns.sim_duration)
        wind = _wind_spec(ns.wind)
        home = Home() if ns.home is None else parse_home(ns.home)
        start = None if ns.start is None else _vector(ns.start, "--start")
        if not 0 <= ns.port < 65536:
            raise ValueError(f"--port must be in 0-65535 (0: a free port, printed), got {ns.port}")
        vehicle = SitlVehicle(wind=wind, sensors=ns.sensors, start=start, seed=ns.seed)
        replay = None
        if ns.agent is not None:  # PX4 starts after the bridge: the replay waits for its heartbeat as long
            ns.connect_timeout = max(ns.connect_timeout, ns.accept_timeout + 60.0)
            replay = _make_replay(parser, ns, ns.connect or DEFAULT_CONNECT, lambda t: print(f"replay: {t}",
                                                                                             flush=True))
        bridge = Px4Bridge(vehicle, home, ns.host, ns.port, realtime=ns.realtime or replay is not None,
                           accept_timeout=ns.accept_timeout, actuator_timeout=ns.actuator_timeout,
                           baro_noise=BARO_NOISE_PA if ns.baro_noise is None else ns.baro_noise, seed=ns.seed,
                           tlog=ns.bridge_tlog, log_dir=ns.log, log=log)
    except ValueError as exc:
        parser.error(" ".join(str(exc).split()))
    except SitlError as exc:
        print(f"fawtgym sitl: {exc}", file=sys.stderr)
        return 1
    config = bridge.describe(wind, ns.sensors, ns.seed)
    bridge.write_config(config)
    log(f"vehicle {config['vehicle']} (PX4 airframe 10016 none_iris), wind {json.dumps(wind)}, sensors "
        f"{ns.sensors}, home {home.lat:.6f},{home.lon:.6f},{home.alt:g}, start {config['start_ned']}")
    log(f"listening on {bridge.host}:{bridge.port}; now start PX4: PX4_SYS_AUTOSTART=10016 PX4_SIM_MODEL=none_iris "
        "build/px4_sitl_default/bin/px4 (docs/sitl.md)")
    if replay is None:
        try:
            summary = bridge.serve(ns.sim_duration)
        except SitlError as exc:
            print(f"fawtgym sitl: {exc}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            print(f"fawtgym sitl: interrupted after {bridge.steps} steps", file=sys.stderr)
            return 1
        log(json.dumps(summary))
        return 0
    errors: list[str] = []

    def serve() -> None:
        try:
            bridge.serve(ns.sim_duration)
        except SitlError as exc:
            errors.append(str(exc))

    thread = threading.Thread(target=serve, name="px4-bridge", daemon=True)
    thread.start()
    try:
        summary = replay.run()
    except SitlError as exc:
        print(f"fawtgym sitl: {exc}" + (f" (bridge: {errors[0]})" if errors else ""), file=sys.stderr)
        return 1
    finally:
        bridge.stop()
        thread.join(timeout=ns.actuator_timeout + 1.0)
    log(json.dumps(summary))
    return 0
