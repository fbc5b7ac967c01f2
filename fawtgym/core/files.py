"""The YAML and JSON a user hands the package (scenario, vehicle, sweep and run files; ``--hp`` values): one reader,
one set of one-line errors.

A file that is missing, a directory, not UTF-8, not valid YAML/JSON, holds a key twice (both parsers keep the last
value without a word) or an integer beyond Python's int-to-str limit (the parsers raise Python's own "Exceeds the
limit" while reading, before any range check can run) is refused with a ValueError naming the file.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from fawtgym.core.checks import shown

#: the file name endings :func:`load_data` reads, and the parser of each
DATA_SUFFIXES = {".yaml": "yaml", ".yml": "yaml", ".json": "json"}


class ParseError(ValueError):
    """Text that is not valid YAML/JSON at all (a syntax error, a tag PyYAML cannot construct), as opposed to a
    mapping that holds a key twice or an integer beyond Python's int-to-str limit (plain ValueError)."""


class _DuplicateKey(ValueError):
    """A mapping holds ``key`` twice (``line``: where, 1-based, if known)."""

    def __init__(self, key: Any, line: int | None = None) -> None:
        super().__init__(key)
        self.key, self.line = key, line


def load_data(path: str | Path, what: str) -> Any:
    """The data of the YAML (``.yaml``/``.yml``, needs pyyaml) or JSON file ``path``; ``what`` names it in errors
    (``"scenario file"``)."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{what} {shown(str(p))} is a directory, not a file")
    if not p.is_file():
        raise ValueError(f"{what} {shown(str(p))} does not exist")
    kind = DATA_SUFFIXES.get(p.suffix.lower())
    if kind is None:
        raise ValueError(f"{what} {shown(str(p))} must end in {', '.join(DATA_SUFFIXES)}")
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what} {p} is not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset {exc.start}); "
                         f"it must be {kind.upper()}") from None
    except OSError as exc:
        raise ValueError(f"{what} {p} cannot be read: {exc.strerror or exc}") from None
    return parse_data(text, f"{what} {p}", kind)


def parse_data(text: str, where: str, kind: str = "yaml") -> Any:
    """``text`` parsed as ``kind`` (``"yaml"`` | ``"json"``); ``where`` names it in errors."""
    try:
        if kind == "json":
            return json.loads(text, object_pairs_hook=_unique_pairs)
        return _load_yaml(text, where)
    except _DuplicateKey as exc:
        at = f" (line {exc.line})" if exc.line else ""
        raise ValueError(f"{where}: key {shown(exc.key)} appears twice{at}; give each key once") from None
    except ParseError:  # _load_yaml's, already named
        raise
    except json.JSONDecodeError as exc:
        raise ParseError(f"{where} is not valid JSON: {exc}") from None
    except ValueError as exc:
        if "integer string conversion" in str(exc):  # Python's int-to-str limit, raised while parsing
            raise ValueError(f"{where} holds an integer of more than {sys.get_int_max_str_digits()} digits (no "
                             "option takes one)") from None
        # a tag PyYAML could not construct ("!!int abc"): Python's own text, named as the file's
        raise ParseError(f"{where} is not valid {kind.upper()}: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise ParseError(f"{where} is nested too deeply to read") from None


def _unique_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object, refusing a key given twice."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def _load_yaml(text: str, where: str) -> Any:
    try:
        import yaml
    except ImportError as exc:  # pragma: no cover - pyyaml is in the test extra
        raise ValueError(f"reading {where} needs pyyaml (pip install 'fawtgym[yaml]')") from exc

    class UniqueKeyLoader(yaml.SafeLoader):
        """PyYAML's safe loader, refusing a mapping key given twice."""

        def construct_mapping(self, node: Any, deep: bool = False) -> Any:
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":  # "<<: *anchor" (merged keys may be overridden)
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                    seen.add(key)
                except TypeError:  # an unhashable key: PyYAML's own error follows
                    continue
                if duplicate:
                    raise _DuplicateKey(key, key_node.start_mark.line + 1)
            return super().construct_mapping(node, deep=deep)

    try:
        return yaml.load(text, Loader=UniqueKeyLoader)  # a SafeLoader subclass
    except yaml.YAMLError as exc:
        problem, mark = getattr(exc, "problem", None), getattr(exc, "problem_mark", None)
        detail = (f"{problem} at line {mark.line + 1}, column {mark.column + 1}" if problem and mark
                  else " ".join(str(exc).split()))
        raise ParseError(f"{where} is not valid YAML: {detail}") from None
