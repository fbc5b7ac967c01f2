"""The YAML/JSON files a user hands the package (scenario, vehicle, sweep, run files) and the files a run leaves
(traces): one reader (:mod:`fawtgym.core.files`), one line per error naming the file, no library message."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from fawtgym.core.files import load_data, parse_data
from fawtgym.envs.vehicles import make_vehicle
from fawtgym.eval.runner import read_run, read_traces
from fawtgym.eval.scenarios import load_scenarios
from fawtgym.train.cli import sweep_configs

BIG = "9" * 5000  # beyond Python's 4300-digit int-to-str limit: the parsers raised Python's "Exceeds the limit"


def _one_line(err: pytest.ExceptionInfo[BaseException]) -> str:
    text = str(err.value)
    assert "\n" not in text and len(text) < 600, text
    return text


def _refused(load: Callable[[Path], object], path: Path, content: str, match: str) -> None:
    """``load`` of a file holding ``content`` raises one ValueError line matching ``match``."""
    path.write_text(content)
    with pytest.raises(ValueError, match=match) as err:
        load(path)
    _one_line(err)


@pytest.mark.parametrize("name, content, match", [
    ("a.yaml", b"a: 1\na: 2\n", r"a.yaml: key 'a' appears twice \(line 2\)"),
    ("a.json", b'{"a": 1, "a": 2}', r"a.json: key 'a' appears twice"),
    ("a.yaml", b"a: " + BIG.encode(), r"a.yaml holds an integer of more than 4300 digits"),
    ("a.json", b'{"a": ' + BIG.encode() + b"}", r"a.json holds an integer of more than 4300 digits"),
    ("a.yaml", b"a: [1, 2\n", r"a.yaml is not valid YAML: expected ',' or '\]', but got '<stream end>' at line 2"),
    ("a.json", b'{"a": ', r"a.json is not valid JSON: Expecting value"),
    ("a.yaml", b"a: \xe3\x28\n", r"a.yaml is not UTF-8 text \(byte 0xe3 at offset 3\); it must be YAML"),
    ("a.txt", b"a: 1\n", r"a.txt' must end in .yaml, .yml, .json"),
])
def test_a_bad_file_is_one_line_naming_it(tmp_path: Path, name: str, content: bytes, match: str) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ValueError, match=match) as err:
        load_data(path, "scenario file")
    assert _one_line(err).startswith("scenario file ")
    assert str(err.value).count("scenario file") == 1  # a YAML syntax error was named twice ("...: f is not valid")


def test_missing_file_and_directory_are_told_apart(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"does not exist$"):
        load_data(tmp_path / "nope.yaml", "sweep file")
    (tmp_path / "dir.yaml").mkdir()
    with pytest.raises(ValueError, match=r"is a directory, not a file$"):
        load_data(tmp_path / "dir.yaml", "sweep file")


def test_valid_files_read_as_before() -> None:
    assert parse_data("b: &x {c: 1}\nd:\n  <<: *x\n  c: 2\n", "f") == {"b": {"c": 1}, "d": {"c": 2}}  # merge keys
    assert parse_data('{"a": [1, 2.5, null]}', "f", "json") == {"a": [1, 2.5, None]}
    assert parse_data("1e-4", "f") == "1e-4"  # YAML 1.1, as PyYAML's safe loader reads it


@pytest.mark.parametrize("content, match", [
    ("wind: calm\ndescription: 5\n", r"description must be a str of at most 2000 characters, got 5 \(int\)"),
    ("wind: calm\ndescription: [1]\n", r"description must be a str"),  # it was flown, then the leaderboard crashed
    ("wind: null\n", r"wind must be a wind name or a mapping with 'name', got None"),  # it was flown as calm
    ("wind: calm\nvehicle: 5\n", r"vehicle must be a name or a mapping of fields"),
    ("wind: calm\nseconds: 1\nseconds: 2\n", r"key 'seconds' appears twice \(line 3\)"),
    (f"wind: calm\nseconds: {BIG}\n", r"holds an integer of more than 4300 digits"),
])
def test_scenario_file_fields_are_checked_when_loaded(tmp_path: Path, content: str, match: str) -> None:
    _refused(load_scenarios, tmp_path / "s.yaml", content, match)


def test_vehicle_file_errors(tmp_path: Path) -> None:
    path = tmp_path / "v.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match=r"vehicle file .*v.yaml must hold a mapping of vehicle fields, got list"):
        make_vehicle(path)
    path.write_text(f"base: s500\nmass: {BIG}\n")
    with pytest.raises(ValueError, match=r"v.yaml holds an integer of more than 4300 digits"):
        make_vehicle(path)
    with pytest.raises(ValueError, match=r"vehicle file .*gone.yaml' does not exist"):
        make_vehicle(tmp_path / "gone.yaml")


@pytest.mark.parametrize("content, match", [
    ("grid: 5\n", r"grid must be a mapping, got 5"),
    ("grid: {foo: [1]}\n", r"unknown option\(s\) \['foo'\] for sweep file .* \(base, grid\); valid options: action, "),
    ("base: [1, 2]\n", r"base must be a mapping, got \[1, 2\]"),
    ("hp: [1]\n", r"hp must be a mapping"),
    ("seeds: abc\n", r"seeds must be a seed or a non-empty list of seeds, got 'abc'"),
    ("seeds: [1.5]\n", r"a seed must be an int in \[0, 4294967295\], got 1.5 \(float\)"),
    ("out: 5\n", r"out must be a folder name \(a non-empty str\), got 5"),
    ("grid: {hp: [5]}\n", r"a point's hp must be a mapping, got 5"),
    ("hp: {n_steps: 0}\n", r"ppo hyperparameter n_steps must be an int in \[1, 10000000\], got 0"),
])
def test_sweep_file_shape_is_checked(tmp_path: Path, content: str, match: str) -> None:
    _refused(sweep_configs, tmp_path / "sw.yaml", content, match)


def test_sweep_point_hyperparameters_reach_every_seed(tmp_path: Path) -> None:
    """A grid point's ``hp`` was popped while building its first seed's run: the other seeds trained without it."""
    path = tmp_path / "sw.yaml"
    path.write_text("base: {steps: 10}\ngrid: {hp: [{n_steps: 64}, {n_steps: 128}]}\nseeds: [0, 1, 2]\n")
    _, runs = sweep_configs(path)
    got = sorted((cfg.seed, dict(cfg.hyperparams)["n_steps"]) for cfg, _ in runs)
    assert got == [(seed, n) for seed in (0, 1, 2) for n in (64, 128)]
    assert sorted(folder.name for _, folder in runs)[:2] == ["n_steps_128-s0", "n_steps_128-s1"]  # not "{'n_steps'..."


@pytest.mark.parametrize("content, match", [
    ("[1, 2]", r"must hold a JSON object, got list"),
    ("{}", r"agents must be a list of agent names, got None"),
    ('{"agents": 5, "scenarios": [], "seeds": [1]}', r"agents must be a list of agent names, got 5"),
    ('{"agents": ["px4"], "scenarios": [null], "seeds": [1]}', r"scenarios must be a list of scenario records"),
    ('{"agents": ["px4"], "scenarios": [], "seeds": 3}', r"seeds must be a list, got 3"),
    ('{"agents": ["px4"], "scenarios": [], "seeds": [1.5]}', r"seeds"),
    ('{"agents": ["px4"], "scenarios": [], "seeds": [' + BIG + "]}", r"holds an integer of more than 4300 digits"),
])
def test_run_file_shape_is_checked(tmp_path: Path, content: str, match: str) -> None:
    _refused(read_run, tmp_path / "run.json", content, match)


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04" + bytes(200), bytes(range(256))],
                         ids=["empty", "truncated zip", "garbage"])
def test_unreadable_traces_name_the_file(tmp_path: Path, content: bytes) -> None:
    """EOFError, BadZipFile and numpy's allow_pickle message became one line naming the cell's file."""
    npz = tmp_path / "cells" / "calm" / "px4.npz"
    npz.parent.mkdir(parents=True)
    npz.write_bytes(content)
    with pytest.raises(ValueError, match=r"px4.npz is not a readable trace file of 'fawtgym eval' .*delete it and "
                                         r"px4.json beside it, and run the cell again$") as err:
        read_traces(tmp_path, "px4", "calm")
    _one_line(err)
    good = tmp_path / "cells" / "calm" / "ok.npz"
    np.savez(good, t=np.arange(3.0))
    assert read_traces(tmp_path, "ok", "calm")["t"].tolist() == [0.0, 1.0, 2.0]


@pytest.mark.parametrize("content", [b"\xe3\x28", b"[1, 2]", b'{"a": ' + BIG.encode() + b"}", b"{"],
                         ids=["not UTF-8", "a list", "huge int", "cut"])
def test_an_unreadable_cell_record_is_an_unfinished_cell(tmp_path: Path, content: bytes) -> None:
    """read_cell raised UnicodeDecodeError (and callers AttributeError on a list): the cell is flown again instead."""
    from fawtgym.eval.runner import read_cell

    path = tmp_path / "cell.json"
    path.write_bytes(content)
    assert read_cell(path) is None
