"""The Python blocks of docs/first-hour.md run, and its fawtgym commands and flags exist (as the README's)."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[1] / "docs" / "first-hour.md"
BLOCK = re.compile(r"```(\w*)\n(.*?)```", re.S)


def blocks(lang: str) -> list[str]:
    return [body for kind, body in BLOCK.findall(PAGE.read_text()) if kind == lang]


@pytest.mark.parametrize("index", range(len(blocks("python"))))
def test_python_block_runs(index: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    code = blocks("python")[index]
    if "RecordVideo" in code:
        pytest.importorskip("moviepy", reason="RecordVideo needs moviepy (fawtgym[video])")
    monkeypatch.chdir(tmp_path)
    exec(compile(code, f"first-hour.md python block {index}", "exec"), {"__name__": "__first_hour__"})
    if "RecordVideo" in code:
        assert list((tmp_path / "videos").glob("*.mp4"))


def commands() -> list[list[str]]:
    out = []
    for body in blocks("bash"):
        for line in body.splitlines():
            words = shlex.split(line.split("#")[0])
            if words and words[0] == "fawtgym":
                out.append(words[1:])
    return out


@pytest.mark.parametrize("words", commands(), ids=lambda w: " ".join(w)[:60])
def test_command_and_flags_exist(words: list[str]) -> None:
    from fawtgym.cli import main

    sub = [w for w in words[:2] if not w.startswith("-")]
    sub = sub[:2] if sub and sub[0] in ("reproduce", "bench") else sub[:1]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit) as exc:
        main([*sub, "--help"])
    assert exc.value.code == 0
    for flag in (w.split("=")[0] for w in words if w.startswith("--")):
        assert flag in buf.getvalue(), f"fawtgym {' '.join(sub)} has no {flag}"
