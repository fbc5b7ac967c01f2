"""The one exception type of flight-log processing: a one-line message naming what is wrong and the way out."""

from __future__ import annotations


class FlightLogError(ValueError):
    """A log that cannot be processed as asked (unreadable, truncated, missing a topic, bad option).

    The message is one line; the CLI prints it as ``fawtgym observe: error: <message>`` and exits 2.
    """

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))
