"""Test peers for the SITL hook, written from the MAVLink spec (common.xml) and PX4's documented behaviour with
pymavlink alone: nothing here imports fawtgym.

* :class:`Px4SimPeer`: the PX4 side of ``simulator_mavlink`` (TCP client; HEARTBEAT and SET_MESSAGE_INTERVAL for
  HIL_STATE_QUATERNION on connect; one HIL_ACTUATOR_CONTROLS per HIL_SENSOR, ``mode`` 129 when armed).
* :class:`AutopilotPeer`: a PX4-like autopilot on a UDP link (HEARTBEAT 10 Hz with PX4 custom modes, telemetry at
  100 Hz, COMMAND_LONG handling for SET_MESSAGE_INTERVAL / DO_SET_MODE / ARM_DISARM / NAV_LAND, OFFBOARD only
  after a second of SET_ATTITUDE_TARGET), recording what it receives.
"""

from __future__ import annotations

import math
import select
import socket
import threading
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager

from pymavlink.dialects.v20 import common as mavlink

#: Gazebo-classic Iris (PX4-SITL_gazebo-classic models/iris): link masses, motorConstant, speed = 100 + 1000 u
IRIS_MASS = 1.5 + 4 * 0.005 + 0.015 + 0.01
IRIS_MOTOR_CONSTANT = 5.84e-6
G = 9.80665
#: PX4 10016_none_iris: CA_ROTORn_PX, CA_ROTORn_PY, sign of CA_ROTORn_KM (+ = CCW seen from above), n = 0..3
NONE_IRIS_CA = ((0.1515, 0.245, 1), (-0.1515, -0.1875, 1), (0.1515, -0.245, -1), (-0.1515, 0.1875, -1))


def iris_hover_control() -> float:
    """The motor control u that holds the Iris: k_T (100 + 1000 u)^2 = m g / 4."""
    return (math.sqrt(IRIS_MASS * G / (4 * IRIS_MOTOR_CONSTANT)) - 100.0) / 1000.0


class Px4SimPeer:
    """PX4's simulator_mavlink side, connecting to a simulator on ``port``."""

    def __init__(self, port: int, timeout: float = 5.0) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.pending: deque = deque()
        self.seen: list = []

    def send(self, msg) -> None:
        self.sock.sendall(msg.pack(self.mav))

    def hello(self, interval_us: int = 5000) -> None:
        self.send(mavlink.MAVLink_heartbeat_message(2, 12, 0, 0, 3, 3))
        self.send(mavlink.MAVLink_command_long_message(0, 0, 511, 0, 115, interval_us, 0, 0, 0, 0, 0))

    def _read(self, timeout: float) -> bool:
        ready, _, _ = select.select([self.sock], [], [], max(0.0, timeout))
        if not ready:
            return False
        data = self.sock.recv(65536)
        if not data:
            raise ConnectionError("simulator closed the connection")
        for msg in self.mav.parse_buffer(data) or []:
            if msg.get_type() != "BAD_DATA":
                self.pending.append(msg)
        return True

    def recv(self, timeout: float):
        deadline = time.monotonic() + timeout
        while not self.pending:
            if not self._read(deadline - time.monotonic()) and time.monotonic() >= deadline:
                return None
        msg = self.pending.popleft()
        self.seen.append(msg)
        return msg

    def next_sensor(self, timeout: float = 5.0):
        deadline = time.monotonic() + timeout
        while True:
            msg = self.recv(deadline - time.monotonic())
            if msg is None:
                raise TimeoutError("no HIL_SENSOR from the simulator")
            if msg.get_type() == "HIL_SENSOR":
                return msg

    def quiet_for(self, seconds: float) -> list:
        """Everything that arrives in the next ``seconds`` (without answering)."""
        deadline, got = time.monotonic() + seconds, []
        while time.monotonic() < deadline:
            self._read(deadline - time.monotonic())
        while self.pending:
            got.append(self.pending.popleft())
        self.seen.extend(got)
        return got

    def answer(self, sensor, controls=(0.0, 0.0, 0.0, 0.0), armed: bool = False) -> None:
        c = list(controls) + [0.0] * (16 - len(controls))
        self.send(mavlink.MAVLink_hil_actuator_controls_message(sensor.time_usec, c, 129 if armed else 1, 1))

    def close(self) -> None:
        self.sock.close()


