"""Benchmark: fawtgym observe on a synthetic 20-minute PX4 log, one observer.

The log is built by tiling a real one (``tests/data/flight_logs/sample_px4_events.ulg``, PX4 SITL, 31 s,
every topic) end to end with shifted timestamps until it spans ``--minutes`` (pyulog's writer), so parsing
meets a real log's topic mix and size (about 50 MB for 20 minutes).  The observe run (read, resample,
phases, inputs, one observer over every airborne segment, no files written) is timed in a fresh child
process, which also reports its peak resident memory.  Target (issue 16): under 10 s for 20 minutes on
this machine, memory bounded (the child holds only the topics the estimation reads).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

SOURCE = Path(__file__).resolve().parents[2] / "tests" / "data" / "flight_logs" / "sample_px4_events.ulg"
VEHICLE = SOURCE.with_name("jmavsim_quad.yaml")

_CHILD = """
import resource, sys, time


def peak_mb():
    # VmHWM: this process image's peak resident memory (ru_maxrss would carry the parent's across exec)
    try:
        with open("/proc/self/status") as fh:
            return next(int(line.split()[1]) for line in fh if line.startswith("VmHWM")) / 1024
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


t0 = time.perf_counter()
from fawtgym.flightlog.runner import observe
import fawtgym.observers, fawtgym.envs.vehicles, pyulog
base = peak_mb()
r = observe(sys.argv[1], [sys.argv[2]], sys.argv[3])
dt = time.perf_counter() - t0
print(f"{dt:.3f} {peak_mb():.0f} {r.t.size} {r.estimated.sum()} {r.log.duration:.1f} {base:.0f}")
"""


def tiled_log(source: Path, minutes: float, dest: Path) -> float:
    """Write ``dest``: ``source`` repeated with shifted timestamps to span ``minutes``; returns its duration [s]."""
    from pyulog import ULog

    ulog = ULog(str(source))
    span = ulog.last_timestamp - ulog.start_timestamp + 1_000_000
    copies = int(np.ceil(minutes * 60e6 / span))
    for d in ulog.data_list:
        ts = d.data["timestamp"].astype(np.int64)
        ts = np.where(ts < ulog.start_timestamp, ulog.start_timestamp, ts)  # initial publications stamped 0
        shift = np.repeat(np.arange(copies, dtype=np.int64) * span, ts.size)
        d.data = {k: (np.tile(ts, copies) + shift).astype(v.dtype) if k == "timestamp" else np.tile(v, copies)
                  for k, v in d.data.items()}
    ulog._last_timestamp = ulog.start_timestamp + copies * span
    ulog.write_ulog(str(dest))
    return copies * span * 1e-6


def main(argv: Sequence[str] | None = None) -> int:
    from fawtgym.cli_parser import ArgumentParser, positive_float
    from fawtgym.observers import observer_names

    p = ArgumentParser(prog="fawtgym bench flightlog", description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=positive_float, default=20.0, help="length of the synthetic log (default 20)")
    p.add_argument("--observer", default="ffts_eso", help="observer to run (default ffts_eso)")
    args = p.parse_args(list(sys.argv[1:] if argv is None else argv))
    if args.observer not in observer_names():
        p.error(f"--observer: unknown observer {args.observer!r}; known: {', '.join(observer_names())}")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "tiled.ulg"
        tiled_log(SOURCE, args.minutes, path)
        size = path.stat().st_size / 1e6
        out = subprocess.run([sys.executable, "-c", _CHILD, str(path), args.observer, str(VEHICLE)],
                             capture_output=True, text=True, check=True).stdout.split()
    seconds, rss, points, estimated, duration, base = (float(out[0]), float(out[1]), int(out[2]), int(out[3]),
                                                       float(out[4]), float(out[5]))
    print(f"flightlog: {duration / 60:.1f} min log ({size:.0f} MB, {points} points at 50 Hz, {estimated} estimated), "
          f"observer {args.observer}: {seconds:.2f} s wall ({duration / seconds:.0f}x faster than the flight; "
          f"target < 10 s), peak memory {rss:.0f} MB ({rss - base:.0f} MB above the imports)")
    return 0
