"""Packaging: the wheel holds only ``fawtgym`` (+ its dist-info); the CLI lists its subcommands."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_wheel_contains_only_the_fawtgym_package(tmp_path):
    pytest.importorskip("build")
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(tmp_path), str(ROOT)],
                   check=True, capture_output=True, text=True)
    (wheel,) = tmp_path.glob("fawtgym-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert tops == {"fawtgym", next(t for t in tops if t.endswith(".dist-info"))}, tops
    for sub in ("envs", "envs/wind", "observers", "agents", "train", "eval", "eval/reproduce", "eval/bench"):
        assert f"fawtgym/{sub}/__init__.py" in names, sub
    # every source module of the repo folders made it into the wheel
    for folder, pkg in (("envs", "envs"), ("observers", "observers"), ("agents", "agents"), ("eval", "eval")):
        for src in (ROOT / folder).rglob("*.py"):
            assert f"fawtgym/{pkg}/{src.relative_to(ROOT / folder).as_posix()}" in names, src


def test_every_source_folder_is_a_listed_package():
    import tomllib

    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    for folder in ("envs", "observers", "agents", "train", "eval"):
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT).as_posix().replace("/", ".")
            assert f"fawtgym.{rel}" in listed, f"fawtgym.{rel} missing from [tool.setuptools] packages"


def test_cli_help_lists_subcommands():
    out = subprocess.run([sys.executable, "-m", "fawtgym.cli", "--help"], check=True, capture_output=True,
                         text=True).stdout
    for cmd in ("demo", "list", "wind", "reproduce", "bench"):
        assert cmd in out
    out = subprocess.run([sys.executable, "-m", "fawtgym.cli", "reproduce", "--help"], check=True,
                         capture_output=True, text=True).stdout
    assert "seed000-sim" in out and "table4" in out


def test_cli_list_runs():
    out = subprocess.run([sys.executable, "-m", "fawtgym.cli", "list"], check=True, capture_output=True,
                         text=True).stdout
    assert "s500" in out and "fawtgym/Hover-v0" in out
