"""A flight log as time series: :class:`FlightLog` holds PX4-named topics, parameters and version.

Both readers (:mod:`.ulog`, :mod:`.tlog`) produce this one structure, so everything downstream reads
PX4 topic and field names (``vehicle_local_position.x``, ``vehicle_attitude.q[0]``...) whatever the file.
Times are seconds since the log's first sample (float64), strictly non-decreasing per topic.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.checks import shown

from .errors import FlightLogError


@dataclasses.dataclass
class Topic:
    """One topic: sample times ``t`` [s since log start] (K,) and its fields by PX4 name, each (K,)."""

    name: str
    t: NDArray[np.float64]
    fields: dict[str, NDArray[np.float64]]

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def has(self, *names: str) -> bool:
        return all(n in self.fields for n in names)

    def vector(self, base: str, size: int) -> NDArray[np.float64]:
        """Stack the array field ``base[0..size-1]`` into shape (K, size) (float64)."""
        try:
            return np.stack([np.asarray(self.fields[f"{base}[{i}]"], dtype=float) for i in range(size)], axis=1)
        except KeyError as exc:
            raise FlightLogError(f"topic {shown(self.name)} has no field {shown(exc.args[0])}; it has "
                                 f"{sorted(self.fields)[:12]}") from None

    def columns(self, *names: str) -> NDArray[np.float64]:
        """Stack scalar fields into shape (K, len(names))."""
        missing = [n for n in names if n not in self.fields]
        if missing:
            raise FlightLogError(f"topic {shown(self.name)} has no field(s) {missing}; it has "
                                 f"{sorted(self.fields)[:12]}")
        return np.stack([np.asarray(self.fields[n], dtype=float) for n in names], axis=1)


@dataclasses.dataclass
class FlightLog:
    """A parsed log: ``topics`` by PX4 name (first instance), ``params`` (initial values), ``duration`` [s]."""

    path: str
    kind: str  #: "ulog" or "tlog"
    topics: dict[str, Topic]
    params: dict[str, float]
    duration: float
    version: str = ""  #: PX4 version string as logged ("" when unknown)
    notes: list[str] = dataclasses.field(default_factory=list)  #: reader remarks (e.g. truncated data)
    #: the log's t = 0 on the autopilot's clock [s since boot] (ULog start timestamp; a tlog's earliest boot time),
    #: so log time + ``start`` is PX4 time (= the simulated time of a SITL flight, docs/sitl.md)
    start: float = 0.0

    def has(self, topic: str) -> bool:
        return topic in self.topics and len(self.topics[topic]) > 0


def read_log(path: str | Path, topics: tuple[str, ...] | None = None) -> FlightLog:
    """Read a ``.ulg`` (pyulog) or ``.tlog`` (pymavlink) file; FlightLogError (one line) otherwise.

    ``topics``: PX4 topic names to load (None: every topic the estimation uses, :data:`.topics.USED_TOPICS`);
    loading only these keeps memory proportional to what is used.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise FlightLogError(f"log file must be a path (a str or os.PathLike), got {shown(path)}")
    p = Path(path)
    if p.is_dir():
        raise FlightLogError(f"log file {shown(str(p))} is a directory (give a .ulg or .tlog file)")
    if not p.is_file():
        raise FlightLogError(f"log file {shown(str(p))} does not exist (give a .ulg or .tlog file)")
    suffix = p.suffix.lower()
    if suffix == ".ulg":
        from .ulog import read_ulog

        return read_ulog(p, topics)
    if suffix == ".tlog":
        from .tlog import read_tlog

        return read_tlog(p)
    raise FlightLogError(f"log file {shown(p.name)} has suffix {shown(suffix)}; allowed: .ulg (PX4 ULog), .tlog "
                         f"(MAVLink)")
