"""Every subcommand refuses bad arguments with one line on stderr, exit code 2 and no traceback.

The cases are run in-process through ``fawtgym.cli.main`` (as the ``fawtgym`` script runs them), so a
traceback would fail the test with the exception; two are also run as a real process.  Every case
must be refused before any long work starts (the whole file runs in seconds).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fawtgym.cli import main

CASES = [
    # the dispatcher
    ["nosuch"],
    ["reproduce", "nosuch"],
    ["bench", "nosuch"],
    ["bench", "all", "--steps", "5"],
    # wind
    ["wind", "--preset", "fawt", "--duty", "120"],
    ["wind", "--preset", "fawt", "--duty", "1.2"],
    ["wind", "--preset", "fawt", "--duty", "-0.5"],
    ["wind", "--preset", "fawt-50", "--duty", "30"],
    ["wind", "--preset", "nosuch"],
    ["wind", "--seconds", "-5"],
    ["wind", "--seconds", "0"],
    ["wind", "--seconds", "nan"],
    ["wind", "--dt", "0"],
    ["wind", "--fields", "0"],
    ["wind", "--seed", "-1"],
    ["wind", "--seconds", "1e9"],
    ["wind", "--plot", "/nonexistent/dir/w.png"],
    ["wind", "--plot", "a_file/w.png"],
    ["wind", "--plot", "w.txt"],
    # demo
    ["demo", "--duty", "120"],
    ["demo", "--duty", "0.5"],
    ["demo", "--duty", "45"],
    ["demo", "--seed", "-3"],
    ["demo", "--seconds", "1e9"],
    ["demo", "--seconds", "0"],
    ["demo", "--seconds", "2", "--fan-on", "-1"],
    ["demo", "--seconds", "2", "--fan-on", "5"],
    # list
    ["list", "--bogus"],
    # eval and leaderboard
    ["eval", "--seeds", "-1"],
    ["eval", "--workers", "0"],
    ["eval", "--agents", "nosuch"],
    ["eval", "--scenarios", "nosuch"],
    ["eval", "--wind", "fawt-50", "--duration", "-1"],
    ["eval", "--out", "a_file/results"],
    ["leaderboard", "/nonexistent/results"],
    ["eval", "--wind", "calm", "--duration", "1e-300"],  # was flown as one 0.005 s step under the name calm-1e-300s
    ["eval", "--wind", "calm", "--duration", "1", "--record-hz", "1e-300"],  # the sample interval overflowed
    ["eval", "--agents", "px4+leso", "--wind", "calm", "--duration", "1", "--baseline", "nope"],  # was accepted
    ["eval", "--agents", "px4(MPC_XY_P=1, MPC_XY_P=2)"],  # the last value was kept silently
    ["eval", "--agents", "px4(FOO=1)(MPC_XY_P=2)"],  # FOO was dropped unchecked
    # train
    ["train", "--eval-every", "0"],  # divided by zero after the env was built
    ["train", "--hp", "n_steps=0"],  # Stable-Baselines3's assertion traceback
    ["train", "--hp", "clip_range=.nan"],  # trained on NaN
    ["train", "--algo", "nosuch"],
    ["train", "--obs", "nosuch"],
    ["train", "--steps", "0"],
    ["train", "--seed", "-1"],
    ["train", "--scenario", "nosuch"],
    ["train", "--episode-seconds", "-1"],
    ["train", "--episode-seconds", "1e-300"],  # trained on one-step episodes
    ["train", "--out", "a_file/run"],
    # reproductions
    ["reproduce", "seed000-sim", "--seconds", "-1"],
    ["reproduce", "seed000-sim", "--seed", "-1"],
    ["reproduce", "geso", "--t-end", "-1"],
    ["reproduce", "geso", "--dt", "0"],
    ["reproduce", "hc-eso", "--step", "0"],
    ["reproduce", "hc-eso", "--seed", "-1"],
    ["reproduce", "qb", "--t-end", "-1"],
    ["reproduce", "qb", "--mu", "2"],
    ["reproduce", "qb", "--design-for", "nosuch"],
    ["reproduce", "qb", "--solver", "nosuch"],
    ["reproduce", "pdt-sta", "--ts", "0"],
    ["reproduce", "pdt-sta", "--t-final", "-1"],
    ["reproduce", "pdt-sta", "--seed", "-1"],
    ["reproduce", "all", "--only", "nosuch"],
    ["reproduce", "seed000-sim", "--out", "a_file/x"],
    ["reproduce", "geso", "--out", "a_file/x"],
    ["reproduce", "hc-eso", "--out", "a_file/x"],
    ["reproduce", "qb", "--out", "a_file/x"],
    ["reproduce", "pdt-sta", "--out", "a_file/x"],
    ["reproduce", "all", "--out", "a_file/x"],
    ["reproduce", "table4", "--sensors", "foo"],
    ["reproduce", "table4", "--control-rate", "333"],
    ["reproduce", "table4", "--quick", "--duties", "120"],
    ["reproduce", "table4", "--seeds", "0"],
    # flight logs, SITL and replay
    ["observe", "/nonexistent/log.ulg", "--observer", "ffts_eso", "--vehicle", "s500"],
    ["observe", "a_file", "--observer", "ffts_eso", "--vehicle", "s500"],
    ["observe", "a_file", "--observer", "nosuch", "--vehicle", "s500"],
    ["observe", "a_file", "--observer", "ffts_eso", "--vehicle", "nosuch"],
    ["observe", "a_file", "--observer", "ffts_eso", "--vehicle", "s500", "--rate", "0"],
    ["observe", "a_file", "--observer", "ffts_eso", "--vehicle", "s500", "--rate", "1e300"],  # numpy's size error
    ["observe", ".", "--observer", "ffts_eso", "--vehicle", "s500"],  # a folder: it said "does not exist"
    ["sitl", "px4", "--sim-duration", "nan"],  # refused only after PX4 connected
    ["sitl", "px4", "--bridge-tlog", "a_file/x.tlog"],  # refused only after PX4 connected
    ["sitl", "px4", "--log", "a_file"],  # FileExistsError
    ["replay", "--agent", "px4", "--tlog", "a_file/x.tlog"],  # refused only after the autopilot answered
    ["replay", "--agent", "px4", "--rate", "1e300"],  # named the env's control_rate
    ["wind", "--preset", "fawt", "--duty", "50%%"],  # was read as 50
    ["sitl", "px4", "--port", "-1"],
    ["sitl", "px4", "--wind", "nosuch"],
    ["sitl", "px4", "--seed", "-1"],
    ["sitl", "nosuch"],
    ["replay", "--agent", "nosuch"],
    ["replay", "--agent", "px4", "--rate", "10"],
    ["replay", "--agent", "px4", "--connect", "nosuch:1:2"],
    # benchmarks
    ["bench", "flightlog", "--minutes", "0"],
    ["bench", "flightlog", "--observer", "nosuch"],
    ["bench", "env", "--steps", "0"],
    ["bench", "env", "--control-rate", "333"],
    ["bench", "env", "--integrator", "nosuch"],
    ["bench", "wind", "--batch", "0"],
    ["bench", "wind", "--calls", "-1"],
    ["bench", "observers", "--n", "0"],
    ["bench", "observers", "--only", "nosuch"],
    ["bench", "closed-loop", "--steps", "0"],
    ["bench", "closed-loop", "--control-rate", "333"],
    ["bench", "qb-sdp", "--alpha", "-1"],
    ["bench", "qb-sdp", "--solver", "nosuch"],
    ["bench", "eval", "--seeds", "0"],
    ["bench", "eval", "--workers", "0"],
    ["bench", "train", "--steps", "0"],
    ["bench", "train", "--threads", "0"],
    ["bench", "train", "--rows", "0"],
    ["bench", "render", "--frames", "0"],
]


def _id(case: object) -> str:
    values = case.values[0] if hasattr(case, "values") else case
    return " ".join(values)  # type: ignore[arg-type]


@pytest.mark.parametrize("argv", CASES, ids=[_id(c) for c in CASES])
def test_bad_arguments_give_one_line(argv: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # nothing a refused command might write lands in the repository
    (tmp_path / "a_file").write_text("a file, not a folder\n")  # no folder can be made under it, even as root
    with pytest.raises(SystemExit) as exc:
        raise SystemExit(main(argv))
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert exc.value.code == 2, err
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert "error" in lines[0]


BIG = "9" * 5000


@pytest.mark.parametrize("argv", [["train", "--seed", BIG], ["eval", "--agents", f"px4(MPC_XY_P={BIG})"],
                                  ["eval", "--agents", f"sb3:{BIG}"], ["leaderboard", "x", "--baseline", BIG]],
                         ids=["argparse int", "override", "sb3 path", "baseline"])
def test_a_huge_value_is_cut_in_the_one_line(argv: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """The 5000 digits were repeated in full (5 kB lines), or Python's int-to-str error leaked."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit):
        raise SystemExit(main(argv))
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and len(err) < 800 and "Exceeds the limit" not in err, err[:300]


