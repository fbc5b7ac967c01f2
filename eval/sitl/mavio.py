"""pymavlink plumbing shared by the bridge and the replay: the dialect, a ``.tlog`` writer, the error type.

A ``.tlog`` is what MAVProxy and QGroundControl write and pymavlink's ``mavlogdump.py`` reads: each message as an
8-byte big-endian timestamp [us since the Unix epoch] followed by its packed MAVLink bytes.  pymavlink's own
``setup_logfile`` records received messages only; :class:`TlogWriter` records both directions.
"""

from __future__ import annotations

import struct
import threading
import time
from pathlib import Path
from typing import Any


class SitlError(RuntimeError):
    """A SITL/replay run stopped: the message is the one-line reason shown to the user."""


def mavlink_dialect() -> Any:
    """pymavlink's MAVLink 2 ``common`` dialect module (ImportError naming the extra if pymavlink is missing)."""
    try:
        from pymavlink.dialects.v20 import common
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("the SITL hook needs pymavlink: pip install 'fawtgym[sitl]'") from exc
    return common


class TlogWriter:
    """Appends MAVLink messages (sent and received) with wall-clock timestamps to a ``.tlog`` file."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb")
        self._lock = threading.Lock()
        self.count = 0

    def write(self, msg: Any) -> None:
        """Record one packed message (a pymavlink message whose ``pack`` has run, i.e. sent or parsed)."""
        buf = msg.get_msgbuf()
        if not buf or msg.get_type() == "BAD_DATA":
            return
        with self._lock:
            if self._file.closed:
                return
            self._file.write(struct.pack(">Q", int(time.time() * 1e6)) + bytes(buf))
            self.count += 1

    def close(self) -> None:
        with self._lock:
            if not self._file.closed:
                self._file.close()

    def __enter__(self) -> TlogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
