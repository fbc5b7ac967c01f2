"""Read a PX4 ULog (``.ulg``) with pyulog, PX4's own parser, into a :class:`~.logdata.FlightLog`.

Only the topics the estimation uses are parsed (pyulog's ``message_name_filter_list``), the first
instance of each.  Timestamps (microseconds of the autopilot's boot clock) become seconds since the
log's start; samples stamped before the start (a topic's initial publication carries 0) are placed at 0.
A file that is not a ULog, or that ends before any logged data (cut inside the header or the format
definitions), raises :class:`~.errors.FlightLogError` with one line.  A file cut inside the data section is
read up to the cut (what a crash-truncated log holds is valid) and a note says where the data ends.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fawtgym.core.checks import listed, shown

from .errors import FlightLogError
from .logdata import FlightLog, Topic


def read_ulog(path: Path, topics: tuple[str, ...] | None = None) -> FlightLog:
    try:
        from pyulog import ULog
    except ImportError:  # pragma: no cover - depends on the install
        raise FlightLogError("reading .ulg files needs pyulog: pip install 'fawtgym[logs]'") from None
    from .topics import USED_TOPICS

    if topics is not None and (isinstance(topics, str) or not all(isinstance(t, str) and t for t in topics)):
        raise FlightLogError(f"topics must be a sequence of PX4 topic names (e.g. ('vehicle_attitude',)), got "
                             f"{shown(topics)}")
    wanted = list(USED_TOPICS if topics is None else topics)
    size = path.stat().st_size
    try:
        ulog = ULog(str(path), wanted)
    except Exception as exc:  # pyulog raises its own ULogException, struct.error, IndexError, ...
        what = " ".join(str(exc).split()) or type(exc).__name__
        raise FlightLogError(f"{path.name} is not a readable PX4 ULog ({what}); give a .ulg written by PX4's "
                             "logger") from None
    if not ulog.data_list and topics is not None and not ulog.file_corruption and _has_data(path):
        raise FlightLogError(f"{path.name} holds no sample of the topic(s) {listed(wanted)} (PX4 topic names as "
                             "logged, e.g. vehicle_attitude)")
    if not ulog.data_list:
        where = "inside the format definitions" if ulog.file_corruption else "before any logged data"
        raise FlightLogError(f"{path.name} is truncated or empty: the file ends after {size} bytes, {where} "
                             "(no topic has a sample)")
    t0 = ulog.start_timestamp
    topics_out: dict[str, Topic] = {}
    for d in ulog.data_list:
        if d.name in topics_out or d.multi_id != 0:
            continue
        ts = np.asarray(d.data["timestamp"], dtype=np.int64)
        t = np.maximum(ts - t0, 0).astype(float) * 1e-6
        fields = {k: v for k, v in d.data.items() if k != "timestamp" and not k.startswith("_padding")}
        topics_out[d.name] = Topic(d.name, t, fields)
    params = {k: float(v) for k, v in ulog.initial_parameters.items()}
    duration = max((ulog.last_timestamp - t0) * 1e-6, 0.0)
    version = str(ulog.msg_info_dict.get("ver_sw_release", "") or ulog.msg_info_dict.get("ver_sw", ""))
    notes = []
    if ulog.file_corruption:
        notes.append(f"pyulog found corrupt data in {path.name}; data read up to t = {duration:.1f} s")
    return FlightLog(str(path), "ulog", topics_out, params, duration, _px4_version(version), notes, start=t0 * 1e-6)


def _has_data(path: Path) -> bool:
    """Whether any topic of the log has a sample (reads it all: only to tell a missing topic from a cut log)."""
    from pyulog import ULog

    try:
        return bool(ULog(str(path)).data_list)
    except Exception:  # pyulog raises many types on a damaged file: the truncation message follows
        return False


def _px4_version(ver: str) -> str:
    """'v1.14.0' from PX4's ver_sw_release integer (0xAABBCCTT), else the raw string (a git hash)."""
    try:
        n = int(ver)
    except ValueError:
        return ver
    return f"v{(n >> 24) & 0xFF}.{(n >> 16) & 0xFF}.{(n >> 8) & 0xFF}"