def _help_argvs() -> list[object]:
    from fawtgym.cli import BENCHMARKS, COMMANDS, REPRODUCTIONS

    out: list[object] = [["--help"], ["bench", "all", "--help"]]
    out += [[c, "--help"] for c in COMMANDS]
    for name in REPRODUCTIONS:
        argv = ["reproduce", name, "--help"]
        out.append(argv)
    out += [["bench", name, "--help"] for name in BENCHMARKS]
    return out


HELP_ARGVS = _help_argvs()


@pytest.mark.parametrize("argv", HELP_ARGVS, ids=[_id(c) for c in HELP_ARGVS])
def test_help_texts_speak_plainly(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """Help names papers by author and year: no internal file names, issue numbers or RST markup."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for word in ("seed-0", "issue ", "``", "_wang2024", ".txt", ":mod:", ":func:"):
        assert word not in out, (argv, word)


def test_bench_all_help_lists_every_benchmark(capsys: pytest.CaptureFixture[str]) -> None:
    from fawtgym.cli import BENCHMARKS

    with pytest.raises(SystemExit):
        main(["bench", "all", "--help"])
    out = capsys.readouterr().out
    assert all(name in out for name in BENCHMARKS)


def test_real_process_one_line(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    for argv in (["wind", "--seed", "-1"], ["demo", "--seconds", "1e9"]):
        p = subprocess.run([sys.executable, "-m", "fawtgym", *argv], capture_output=True, text=True, env=env,
                           cwd=tmp_path, timeout=120)
        assert p.returncode == 2, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr, p.stderr
        assert p.stdout == ""
