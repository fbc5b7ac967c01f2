"""The progress bar of a reproduction study: one tqdm bar on stderr, off with ``--no-progress``.

A study's simulation loop takes a ``progress`` callback (``None`` or a callable taking a count) and calls it
once per unit of work (a simulation step, an SDP solve, ...); the callback only counts, so the numbers are
the same with or without a bar.  ``fawtgym reproduce all`` runs every study with ``--no-progress`` and shows
its own bar over the studies.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Callable, Iterator
from typing import Any

#: a progress callback: called with the number of units just done
Progress = Callable[[int], Any]

#: the flag every study accepts
FLAG = "--no-progress"


def add_flag(parser: argparse.ArgumentParser) -> None:
    """Add ``--no-progress`` (stored as ``no_progress``) to a study's parser."""
    parser.add_argument(FLAG, action="store_true", help="no progress bar")


@contextlib.contextmanager
def bar(total: int, desc: str, unit: str = "step", disable: bool = False) -> Iterator[Progress]:
    """A transient tqdm bar of ``total`` units; yields its ``update`` to pass into the simulation loop."""
    from tqdm.auto import tqdm

    with tqdm(total=int(total), desc=desc, unit=unit, leave=False, dynamic_ncols=True, disable=disable) as b:
        yield b.update


def tick(progress: Progress | None, n: int = 1) -> None:
    """Call ``progress(n)`` if there is a callback."""
    if progress is not None:
        progress(n)
