"""``fawtgym sitl px4``: our env as PX4's simulator, over the TCP MAVLink interface of ``simulator_mavlink``.

What PX4 v1.13/v1.14 ``px4_sitl_default`` (an airframe without a simulator of its own, e.g. 10016 ``none_iris``)
expects of a simulator, and what :class:`Px4Bridge` does:

* PX4 connects as the TCP client to port 4560 (``simulator_mavlink start -c 4560``); the bridge listens.
  PX4 sends a HEARTBEAT and COMMAND_LONG 511 (SET_MESSAGE_INTERVAL) asking for HIL_STATE_QUATERNION (ground
  truth); the bridge acknowledges it and sends that message at the requested interval of simulated time.
* Lockstep: PX4's clock is set by HIL_SENSOR ``time_usec`` and advances only when one arrives.  Each sample is
  answered by HIL_ACTUATOR_CONTROLS (``controls[0..3]`` = motors 1-4 in [0, 1]; ``mode`` bit 128 when armed).
  The bridge sends the sample of time t, waits for the answer, and only then steps the physics by one period
  (4000 us: PX4's IMU_INTEG_RATE 250 Hz) with those motors, so ``time_usec`` increases strictly by one period.
  Until PX4's first answer (its modules start in the first seconds) the bridge sends samples paced to the
  wall clock with the motors off (waiting up to ``boot_wait``, default one period, for an answer to each),
  as Gazebo does; from the first answer on it is in lockstep, and a missing
  answer is an error after ``actuator_timeout`` seconds.
* HIL_SENSOR every step: accelerometer (specific force, FRD), gyroscope, magnetometer and barometer from the
  env's sensor model (its noise preset applies), the field at the home position, ISA pressure and temperature
  (:mod:`.convert`); ``fields_updated`` = accel 0x7 | gyro 0x38 | mag 0x1C0 | baro 0x1A00.
* The barometer carries white noise, ``baro_noise`` Pa RMS (default 1 Pa, Gazebo-classic's barometer plugin):
  a constant pressure is flagged STALE by PX4 and EKF2 then drops the barometer (the hand test against PX4
  v1.14.0 showed it).  Its draws come from their own generator, seeded by ``seed``.
* HIL_GPS at 10 Hz: 3D fix, 12 satellites, position and velocity from the env's (noisy) position sensor mapped
  onto the home point.

* ``log_dir``: ``truth.csv`` per step: the true state, wind and motors, and the true disturbance wrench held
  over the step (the env's aerodynamic force NED / torque FRD and the ground contact wrench,
  :data:`TRUTH_WRENCH_COLUMNS`; docs/sitl.md lists every column), for checking observers on PX4's log.

``realtime=True`` paces the steps to the wall clock; by default both sides run as fast as they can.
"""

from __future__ import annotations

import csv
import json
import math
import select
import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from fawtgym.core import measurement as M
from fawtgym.core.checks import check_number, shown
from fawtgym.core.frames import rot_to_euler
from fawtgym.envs.options import MAX_EPISODE_SECONDS

from . import convert as C
from .airframe import PX4_MOTOR_TO_ROTOR
from .mavio import SitlError, TlogWriter, mavlink_dialect
from .plant import SitlVehicle

MSG_ID_HIL_STATE_QUATERNION = 115
#: truth.csv's wrench columns: the env's aerodynamic (wind) force, world NED [N], and torque, body FRD [N m], then
#: the ground contact wrench (zero in the air), each held over the step that ends at the row's ``t``
TRUTH_WRENCH_COLUMNS = ("fa_n", "fa_e", "fa_d", "ta_x", "ta_y", "ta_z", "fg_n", "fg_e", "fg_d", "tg_x", "tg_y", "tg_z")
CMD_SET_MESSAGE_INTERVAL = 511


def check_sim_duration(duration: object) -> float:
    """``--sim-duration`` [simulated s] in (0, 1e9]; ValueError naming it otherwise."""
    return check_number(duration, "sim duration (--sim-duration)", minimum=0.0, maximum=MAX_EPISODE_SECONDS,
                        note="simulated s")


