"""Make small test data from a SITL flight: a ULog cut down to the topics ``fawtgym observe`` reads, and the
bridge's ``truth.csv`` cut down to its disturbance wrench.

``python -m fawtgym.flightlog.trim px4.ulg truth.csv OUT_ULG OUT_CSV [--max-rate 100] [--block 5]
[--tlog replay.tlog OUT_TLOG]``

* The ULog keeps :data:`~.topics.USED_TOPICS` (first instance), every parameter and the format definitions
  (pyulog's reader and writer); a topic logged faster than ``--max-rate`` Hz keeps every n-th sample (the
  smallest n that brings it under the rate), so the log stays a valid PX4 ULog that pyulog and
  ``fawtgym observe`` read as before, only sparser.
* The truth keeps ``t``, the wind and the total disturbance wrench the env applied (aerodynamic + ground:
  ``f_n, f_e, f_d`` world NED [N], ``t_x, t_y, t_z`` body FRD [N m]; :data:`~fawtgym.eval.sitl.bridge.
  TRUTH_WRENCH_COLUMNS`), as means over blocks of ``--block`` steps labelled with the block's last ``t``
  (a block mean keeps every mean over whole blocks exact), and ``contact``: the fraction of the block's steps
  with ground contact (0 in the air).
* The replay's ``.tlog`` (optional) keeps the MAVLink messages :mod:`.tlog` reads, at most 50 Hz each.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fawtgym.core.checks import check_int, check_number


def _max_rate(max_rate: object) -> float:
    """``--max-rate`` [Hz] in (0, 1e4] (0 divided by zero; NaN and -1 were taken)."""
    return check_number(max_rate, "max_rate (--max-rate)", minimum=0.0, maximum=1e4, note="Hz")


def trim_ulog(src: str | Path, dest: str | Path, max_rate: float = 100.0) -> dict[str, int]:
    """Write ``dest``: ``src`` with only the topics observe reads, each at most ``max_rate`` Hz.  Returns the
    samples kept per topic."""
    from pyulog import ULog

    from .topics import USED_TOPICS

    max_rate = _max_rate(max_rate)
    ulog = ULog(str(src), list(USED_TOPICS))
    ulog._data_list = [d for d in ulog.data_list if d.multi_id == 0]
    kept = {}
    for d in ulog.data_list:
        ts = d.data["timestamp"].astype(np.int64)
        span = (ts[-1] - ts[0]) * 1e-6 if ts.size > 1 else 0.0
        rate = (ts.size - 1) / span if span > 0 else 0.0
        every = max(1, int(np.ceil(rate / max_rate)))
        d.data = {k: v[::every] for k, v in d.data.items()}
        kept[d.name] = int(d.data["timestamp"].size)
    ulog.write_ulog(str(dest))
    return kept


def trim_tlog(src: str | Path, dest: str | Path, max_rate: float = 50.0) -> dict[str, int]:
    """Write ``dest``: the messages of ``src`` that :mod:`.tlog` reads, from the autopilot (system 1), each type
    at most ``max_rate`` Hz of log time (a message is kept when at least ``1 / max_rate`` s passed since the last
    one kept of its type), with their original receive times.  Returns the messages kept per type."""
    import struct

    from pymavlink import mavutil

    from .tlog import _WANTED

    max_rate = _max_rate(max_rate)
    conn = mavutil.mavlink_connection(str(src), dialect="common", robust_parsing=True)
    last: dict[str, float] = {}
    kept: dict[str, int] = {}
    with open(dest, "wb") as fh:
        while (msg := conn.recv_match(type=_WANTED)) is not None:
            kind, t = msg.get_type(), float(msg._timestamp)
            if msg.get_srcSystem() != 1 or (kind in last and t - last[kind] < 1.0 / max_rate - 1e-6):
                continue
            last[kind] = t
            kept[kind] = kept.get(kind, 0) + 1
            fh.write(struct.pack(">Q", int(round(t * 1e6))) + msg.get_msgbuf())
    return kept


def trim_truth(src: str | Path, dest: str | Path, block: int = 5) -> int:
    """Write ``dest``: t, wind and the total disturbance wrench of the bridge's truth.csv, block means."""
    block = check_int(block, "block (--block, steps)", 1, 10**6)
    tr = np.genfromtxt(src, delimiter=",", names=True)
    aero = np.column_stack([tr[c] for c in ("fa_n", "fa_e", "fa_d", "ta_x", "ta_y", "ta_z")])
    ground = np.column_stack([tr[c] for c in ("fg_n", "fg_e", "fg_d", "tg_x", "tg_y", "tg_z")])
    wind = np.column_stack([tr[c] for c in ("wind_n", "wind_e", "wind_d")])
    n = (tr.size // block) * block
    contact = np.any(ground != 0.0, axis=1, keepdims=True).astype(float)
    means = np.concatenate([wind, aero + ground, contact], axis=1)[:n].reshape(-1, block, 10).mean(axis=1)
    t = tr["t"][block - 1:n:block]
    np.savetxt(dest, np.column_stack([t, means]), delimiter=",", fmt="%.6g", comments="",
               header="t,wind_n,wind_e,wind_d,f_n,f_e,f_d,t_x,t_y,t_z,contact")
    return int(t.size)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fawtgym.flightlog.trim", description=__doc__.split("\n\n")[0])
    p.add_argument("ulog")
    p.add_argument("truth_csv")
    p.add_argument("out_ulog")
    p.add_argument("out_csv")
    p.add_argument("--max-rate", type=float, default=100.0)
    p.add_argument("--block", type=int, default=5)
    p.add_argument("--tlog", nargs=2, metavar=("TLOG", "OUT_TLOG"), help="also trim a replay .tlog (50 Hz)")
    a = p.parse_args(argv)
    print(trim_ulog(a.ulog, a.out_ulog, a.max_rate), trim_truth(a.truth_csv, a.out_csv, a.block))
    if a.tlog:
        print(trim_tlog(*a.tlog))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
