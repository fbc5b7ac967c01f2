"""The evaluation runner, the agent grammar, scenarios and the leaderboard (fawtgym eval / leaderboard)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fawtgym.agents.spec import make_agent, parse_agent, parse_agents, split_agents
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.eval import leaderboard as lb
from fawtgym.eval.runner import cell_paths, load_run, read_traces, run_cells, update_run_file
from fawtgym.eval.runner_cli import main as eval_main
from fawtgym.eval.scenarios import get_scenario, load_scenarios, resolve_scenarios, scenario_from_mapping

TESTS = Path(__file__).parent
SHORT = {"name": "short-fawt", "wind": {"name": "fawt-50", "on_time": 0.2}, "seconds": 1.0}
SHORT_CALM = {"name": "short-calm", "wind": "calm", "seconds": 0.5}


# ---- agent grammar -----------------------------------------------------------------------------
def test_agent_grammar() -> None:
    assert parse_agent("px4").name == "px4"
    spec = parse_agent(" px4+geso( order = 3 ) ")
    assert spec.kind == "px4+observer" and spec.observer == "geso" and spec.name == "px4+geso(order=3)"
    assert parse_agent("px4(MPC_XY_P=1.2, position_rate=50)").name == "px4(MPC_XY_P=1.2, position_rate=50)"
    assert parse_agent("_plugin_agent:HoverHold(level=0.3)").kind == "plugin"
    assert parse_agent("sb3:runs/best.zip").target == "runs/best.zip"
    assert split_agents("px4,px4+geso(order=3, omega_t=4.0),px4+leso") == \
        ["px4", "px4+geso(order=3, omega_t=4.0)", "px4+leso"]
    assert [s.name for s in parse_agents("px4, px4+ffts_eso")] == ["px4", "px4+ffts_eso"]


@pytest.mark.parametrize("text, match", [
    ("foo", "unknown agent 'foo'; valid: px4, px4\\+ffts_eso"),
    ("px4+nope", "unknown observer 'nope'; registered observers: ffts_eso"),
    ("px4+geso(order=)", "cannot read the keyword overrides"),
    ("px4+geso(3)", "key=value"),
    ("px4+geso(order=len)", "must be a Python literal"),
    ("px4,px4", "given twice"),
    ("px4+geso(order=3", "unbalanced"),
    ("bad module:X", "module:Class"),
    ("px4(MPC_XY_P=1, MPC_XY_P=2)", "MPC_XY_P is given twice"),  # ast keeps the last one: it was flown silently
    ("px4(FOO=1)(MPC_XY_P=2)", "one group of key=value pairs"),  # a call of a call: FOO was dropped unchecked
    ("px4(MPC_XY_P=" + "9" * 5000 + ")", "an int of more than 4300 digits, beyond any option's range$"),
    ("sb3:" + "9" * 5000, "is not a folder of 'fawtgym train'"),  # OSError: File name too long (with the 5 kB name)
])
def test_agent_grammar_errors(text: str, match: str) -> None:
    with pytest.raises(ValueError, match=match) as err:
        specs = parse_agents(text)
        if specs[0].kind == "sb3":  # the path is read when the agent is built
            from fawtgym.agents.sb3_agent import locate_run

            locate_run(specs[0].target)
    assert "\n" not in str(err.value) and len(str(err.value)) < 1000


def test_make_agent_errors_and_plugin() -> None:
    env = HoverBatchEnv(num_envs=2)
    _, info = env.reset(seed=0)
    for text, match in [("px4(MPC_XY_PP=1)", "unknown PX4 parameter 'MPC_XY_PP'"),
                        ("px4(order=2)", "unknown option 'order'"),
                        ("px4+leso(w0=3)", r"unknown option\(s\) \['w0'\] for observer leso; its gains: gravity, "
                                           "omega_t, omega_a"),
                        ("px4+geso(order=9)", "GESO order must be one of"),
                        ("sb3:x.zip", "is not a folder of .fawtgym train."),
                        ("nosuch_module_xyz:A", "cannot import module 'nosuch_module_xyz'"),
                        ("_plugin_agent:Missing", "has no 'Missing'; Agent classes in it: \\['HoverHold'\\]"),
                        ("_plugin_agent:NotAnAgent", "not a subclass")]:
        with pytest.raises(ValueError, match=match):
            make_agent(text, env)
    agent = make_agent("_plugin_agent:HoverHold", env)
    agent.reset(info)
    assert np.allclose(agent.act(None, info), env.hover_action())
    eso = make_agent("px4+ffts_eso", env).observer  # the flight gains of Wang et al. (2024) Sec. 7.2
    assert (eso.kt1, eso.kt2, eso.kt3, eso.ka1) == (6.0, 3.0, 1.0, 8.0)
    assert make_agent("px4+ffts_eso(kt1=5.0)", env).observer.kt1 == 5.0
    env.close()


# ---- scenarios ---------------------------------------------------------------------------------
def test_scenarios_builtin_and_files(tmp_path: Path) -> None:
    t4 = get_scenario("table4-50")
    assert t4.fan_schedule == (5.0, 50.0) and t4.seconds == 75.0 and t4.duty == 50 and t4.sensors == "mocap_imu"
    assert get_scenario("fawt-55-steady").wind == {"name": "fawt", "duty": 0.55}
    assert get_scenario("fawt-40-steady").duty == 40
    for bad in ("table4-55", "fawt-80-steady", "nope"):
        with pytest.raises(ValueError, match="unknown scenario"):
            get_scenario(bad)
    y = tmp_path / "mine.yaml"
    y.write_text("windy:\n  wind: {name: fawt-30, on_time: 1.0}\n  seconds: 3\ncalm2:\n  wind: calm\n")
    scs = load_scenarios(y)
    assert [s.name for s in scs] == ["windy", "calm2"] and scs[0].seconds == 3
    j = tmp_path / "one.json"
    j.write_text(json.dumps(SHORT))
    assert resolve_scenarios([str(j), "calm"])[0].name == "short-fawt"
    with pytest.raises(ValueError, match="unknown field"):
        scenario_from_mapping("x", {"wind": "calm", "windspeed": 3})
    with pytest.raises(ValueError, match="needs a 'wind'"):
        scenario_from_mapping("x", {"seconds": 3})
    with pytest.raises(ValueError, match="does not exist"):
        load_scenarios(tmp_path / "nope.yaml")
    with pytest.raises(ValueError, match="given twice"):
        resolve_scenarios(["calm", "calm"])
    j.write_text(json.dumps({"x": SHORT}))
    with pytest.raises(ValueError, match="entry 'x' has name 'short-fawt'"):
        load_scenarios(j)


# ---- runner ------------------------------------------------------------------------------------
def _cells(out: Path, agents: list[str], scenarios: list[dict], seeds: list[int], **kw: object) -> dict:
    scs = [scenario_from_mapping(s["name"], s) for s in scenarios]
    update_run_file(out, agents, scs, seeds, "px4", "test", 20.0)
    return run_cells(out, agents, scs, seeds, progress=False, **kw)


def _numbers(out: Path) -> dict:
    run, cells = load_run(out)
    res = {}
    for (agent, sc), cell in cells.items():
        traces = read_traces(out, agent, sc)
        res[(agent, sc)] = (cell["episodes"], {k: v.tobytes() for k, v in traces.items()})
    return res


def test_run_is_paired_reproducible_and_resumes(tmp_path: Path) -> None:
    agents = ["px4", "px4+ffts_eso", "_plugin_agent:HoverHold"]
    s1 = _cells(tmp_path / "a", agents, [SHORT, SHORT_CALM], [0, 1], workers=1)
    assert not s1["errors"] and len(s1["done"]) == 6
    s2 = _cells(tmp_path / "b", agents, [SHORT, SHORT_CALM], [0, 1], workers=2)
    assert _numbers(tmp_path / "a") == _numbers(tmp_path / "b")  # same seeds, same numbers, bitwise
    again = _cells(tmp_path / "a", agents, [SHORT, SHORT_CALM], [0, 1], workers=1)
    assert again["done"] == [] and len(again["skipped"]) == 6
    assert not s2["errors"]
    _, cells = load_run(tmp_path / "a")
    eso = cells[("px4+ffts_eso", "short-fawt")]
    assert eso["observer"]["name"] == "ffts_eso" and eso["observer"]["kwargs"]["kt1"] == 6.0
    assert all(e["force_rmse"] is not None for e in eso["episodes"])
    assert all(e["force_rmse"] is None for e in cells[("px4", "short-fawt")]["episodes"])
    # paired: the wind each row met is the same realization for every agent (it depends on the position only
    # through the jet profile, so compare the calm-air sensor-noise-driven runs' wind: zero; and the fawt runs'
    # wind speed to a few percent)
    w_px4 = read_traces(tmp_path / "a", "px4", "short-fawt")["wind_speed"]
    w_eso = read_traces(tmp_path / "a", "px4+ffts_eso", "short-fawt")["wind_speed"]
    assert np.allclose(w_px4, w_eso, rtol=0.05)
    # a different seed set in the same folder is refused (paired comparisons need one seed set)
    with pytest.raises(ValueError, match="seeds"):
        _cells(tmp_path / "a", agents, [SHORT], [0, 1, 2])


def test_leaderboard_outputs_and_best(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    agents = ["px4", "px4+ffts_eso", "_plugin_agent:HoverHold"]
    _cells(tmp_path, agents, [SHORT, SHORT_CALM], [0, 1, 2], workers=1)
    board = lb.leaderboard(tmp_path)
    assert board["scenario"] == "short-fawt" and set(board["ranking"]) == set(agents)
    means = {a: board["summaries"]["short-fawt"][a]["metrics"]["pos_err_mean"]["value"] for a in agents}
    assert board["ranking"][0] == min(means, key=means.get) or board["summaries"]["short-fawt"][
        min(means, key=means.get)]["failures"]
    assert lb.main([str(tmp_path), "--best", "--scenario", "short-calm"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-1] == lb.leaderboard(tmp_path, "short-calm")["ranking"][0]
    assert "| rank | agent |" in out[1]
    for name in ("leaderboard.md", "leaderboard.csv", "leaderboard.json"):
        assert (tmp_path / name).stat().st_size > 100
    csv_lines = (tmp_path / "leaderboard.csv").read_text().splitlines()
    assert len(csv_lines) == 1 + 2 * len(agents)
    data = json.loads((tmp_path / "leaderboard.json").read_text())
    assert data["baseline"] == "px4" and data["summaries"]["short-fawt"]["px4+ffts_eso"]["vs_baseline"]


def test_leaderboard_html_is_self_contained(tmp_path: Path) -> None:
    import re

    scen = {**SHORT, "name": "table4-like", "wind": {"name": "fawt-50", "on_time": 0.3, "off_time": 1.2},
            "seconds": 2.0}
    steady = {"name": "steady", "wind": "fawt-50", "seconds": 1.5}
    _cells(tmp_path, ["px4", "px4+ffts_eso"], [scen, steady], [0, 1], workers=1)
    assert lb.main([str(tmp_path), "--html", "--quiet"]) == 0
    page = (tmp_path / "html" / "index.html").read_text()
    assert "http://" not in page and "https://" not in page and "<script" not in page
    images = re.findall(r'<img src="([^"]+)"', page)
    assert {"ranking.png", "traces_table4-like.png", "estimation_table4-like.png", "wind_psd.png"} <= set(images)
    for img in images:
        assert (tmp_path / "html" / img).stat().st_size > 1000
    assert "px4+ffts_eso" in page and "95 %" in page


@pytest.mark.parametrize("argv, match", [
    (["--agents", "px4,foo"], "unknown agent 'foo'"),
    (["--scenarios", "table4-55"], "unknown scenario 'table4-55'"),
    (["--scenarios", "/nonexistent/s.yaml"], "does not exist"),
    (["--seeds", "-2"], "--seeds"),
    (["--wind", "fawt-50"], "--wind and --duration go together"),
    (["--wind", "hurricane", "--duration", "3"], "unknown wind 'hurricane'"),
    (["--out", "/proc/version/x"], "is a file, not a folder"),
    (["--agents", "px4+qb(alpha=1)"], "unknown option"),
])
def test_eval_cli_errors_are_one_line(argv: list[str], match: str, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    if "--out" not in argv:
        argv = [*argv, "--out", str(tmp_path / "r")]
    with pytest.raises(SystemExit) as exc:
        eval_main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and match.replace("\\", "") in err, err
    assert not (tmp_path / "r").exists()  # nothing written before the inputs were checked


def test_leaderboard_cli_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for argv, match in ([str(tmp_path / "nope")], "not a results folder"), ([str(tmp_path)], "not a results folder"):
        with pytest.raises(SystemExit) as exc:
            lb.main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and match in err


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), env.get("PYTHONPATH", "")])
    return env


def test_resume_after_kill_recomputes_nothing_finished(tmp_path: Path) -> None:
    """A run killed after its first cell: the rerun keeps that cell's file as it was and flies only the rest."""
    scen = tmp_path / "s.json"
    scen.write_text(json.dumps({"a": {**SHORT, "name": "a", "seconds": 2.0}, "b": {"wind": "calm", "seconds": 4.0}}))
    out = tmp_path / "r"
    cmd = [sys.executable, "-m", "fawtgym.cli", "eval", "--agents", "px4,px4+ffts_eso", "--scenarios", str(scen),
           "--seeds", "2", "--out", str(out), "--workers", "1", "--no-progress"]
    proc = subprocess.Popen(cmd, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first = cell_paths(out, "px4", "a")[0]
    deadline = time.time() + 240
    while not first.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    assert first.exists(), "the first cell was never written"
    done = sorted(out.glob("cells/*/*.json"))
    assert 1 <= len(done) < 4
    stamps = {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in done}
    res = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert f"{4 - len(done)} cell(s) flown, {len(done)} already finished" in res.stdout
    for p, (mtime, content) in stamps.items():
        assert p.stat().st_mtime_ns == mtime and p.read_bytes() == content
    assert len(list(out.glob("cells/*/*.json"))) == 4
    assert not list(out.glob("cells/*/.*.tmp"))


def test_ray_backend_gives_the_local_numbers(tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    agents = ["px4", "px4+ffts_eso"]
    _cells(tmp_path / "local", agents, [SHORT], [0, 1], workers=1)
    os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             runtime_env={"env_vars": {"PYTHONPATH": _env()["PYTHONPATH"]}})  # the caller's too (a worktree's)
    try:
        summary = _cells(tmp_path / "ray", agents, [SHORT], [0, 1], backend="ray")
    finally:
        ray.shutdown()
    assert not summary["errors"] and len(summary["done"]) == 2
    assert _numbers(tmp_path / "local") == _numbers(tmp_path / "ray")


def test_eval_baseline_may_be_an_agent_of_the_run_flown_earlier(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                                ) -> None:
    """--baseline names any agent of the results folder (this command's or an earlier one's), in any spelling the
    grammar reads; a name that is none of them is refused (it was accepted and printed 'vs baseline n/a')."""
    from fawtgym.cli import main

    common = ["--wind", "calm", "--duration", "0.05", "--seeds", "1", "--out", str(tmp_path / "r"), "--no-progress"]
    assert main(["eval", "--agents", "px4+geso(order=3)", *common]) == 0
    assert main(["eval", "--agents", "px4", "--baseline", "px4+geso( order = 3 )", *common]) == 0
    with pytest.raises(SystemExit) as exc:
        main(["eval", "--agents", "px4", "--baseline", "px4+leso", *common])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--baseline 'px4+leso' is not an agent of this run; agents: px4+geso(order=3), px4" in err
