"""``fawtgym observe LOG.ulg|LOG.tlog --observer NAME[,NAME...] --vehicle PRESET|FILE [--out DIR]``.

Runs registered observers on a recorded flight and writes ``estimates.csv`` (or ``.parquet``),
``summary.json`` / ``summary.txt`` and ``force.png`` / ``torque.png`` into DIR; prints the summary.
Errors (unreadable or truncated log, missing topic, bad option) are one line on stderr, exit code 2.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from fawtgym.cli_parser import ArgumentParser

from .errors import FlightLogError
from .inputs import INPUT_SOURCES, SCALE_CHOICES, THRUST_CURVES
from .runner import DEFAULT_RATE, DEFAULT_SETTLE


def build_parser() -> ArgumentParser:
    p = ArgumentParser(prog="fawtgym observe", description=(
        "Run registered observers on a recorded flight (PX4 .ulg or MAVLink .tlog): disturbance force (world NED) "
        "and torque (body FRD) over the armed, airborne time, figures and a per-phase summary (docs/flightlogs.md)."))
    p.add_argument("log", help="PX4 ULog (.ulg) or MAVLink telemetry log (.tlog)")
    p.add_argument("--observer", required=True, help="comma-separated observer names (see: fawtgym list)")
    p.add_argument("--vehicle", required=True, help="vehicle preset name (see: fawtgym list) or a .yaml/.json file")
    p.add_argument("--out", default=None, help="output folder (default: observe_<log name>)")
    p.add_argument("--rate", type=float, default=DEFAULT_RATE, help=f"observer rate [Hz] (default {DEFAULT_RATE:g})")
    p.add_argument("--inputs", choices=INPUT_SOURCES, default="auto", help="known-input source (default auto)")
    p.add_argument("--thrust-curve", choices=THRUST_CURVES, default="auto",
                   help="rotor thrust curve: px4 (THR_MDL_FAC of the log) or preset (default auto)")
    p.add_argument("--thrust-scale", default="auto",
                   help=f"one of {', '.join(SCALE_CHOICES)} or a number (default auto)")
    p.add_argument("--settle", type=float, default=DEFAULT_SETTLE,
                   help=f"seconds after each take-off left out of the summary (default {DEFAULT_SETTLE:g})")
    p.add_argument("--format", choices=("auto", "csv", "parquet"), default="auto",
                   help="table format (auto: parquet when pyarrow is installed, else csv)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures (no matplotlib needed)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    from .outputs import write_figures, write_summary, write_table
    from .runner import observe

    observers = [o.strip() for o in args.observer.split(",") if o.strip()]
    out = Path(args.out) if args.out else Path(f"observe_{Path(args.log).stem}")
    try:
        result = observe(args.log, observers, args.vehicle, rate=args.rate, inputs=args.inputs,
                         thrust_curve=args.thrust_curve, thrust_scale=args.thrust_scale, settle=args.settle)
        out.mkdir(parents=True, exist_ok=True)
        table = write_table(result, out, args.format)
        _, text = write_summary(result, out)
        figures = [] if args.no_figures else write_figures(result, out)
    except (FlightLogError, ValueError, OSError) as exc:
        parser.error(str(exc))
    print(text)
    print(f"wrote {table}, {out / 'summary.json'}" + "".join(f", {f}" for f in figures))
    return 0
