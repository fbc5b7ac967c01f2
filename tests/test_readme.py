"""Every code block of the README works: Python blocks run, YAML blocks are valid scenario files, and every
``fawtgym`` command in a bash block names a real subcommand whose ``--help`` knows each of its flags."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCK = re.compile(r"```(\w*)\n(.*?)```", re.S)


def blocks(lang: str) -> list[str]:
    return [body for kind, body in BLOCK.findall(README.read_text()) if kind == lang]


def test_readme_has_the_two_quick_start_commands() -> None:
    first = blocks("bash")[0].strip().splitlines()
    assert first[0].startswith('pip install -e ".[plot]" && fawtgym eval')
    assert first[1] == 'pip install -e ".[test]" && python -m pytest -n 2'
    ci = (README.parent / ".ci" / "run").read_text()
    assert 'pip install -e ".[test]" && python -m pytest -n 2' in ci


@pytest.mark.parametrize("index", range(len(blocks("python"))))
def test_python_block_runs(index: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code = blocks("python")[index]
    exec(compile(code, f"README.md python block {index}", "exec"), {"__name__": "__readme__"})


@pytest.mark.parametrize("index", range(len(blocks("yaml"))))
def test_yaml_block_is_a_valid_scenario_file(index: int, tmp_path: Path) -> None:
    from fawtgym.eval.scenarios import check_scenario, load_scenarios

    path = tmp_path / "scenarios.yaml"
    path.write_text(blocks("yaml")[index])
    for sc in load_scenarios(path):
        check_scenario(sc)


def fawtgym_commands() -> list[list[str]]:
    out = []
    for body in blocks("bash"):
        for line in body.splitlines():
            for part in line.split("&&"):
                words = shlex.split(part.split("#")[0])
                if words and words[0] == "fawtgym":
                    out.append(words[1:])
    return out


@pytest.mark.parametrize("words", fawtgym_commands(), ids=lambda w: " ".join(w)[:60])
def test_bash_fawtgym_command_is_real(words: list[str]) -> None:
    from fawtgym.cli import main

    sub = [w for w in words[:2] if not w.startswith("-")]
    if sub and sub[0] in ("reproduce", "bench"):
        sub = sub[:2]
    else:
        sub = sub[:1]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit) as exc:
        main([*sub, "--help"])
    assert exc.value.code == 0
    help_text = buf.getvalue()
    for flag in (w.split("=")[0] for w in words if w.startswith("--")):
        assert flag in help_text, f"fawtgym {' '.join(sub)} has no {flag}"
