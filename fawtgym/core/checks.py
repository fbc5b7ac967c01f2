"""Argument checks shared by every package (one message and exception type whatever the caller)."""

from __future__ import annotations

import inspect
import math
import numbers
import sys
from typing import Any

import numpy as np


def check_flag(value: Any, name: str) -> bool:
    """A boolean option: ``True``/``False`` (numpy booleans too), never a truthy stand-in.

    ``bool("False")`` is True and ``bool(-1)`` is True, so an option passed through ``bool()`` silently turns a
    typo into the opposite setting; this refuses anything that is not a boolean, naming the option and the value.
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ValueError(f"{name} must be True or False, got {shown(value)} ({type(value).__name__})")


def check_number(value: Any, name: str, *, minimum: float = -math.inf, maximum: float = math.inf,
                 inclusive_minimum: bool = False, inclusive_maximum: bool = True, note: str = "") -> float:
    """A real number as a float: int, float or a numpy real scalar (bool, complex, str, None refused), finite, above
    ``minimum`` (``>=`` with ``inclusive_minimum``) and at most ``maximum``.

    Else one-line ValueError naming ``name``, the allowed range and the value, e.g.
    ``"omega_t must be a finite real number in (0, 1e+06] rad/s, got 1e+300 (float)"``.
    """
    ok = isinstance(value, (numbers.Real, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    try:
        v = float(value) if ok else math.nan
    except OverflowError:       # an int beyond float range
        v = math.inf
    if (ok and math.isfinite(v) and (v >= minimum if inclusive_minimum else v > minimum)
            and (v <= maximum if inclusive_maximum else v < maximum)):
        return v
    bounds = _range_text(minimum, maximum, inclusive_minimum, inclusive_maximum)
    raise ValueError(f"{name} must be a finite real number{bounds}"
                     f"{' ' + note if note else ''}, got {shown(value)} ({type(value).__name__})")


def shown(value: Any, limit: int = 200) -> str:
    """``repr(value)`` for an error message, at most ``limit`` characters: a longer one (e.g. an int of thousands of
    digits, whose full repr Python refuses beyond 4300 digits) is cut, with its length (and sign) stated; a container
    holding such an int is named by its type; a multi-line repr (numpy arrays) is put on one line."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        bits = abs(int(value)).bit_length()
        if bits > 3 * limit:  # more than ~0.9 limit digits
            return f"{'a negative' if value < 0 else 'an'} int of about {int(bits * math.log10(2)) + 1} digits"
    try:
        text = repr(value)
    except ValueError:  # it holds an int beyond Python's int-to-str limit (e.g. a list with 10**5000 in it)
        return f"a {type(value).__name__} holding an int of more than {sys.get_int_max_str_digits()} digits"
    if "\n" in text:  # a multi-line repr (a numpy array's wraps): one line, as every message is
        text = " ".join(text.split())
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def listed(values: Any) -> str:
    """Names for an error message: ``values`` sorted by their text, in a list's brackets, each worded by :func:`shown`
    (the repr of a list of strings; mixed types and ints beyond Python's int-to-str limit too)."""
    return "[" + ", ".join(shown(v) for v in sorted(values, key=shown)) + "]"


def keyword_names(func: Any) -> list[str]:
    """The names ``func`` (a function, method or class) takes by keyword, in order: ``self``, ``*args`` and
    ``**kwargs`` left out (what :func:`check_known` lists as a constructor's valid options)."""
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return [p.name for p in inspect.signature(func).parameters.values() if p.kind in kinds and p.name != "self"]


def check_known(options: Any, valid: Any, owner: str, hint: str = "") -> None:
    """Refuse option names of ``options`` not in ``valid``: one-line ValueError ``"unknown option(s) ['foo'] for
    <owner><hint>; valid options: a, b"`` (``none`` when nothing is valid).  Python's own "unexpected keyword
    argument" is a TypeError, which ``gym.make`` re-raises with the repr of every keyword argument appended (not one
    line for an array, Python's int-to-str error for a huge int): every entry point refuses alike with this."""
    unknown = set(options) - set(valid)
    if unknown:
        raise ValueError(f"unknown option(s) {listed(unknown)} for {owner}{hint}; valid options: "
                         f"{', '.join(valid) if valid else 'none'}")


def check_int(value: Any, name: str, minimum: int, maximum: int) -> int:
    """An int (a numpy integer too; bool, float and str refused) in [``minimum``, ``maximum``]; else one-line
    ValueError naming ``name``, the range and the value."""
    if (isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
            and minimum <= value <= maximum):
        return int(value)
    raise ValueError(f"{name} must be an int in [{minimum}, {maximum}], got {shown(value)} ({type(value).__name__})")


def check_positive(value: Any, name: str, *, maximum: float = math.inf, note: str = "") -> float:
    """:func:`check_number` with the range (0, ``maximum``]: a real, finite, positive number."""
    return check_number(value, name, minimum=0.0, maximum=maximum, note=note)


def _range_text(minimum: float, maximum: float, inclusive_minimum: bool, inclusive_maximum: bool) -> str:
    """" > 0", " >= 0", " <= 5", " < 5", " in (0, 10]", " in [1, 2)" or "" (no bound)."""
    has_min, has_max = minimum > -math.inf, maximum < math.inf
    if has_min and has_max:
        return f" in {'[' if inclusive_minimum else '('}{minimum:g}, {maximum:g}{']' if inclusive_maximum else ')'}"
    if has_min:
        return f" {'>=' if inclusive_minimum else '>'} {minimum:g}"
    if has_max:
        return f" {'<=' if inclusive_maximum else '<'} {maximum:g}"
    return ""
