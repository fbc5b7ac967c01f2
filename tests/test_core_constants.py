"""Physical constants live once, in fawtgym.core.constants (DESIGN.md: core holds the shared constants): gravity and
the Earth field are the same objects wherever they are imported from, the physics uses the same g, and no module
outside core types the number again."""

from __future__ import annotations

import io
import tokenize
from pathlib import Path

import numpy as np

from fawtgym.core import constants, measurement
from fawtgym.envs import vehicles

ROOT = Path(__file__).resolve().parents[1]
#: the package's source folders (the package-dir mapping of pyproject.toml)
SOURCES = ("fawtgym", "envs", "observers", "agents", "train", "eval")
#: files allowed to type g (none: the observers' defaults use the core constant too)
PENDING: set[str] = set()


def test_gravity_is_standard_gravity_and_one_object() -> None:
    assert constants.GRAVITY == 9.80665  # the CGPM's standard acceleration of free fall, PX4's CONSTANTS_ONE_G
    assert vehicles.GRAVITY is constants.GRAVITY  # the env's name is a re-export, not a second definition
    assert measurement.EARTH_FIELD_NED is constants.EARTH_FIELD_NED


def test_the_physics_falls_with_the_same_g() -> None:
    import gymnasium as gym

    import fawtgym  # noqa: F401  (registers the env ids)

    env = gym.make("fawtgym/Hover-v0")
    np.testing.assert_array_equal(env.unwrapped.model.opt.gravity, [0.0, 0.0, -constants.GRAVITY])  # MuJoCo z-up
    env.close()


def _numbers(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every numeric literal in ``path``'s code (comments and strings, i.e. docs, are not code)."""
    tokens = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
    return [(t.start[0], t.string) for t in tokens if t.type == tokenize.NUMBER]


def test_no_module_outside_core_types_gravity_again() -> None:
    found = {}
    for folder in SOURCES:
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel == "fawtgym/core/constants.py" or rel in PENDING:
                continue
            lines = [line for line, text in _numbers(path) if text.startswith("9.80665")]
            if lines:
                found[rel] = lines
    assert not found, f"import GRAVITY from fawtgym.core.constants instead of typing 9.80665: {found}"


def test_the_scan_sees_a_literal() -> None:
    """The scan above finds the number in code and not in documentation (so it can fail)."""
    src = '"""g = 9.80665 in a docstring"""\nG = 9.80665  # 9.80665 in a comment\n'
    tokens = tokenize.generate_tokens(io.StringIO(src).readline)
    assert [(t.start[0], t.string) for t in tokens if t.type == tokenize.NUMBER] == [(2, "9.80665")]
