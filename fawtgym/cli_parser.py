"""``ArgumentParser`` whose errors are one line: ``prog: error: <what was wrong and what is allowed>``.

argparse prints the whole usage before an error; a newcomer then reads a wall of options instead of
the one line that says what was wrong.  Every subcommand builds its parser from this class; ``--help``
still shows the full usage.

The argument types below check a value when it is parsed, before any long work starts, and name the
value and what is allowed.  One convention holds for every command: a FAWT duty on the command line
is in percent (``--duty 50`` or ``--duty 50%``), as in the wind names ``fawt-50`` and ``table4-50``
and in Table 3 of Wang et al. (2024); a fraction such as ``0.5`` is refused with a hint.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

from fawtgym.core.checks import shown


class ArgumentParser(argparse.ArgumentParser):
    """argparse with one-line errors (exit code 2, nothing on stdout) and help in plain text.

    Help is shown without reStructuredText markup (the docstrings it is built from use ``code``).
    """

    def format_help(self) -> str:
        return super().format_help().replace("``", "")

    def error(self, message: str) -> NoReturn:
        message = " ".join(str(message).split())
        # argparse quotes the raw text it refused ("invalid int value: '999...'"): a long one is cut as every message
        message = re.sub(r"'([^']{200,})'", lambda m: shown(m.group(1)), message)
        sys.stderr.write(f"{self.prog}: error: {message} (see: {self.prog} --help)\n")
        raise SystemExit(2)


def _number(text: str, kind: type, what: str) -> float | int:
    try:
        value = kind(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"{shown(text)} is not {what}") from None
    if isinstance(value, float) and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{shown(text)} is not {what}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (a duration, a step, a rate)."""
    v = _number(text, float, "a positive number")
    if v <= 0:
        raise argparse.ArgumentTypeError(f"{shown(text)} is not a positive number")
    return float(v)


def nonnegative_float(text: str) -> float:
    """A finite number >= 0 (a switch-on time)."""
    v = _number(text, float, "a number >= 0")
    if v < 0:
        raise argparse.ArgumentTypeError(f"{shown(text)} is not a number >= 0")
    return float(v)


def positive_int(text: str) -> int:
    """An integer >= 1 (a count)."""
    v = _number(text, int, "a positive integer")
    if v < 1:
        raise argparse.ArgumentTypeError(f"{shown(text)} is not a positive integer")
    return int(v)


def seed(text: str) -> int:
    """A random seed: an integer in [0, 2**32) (what numpy's generators accept)."""
    v = _number(text, int, "a seed (an integer 0 to 4294967295)")
    if not 0 <= v < 2**32:
        raise argparse.ArgumentTypeError(f"{shown(text)} is not a seed (an integer 0 to 4294967295)")
    return int(v)


def bounded_int(lo: int, hi: int) -> Callable[[str], int]:
    """An integer in [lo, hi]."""

    def parse(text: str) -> int:
        v = _number(text, int, f"an integer from {lo} to {hi}")
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{shown(text)} is not an integer from {lo} to {hi}")
        return int(v)

    parse.__name__ = f"int_{lo}_{hi}"
    return parse


def duty_percent(lo: float = 0.0, hi: float = 100.0) -> Callable[[str], float]:
    """A FAWT duty in percent, ``lo < d <= hi`` (``50`` or ``50%``), returned in percent.

    A value below 1 without ``%`` is refused with a hint: it is almost surely a fraction.
    """

    def parse(text: str) -> float:
        t = text.strip()
        has_pct = t.endswith("%")
        v = _number(t[:-1] if has_pct else t, float, f"a duty in percent ({lo:g}-{hi:g})")  # one % sign at most
        if not has_pct and 0 < v < 1:
            raise argparse.ArgumentTypeError(f"{shown(text)}: the duty is given in percent ({lo:g}-{hi:g}); "
                                             f"for {100 * v:g} % write {100 * v:g}")
        inside = (lo < v <= hi) if lo == 0 else (lo <= v <= hi)
        if not inside:
            rng = f"above 0 and at most {hi:g}" if lo == 0 else f"from {lo:g} to {hi:g}"
            raise argparse.ArgumentTypeError(f"{shown(text)} is not a duty in percent {rng}")
        return float(v)

    parse.__name__ = "duty_percent"
    return parse


def choice_list(allowed: Sequence[str], what: str) -> Callable[[str], list[str]]:
    """A comma list whose every item is one of ``allowed``."""

    def parse(text: str) -> list[str]:
        items = [s.strip() for s in text.split(",") if s.strip()]
        bad = [s for s in items if s not in allowed]
        if not items or bad:
            raise argparse.ArgumentTypeError(f"{', '.join(bad) or repr(text)}: not {what}; "
                                             f"allowed: {', '.join(allowed)}")
        return items

    parse.__name__ = what
    return parse


def check_output_file(parser: argparse.ArgumentParser, flag: str, path: str | Path | None,
                      suffixes: Sequence[str] = ()) -> None:
    """Refuse, before any work, an output file whose folder is missing or not writable or whose suffix is wrong."""
    if path is None:
        return
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        parser.error(f"{flag} {path}: the file must end in {' or '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        parser.error(f"{flag} {path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        parser.error(f"{flag} {path}: the folder {folder} is not writable")
    if p.is_dir():
        parser.error(f"{flag} {path}: is a folder, not a file")


def check_output_dir(parser: argparse.ArgumentParser, flag: str, path: str | Path | None) -> None:
    """Refuse, before any work, an output folder that cannot be created or written."""
    if path is None:
        return
    p = Path(path)
    if p.exists() and not p.is_dir():
        parser.error(f"{flag} {path}: exists and is not a folder")
    q = p
    while not q.exists():
        q = q.parent if q.parent != q else Path(".")
    if not q.is_dir():
        parser.error(f"{flag} {path}: cannot be created, {q} is a file, not a folder")
    if not os.access(q, os.W_OK):
        parser.error(f"{flag} {path}: cannot be created or written, the folder {q} is not writable")
