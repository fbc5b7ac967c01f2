"""The one exception type of flight-log processing: a one-line message naming what is wrong and the way out."""

from __future__ import annotations

from typing import Any

from fawtgym.core.checks import check_number


class FlightLogError(ValueError):
    """A log that cannot be processed as asked (unreadable, truncated, missing a topic, bad option).

    The message is one line; the CLI prints it as ``fawtgym observe: error: <message>`` and exits 2.
    """

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


def log_number(value: Any, name: str, **bounds: Any) -> float:
    """:func:`~fawtgym.core.checks.check_number` of a flight-log option, its refusal a :class:`FlightLogError`."""
    try:
        return check_number(value, name, **bounds)
    except ValueError as exc:
        raise FlightLogError(str(exc)) from None
