"""Argument checks shared by every package (one message and exception type whatever the caller)."""

from __future__ import annotations

from typing import Any

import numpy as np


def check_flag(value: Any, name: str) -> bool:
    """A boolean option: ``True``/``False`` (numpy booleans too), never a truthy stand-in.

    ``bool("False")`` is True and ``bool(-1)`` is True, so an option passed through ``bool()`` silently turns a
    typo into the opposite setting; this refuses anything that is not a boolean, naming the option and the value.
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ValueError(f"{name} must be True or False, got {value!r} ({type(value).__name__})")
