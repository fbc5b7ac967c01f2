"""``ArgumentParser`` whose errors are one line: ``prog: error: <what was wrong and what is allowed>``.

argparse prints the whole usage before an error; a newcomer then reads a wall of options instead of
the one line that says what was wrong.  Every subcommand builds its parser from this class; ``--help``
still shows the full usage.
"""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn


class ArgumentParser(argparse.ArgumentParser):
    """argparse with one-line errors (exit code 2, nothing on stdout)."""

    def error(self, message: str) -> NoReturn:
        message = " ".join(str(message).split())
        sys.stderr.write(f"{self.prog}: error: {message} (see: {self.prog} --help)\n")
        raise SystemExit(2)
