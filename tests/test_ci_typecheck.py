"""``.ci/typecheck.py`` lays out the installed package as symlinks and maps mypy's paths back to the repository."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture()
def typecheck(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    spec = importlib.util.spec_from_file_location("ci_typecheck", ROOT / ".ci" / "typecheck.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(module, "TREE", tmp_path / "tree")
    return module


def test_tree_is_the_installed_layout(typecheck) -> None:
    mapping = typecheck.build_tree()
    tree = typecheck.TREE
    # every package of [tool.setuptools.package-dir] is where the wheel puts it, and is the source itself
    assert (tree / "fawtgym" / "envs" / "hover_env.py").resolve() == ROOT / "envs" / "hover_env.py"
    assert (tree / "fawtgym" / "eval" / "reproduce" / "table4.py").resolve() == ROOT / "eval/reproduce/table4.py"
    assert (tree / "fawtgym" / "core" / "so3.py").resolve() == ROOT / "fawtgym" / "core" / "so3.py"
    assert (tree / "fawtgym" / "cli.py").resolve() == ROOT / "fawtgym" / "cli.py"
    assert set(mapping.values()) >= {ROOT / "envs", ROOT / "observers", ROOT / "fawtgym"}
    typecheck.build_tree()  # rebuilding over an existing tree works


@pytest.mark.parametrize(("line", "expected"), [
    ("fawtgym/envs/hover_env.py:12: error: x  [attr-defined]", "envs/hover_env.py:12: error: x  [attr-defined]"),
    ("fawtgym/envs/wind/dryden.py:3: note: y", "envs/wind/dryden.py:3: note: y"),
    ("fawtgym/flightlog/tlog.py:9: error: z", "fawtgym/flightlog/tlog.py:9: error: z"),
    ("fawtgym/eval/bench/env.py:1: error: w", "eval/bench/env.py:1: error: w"),
    ("Found 3 errors in 2 files (checked 128 source files)", "Found 3 errors in 2 files (checked 128 source files)"),
])
def test_mypy_lines_get_the_repository_paths(typecheck, line: str, expected: str) -> None:
    mapping = typecheck.build_tree()
    assert typecheck.to_repo_path(line, mapping) == expected