class Px4Bridge:
    """TCP server that plays PX4's simulator with a :class:`~fawtgym.eval.sitl.plant.SitlVehicle`.

    The socket is bound in the constructor (``port=0`` picks a free port: read :attr:`port`); :meth:`serve`
    accepts one PX4 connection and runs lockstep until ``duration`` seconds of simulated time, :meth:`stop`, or
    an error (:class:`SitlError` with a one-line reason: no connection, PX4 disconnected, no answer, malformed
    data only).
    """

    def __init__(self, vehicle: SitlVehicle, home: C.Home | None = None, host: str = "127.0.0.1", port: int = 4560,
                 realtime: bool = False, gps_rate: float = 10.0, accept_timeout: float = 120.0,
                 actuator_timeout: float = 5.0, boot_timeout: float = 120.0, boot_wait: float | None = None,
                 baro_noise: float = C.BARO_NOISE_PA, seed: int = 0, tlog: str | Path | None = None,
                 log_dir: str | Path | None = None, log: Callable[[str], None] | None = None) -> None:
        for name, value in (("gps_rate", gps_rate), ("accept_timeout", accept_timeout),
                            ("actuator_timeout", actuator_timeout), ("boot_timeout", boot_timeout)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {shown(value)}")
        if not (isinstance(baro_noise, (int, float)) and math.isfinite(baro_noise) and baro_noise >= 0):
            raise ValueError(f"baro_noise must be a number of Pa RMS >= 0, got {shown(baro_noise)}")
        self.vehicle = vehicle
        self.baro_noise = float(baro_noise)
        self._baro_rng = np.random.default_rng([int(seed), 0xBA20])
        self.home = home or C.Home()
        self.realtime = bool(realtime)
        self.step_us = int(round(vehicle.dt * 1e6))
        self.gps_every = max(1, int(round(1.0 / (gps_rate * vehicle.dt))))
        self.accept_timeout, self.actuator_timeout, self.boot_timeout = accept_timeout, actuator_timeout, boot_timeout
        self.boot_wait = vehicle.dt if boot_wait is None else float(boot_wait)
        self.log = log or (lambda text: None)
        self._mavlink = mavlink_dialect()
        try:
            self._server = socket.create_server((host, int(port)))
        except OSError as exc:
            raise SitlError(f"cannot listen on {host}:{port} ({exc.strerror or exc})") from None
        self.host, self.port = host, self._server.getsockname()[1]
        self._stop = threading.Event()
        self._tlog_path = Path(tlog) if tlog else None
        self._log_dir = Path(log_dir) if log_dir else None
        self.steps = 0
        self.lockstep = False
        self.bad_bytes = 0
        self.heartbeats = 0

    # ---- public -------------------------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask :meth:`serve` to return after the current step (thread-safe)."""
        self._stop.set()

    def close(self) -> None:
        self._server.close()

    def serve(self, duration: float | None = None) -> dict[str, Any]:
        """Accept PX4 and fly until ``duration`` simulated seconds (None: until :meth:`stop` or an error).

        Returns a summary (steps, simulated and wall seconds, lockstep reached, final true position).
        """
        if duration is not None:
            duration = check_sim_duration(duration)
        self._server.settimeout(self.accept_timeout)
        try:
            conn, peer = self._server.accept()
        except TimeoutError:
            raise SitlError(f"no PX4 connected to {self.host}:{self.port} within {self.accept_timeout:g} s "
                            "(start PX4 after the bridge; see docs/sitl.md)") from None
        finally:
            self._server.close()
        self.log(f"PX4 connected from {peer[0]}:{peer[1]}")
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        tlog = TlogWriter(self._tlog_path) if self._tlog_path else None
        rows: list[list[float]] | None = [] if self._log_dir else None
        try:
            return self._run(conn, duration, tlog, rows)
        finally:
            conn.close()
            if tlog is not None:
                tlog.close()
            if rows is not None:
                self._write_log(rows)

    # ---- the lockstep loop --------------------------------------------------------------------------------
    def _run(self, conn: socket.socket, duration: float | None, tlog: TlogWriter | None,
             rows: list[list[float]] | None) -> dict[str, Any]:
        mav = self._mavlink.MAVLink(None, srcSystem=1, srcComponent=51)
        mav.robust_parsing = True
        self._conn, self._mav, self._tlog = conn, mav, tlog
        self._motors = np.zeros(4)
        self._gt_interval_us: int | None = None
        self._next_gt_us = 0
        wall0 = time.monotonic()
        boot_deadline = wall0 + self.boot_timeout
        n_steps = None if duration is None else int(round(duration / self.vehicle.dt))
        plant = self.vehicle
        while not self._stop.is_set() and (n_steps is None or self.steps < n_steps):
            t_us = int(round(plant.time * 1e6)) + self.step_us  # sample k at (k + 1) periods: strictly increasing
            self._send_sample(t_us)
            if self.lockstep:
                if not self._await_actuator(t_us, time.monotonic() + self.actuator_timeout):
                    raise SitlError(f"no HIL_ACTUATOR_CONTROLS from PX4 within {self.actuator_timeout:g} s after "
                                    f"the sample at t = {t_us / 1e6:.3f} s{self._garbage_note()}")
            else:
                if self._await_actuator(t_us, time.monotonic() + self.boot_wait):
                    self.lockstep = True
                    self.log(f"lockstep from t = {t_us / 1e6:.3f} s (PX4's first HIL_ACTUATOR_CONTROLS)")
                elif time.monotonic() > boot_deadline:
                    raise SitlError(f"PX4 sent no HIL_ACTUATOR_CONTROLS within {self.boot_timeout:g} s of sensor "
                                    f"data{self._garbage_note()}")
            (f_aero, t_aero), (f_ground, t_ground) = plant.aero_wrench, plant.ground_wrench  # held over this step
            plant.step(self._motors)
            self.steps += 1
            if rows is not None:
                t = plant.truth
                rows.append([plant.time, *t[M.POSITION], *t[M.VELOCITY], *rot_to_euler(t[M.ATTITUDE]),
                             *t[M.ANGULAR_VELOCITY], *t["wind"], *self._motors, *f_aero, *t_aero, *f_ground,
                             *t_ground])
            if self.realtime:
                lag = wall0 + self.steps * plant.dt - time.monotonic()
                if lag > 0:
                    time.sleep(lag)
        wall = time.monotonic() - wall0
        return {"steps": self.steps, "sim_seconds": self.vehicle.time, "wall_seconds": wall,
                "lockstep": self.lockstep, "position": self.vehicle.truth[M.POSITION].tolist(),
                "heartbeats": self.heartbeats, "bad_bytes": self.bad_bytes}

    def _garbage_note(self) -> str:
        return f" ({self.bad_bytes} bytes received were not valid MAVLink)" if self.bad_bytes else ""

    def _send(self, msg: Any) -> None:
        buf = msg.pack(self._mav)
        try:
            self._conn.sendall(buf)
        except OSError as exc:
            raise SitlError(f"the PX4 connection broke while sending ({exc.strerror or exc}) after {self.steps} "
                            "steps") from None
        if self._tlog is not None:
            self._tlog.write(msg)

    def _send_sample(self, t_us: int) -> None:
        plant, home = self.vehicle, self.home
        meas, truth = plant.measurement, plant.truth
        alt = home.alt - float(truth[M.POSITION][2])
        mag = C.home_magnetometer(meas, truth[M.ATTITUDE], home)
        L = self._mavlink
        noise = self.baro_noise * float(self._baro_rng.standard_normal()) if self.baro_noise else 0.0
        self._send(L.MAVLink_hil_sensor_message(**C.hil_sensor_fields(meas, mag, alt, t_us, pressure_noise_pa=noise)))
        if self.steps % self.gps_every == 0:
            self._send(L.MAVLink_hil_gps_message(**C.hil_gps_fields(home, meas[M.POSITION], meas[M.VELOCITY], t_us)))
        if self._gt_interval_us is not None and t_us >= self._next_gt_us:
            self._next_gt_us = t_us + self._gt_interval_us
            fields = C.hil_state_quaternion_fields(home, truth[M.POSITION], truth[M.VELOCITY], truth[M.ATTITUDE],
                                                   truth[M.ANGULAR_VELOCITY], plant.acceleration, t_us)
            self._send(L.MAVLink_hil_state_quaternion_message(**fields))

    def _await_actuator(self, t_us: int, deadline: float) -> bool:
        """Read PX4's messages until an answer to the sample ``t_us`` arrives (True) or ``deadline`` (False)."""
        answered = False
        while not answered:
            wait = deadline - time.monotonic()
            if wait <= 0:
                return False
            ready, _, _ = select.select([self._conn], [], [], wait)
            if not ready:
                return False
            try:
                data = self._conn.recv(65536)
            except OSError as exc:
                raise SitlError(f"the PX4 connection broke ({exc.strerror or exc}) after {self.steps} steps "
                                f"(t = {self.vehicle.time:.3f} s)") from None
            if not data:
                raise SitlError(f"PX4 closed the connection after {self.steps} steps (t = {self.vehicle.time:.3f} s)"
                                f"{self._garbage_note()}")
            for msg in self._mav.parse_buffer(data) or []:
                answered |= self._handle(msg, t_us)
        return True

    def _handle(self, msg: Any, t_us: int) -> bool:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            self.bad_bytes += len(msg.get_msgbuf())
            return False
        if self._tlog is not None:
            self._tlog.write(msg)
        if kind == "HIL_ACTUATOR_CONTROLS":
            try:
                self._motors = C.motor_commands(msg.controls, msg.mode, PX4_MOTOR_TO_ROTOR)
            except ValueError as exc:
                raise SitlError(f"PX4 sent a bad HIL_ACTUATOR_CONTROLS at t = {t_us / 1e6:.3f} s: {exc}") from None
            return msg.time_usec == 0 or msg.time_usec >= t_us  # an older one answers an earlier sample
        if kind == "HEARTBEAT":
            self.heartbeats += 1
        elif kind == "COMMAND_LONG":
            result = 3  # MAV_RESULT_UNSUPPORTED
            if msg.command == CMD_SET_MESSAGE_INTERVAL and int(msg.param1) == MSG_ID_HIL_STATE_QUATERNION:
                interval = int(msg.param2)
                self._gt_interval_us = None if interval < 0 else (interval or 20000)
                result = 0  # MAV_RESULT_ACCEPTED
            self._send(self._mavlink.MAVLink_command_ack_message(msg.command, result))
        return False

    def _write_log(self, rows: list[list[float]]) -> None:
        if self._log_dir is None:
            raise RuntimeError("the bridge has no log_dir to write the truth log to")
        self._log_dir.mkdir(parents=True, exist_ok=True)
        with open(self._log_dir / "truth.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["t", "n", "e", "d", "vn", "ve", "vd", "roll", "pitch", "yaw", "p", "q", "r",
                        "wind_n", "wind_e", "wind_d", "m1", "m2", "m3", "m4", *TRUTH_WRENCH_COLUMNS])
            w.writerows([f"{x:.6g}" for x in row] for row in rows)

    def describe(self, wind: Any, sensors: Any, seed: int) -> dict[str, Any]:
        """The configuration (vehicle, wind preset/schedule, sensors, home) printed at start and logged."""
        p = self.vehicle.preset
        return {"vehicle": p.name, "vehicle_source": p.source, "wind": wind, "sensors": sensors, "seed": seed,
                "home": {"lat": self.home.lat, "lon": self.home.lon, "alt": self.home.alt,
                         "mag_ned_gauss": list(self.home.mag_ned)},
                "start_ned": self.vehicle.truth[M.POSITION].tolist(), "step_us": self.step_us,
                "gps_rate_hz": 1.0 / (self.gps_every * self.vehicle.dt), "baro_noise_pa": self.baro_noise,
                "realtime": self.realtime,
                "listen": f"{self.host}:{self.port}"}

    def write_config(self, config: dict[str, Any]) -> None:
        if self._log_dir is not None:
            self._log_dir.mkdir(parents=True, exist_ok=True)
            (self._log_dir / "config.json").write_text(json.dumps(config, indent=2, default=str) + "\n")