class AutopilotPeer(threading.Thread):
    """A PX4-like autopilot talking UDP to a companion listening on ``companion_port``."""

    def __init__(self, companion_port: int, stop_heartbeat_after_arm: float | None = None,
                 stop_telemetry_after_arm: float | None = None, garbage_only: bool = False,
                 ardupilot: bool = False, lifetime: float = 20.0) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.dest = ("127.0.0.1", companion_port)
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True
        self.hb_stop, self.tm_stop, self.garbage_only = stop_heartbeat_after_arm, stop_telemetry_after_arm, garbage_only
        self.lifetime = lifetime
        # PX4: autopilot 12, OFFBOARD = custom main mode 6 (custom_mode bits 16-23), AUTO.LAND main 4 sub 6;
        # ArduCopter: autopilot 3, GUIDED_NOGPS = custom_mode 20, LAND = 9
        self.autopilot = 3 if ardupilot else 12
        self.offboard_mode = 20 if ardupilot else 6 << 16
        self.land_mode = 9 if ardupilot else (4 << 16) | (6 << 24)
        self.events: list[tuple[float, str, object]] = []  # (time, what, detail)
        self.setpoints: list[tuple[float, object]] = []
        self.armed, self.custom_mode, self.landed_state = False, 0, 1  # on the ground
        self.arm_time = self.land_time = None
        self.stop_event = threading.Event()

    def send(self, msg) -> None:
        try:
            self.sock.sendto(msg.pack(self.mav), self.dest)
        except OSError:
            pass

    def _handle(self, msg, now: float) -> None:
        kind = msg.get_type()
        if kind == "SET_ATTITUDE_TARGET":
            self.setpoints.append((now, msg))
            return
        if kind != "COMMAND_LONG":
            return
        self.events.append((now, f"cmd{msg.command}", (msg.param1, msg.param2)))
        result = 0
        if msg.command == 176:  # DO_SET_MODE: OFFBOARD needs a second of setpoints first (PX4)
            streamed = [t for t, _ in self.setpoints]
            wanted = 20 if self.autopilot == 3 else 6
            if int(msg.param2) == wanted and streamed and now - streamed[0] >= 1.0 and now - streamed[-1] < 0.5:
                self.custom_mode = self.offboard_mode
            else:
                result = 1  # TEMPORARILY_REJECTED
        elif msg.command == 400:
            if msg.param1 == 1 and self.custom_mode == self.offboard_mode:
                self.armed, self.arm_time = True, now
            elif msg.param1 == 0:
                self.armed = False
            else:
                result = 1
        elif msg.command == 21:  # NAV_LAND -> the autopilot's land mode
            self.custom_mode = self.land_mode
            self.land_time = self.land_time or now
        self.send(mavlink.MAVLink_command_ack_message(msg.command, result))

    def run(self) -> None:
        t0 = time.monotonic()
        next_hb = next_tm = t0
        while not self.stop_event.is_set() and time.monotonic() - t0 < self.lifetime:
            now = time.monotonic()
            if self.garbage_only:
                self.sock.sendto(bytes((i * 37 + 11) % 251 for i in range(200)), self.dest)
                time.sleep(0.02)
                continue
            ready, _, _ = select.select([self.sock], [], [], 0.002)
            if ready:
                data, _ = self.sock.recvfrom(65536)
                for msg in self.mav.parse_buffer(data) or []:
                    if msg.get_type() != "BAD_DATA":
                        self._handle(msg, now)
            if self.land_time is not None and now - self.land_time > 0.3:
                self.landed_state = 1
                if now - self.land_time > 0.6:
                    self.armed = False
            elif self.armed:
                self.landed_state = 2  # in air
            since_arm = None if self.arm_time is None else now - self.arm_time
            if now >= next_hb:
                next_hb = now + 1.0  # PX4: HEARTBEAT at a constant 1 Hz (it refuses SET_MESSAGE_INTERVAL for it)
                if self.hb_stop is None or since_arm is None or since_arm < self.hb_stop:
                    base = 1 | (128 if self.armed else 0)
                    self.send(mavlink.MAVLink_heartbeat_message(2, self.autopilot, base, self.custom_mode, 4, 3))
                    self.send(mavlink.MAVLink_extended_sys_state_message(0, self.landed_state))
            if now >= next_tm:
                next_tm = now + 0.01
                if self.tm_stop is None or since_arm is None or since_arm < self.tm_stop:
                    ms = int((now - t0) * 1000)
                    self.send(mavlink.MAVLink_attitude_quaternion_message(ms, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
                    self.send(mavlink.MAVLink_local_position_ned_message(ms, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
                    self.send(mavlink.MAVLink_highres_imu_message(ms * 1000, 0.0, 0.0, -G, 0.0, 0.0, 0.0, 0.21,
                                                                  0.01, 0.43, 960.0, 0.0, 0.0, 20.0, 0x1FFF))
        self.sock.close()


@contextmanager
def running_peer(port: int, **kwargs) -> Iterator[AutopilotPeer]:
    """An :class:`AutopilotPeer` running on ``port`` for the body of the ``with``; stopped and joined after it."""
    peer = AutopilotPeer(port, **kwargs)
    peer.start()
    try:
        yield peer
    finally:
        peer.stop_event.set()
        peer.join(5)
