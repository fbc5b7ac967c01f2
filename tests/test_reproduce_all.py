"""``fawtgym reproduce all``: one report over every study (eval/reproduce/report.py).

The fast tests run one short study through the whole pipeline, a failing study, and the argument errors;
the complete ``--quick`` run (every study, about 2-3 minutes on two cores) is marked long.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from _html_check import check_page

from fawtgym.eval.reproduce import claims as C
from fawtgym.eval.reproduce import report


def _check_outputs(out: Path) -> dict:
    md = (out / "report.md").read_text()
    assert md.startswith("# Paper reproductions")
    assert "http://" not in md and "https://" not in md
    check_page(out / "index.html")
    data = json.loads((out / "claims.json").read_text())
    for study in data["studies"]:
        for c in study["claims"]:
            assert c["verdict"] in C.VERDICTS and c["reason"] and c["criterion"] and c["where"]
            assert _md(c["statement"]) in md
    return data


def _md(text: str) -> str:
    """``text`` as it appears in a Markdown table cell."""
    return text.replace("|", "\\|")


def test_every_cli_study_is_in_the_report_table() -> None:
    from fawtgym.cli import REPRODUCTIONS

    assert {s.name for s in report.STUDIES} == set(REPRODUCTIONS) - {"all"}
    for s in report.STUDIES:
        assert REPRODUCTIONS[s.name][0] == f"fawtgym.eval.reproduce.{s.module}:main"
        assert s.paper in C.TITLES


def test_one_study_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "rep"
    assert report.main(["--quick", "--only", "hc-eso", "--out", str(out)]) == 0
    data = _check_outputs(out)
    assert [s["name"] for s in data["studies"]] == ["hc-eso"] and data["quick"]
    claims = data["studies"][0]["claims"]
    assert len(claims) == 4 and all(c["paper"] == C.WANG2022 for c in claims)
    html = (out / "index.html").read_text()
    for fig in ("hc-eso/hc_eso_fig1.png", "hc-eso/hc_eso_fig3.png"):
        assert f'src="{fig}"' in html and (out / fig).is_file()
    assert 'href="hc-eso/hc_eso_summary.md"' in html
    assert (out / "hc-eso" / "log.txt").is_file()
    printed = capsys.readouterr().out
    assert "4 claims" in printed and "report:" in printed


def test_a_failing_study_is_reported_and_the_others_still_run(tmp_path: Path, monkeypatch) -> None:
    broken = report.Study("hc-eso-broken", "hc_eso", C.WANG2022, "broken on purpose",
                          quick_args=("--t-end", "0.05"))  # too short: run() raises ValueError
    fine = report.Study("hc-eso", "hc_eso", C.WANG2022, "short", quick_args=("--t-end", "2", "--no-figures"))
    monkeypatch.setattr(report, "STUDIES", (broken, fine))
    out = tmp_path / "rep"
    assert report.main(["--quick", "--out", str(out)]) == 1
    data = _check_outputs(out)
    err = {s["name"]: s["error"] for s in data["studies"]}
    assert err["hc-eso-broken"].startswith("ValueError: need t_end > 0") and err["hc-eso"] is None
    assert len(data["studies"][1]["claims"]) == 4
    md = (out / "report.md").read_text()
    assert "## Studies that failed" in md and "This study failed" in md and "ValueError" in md
    assert "Traceback" in (out / "hc-eso-broken" / "log.txt").read_text()


@pytest.mark.parametrize("argv, message", [
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["--only", "table5"], "--only table5 unknown"),
    (["--quick", "extra"], "unrecognized arguments: extra"),
])
def test_bad_arguments_give_one_line_and_status_2(argv, message, capsys, tmp_path: Path) -> None:
    try:
        rc = report.main([*argv, "--out", str(tmp_path / "x")])
    except SystemExit as exc:
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and message in err and "Traceback" not in err
    assert not (tmp_path / "x" / "report.md").exists()


def test_unwritable_out_gives_one_line_and_status_2(tmp_path: Path, capsys) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    for out in (blocker, blocker / "sub"):
        assert report.main(["--quick", "--only", "hc-eso", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and str(blocker) in err and "Traceback" not in err


@pytest.mark.long
def test_reproduce_all_quick(tmp_path: Path) -> None:
    """Every study in its short form, one report (about 2-3 minutes on two cores)."""
    out = tmp_path / "all"
    assert report.main(["--quick", "--out", str(out)]) == 0
    data = _check_outputs(out)
    names = [s["name"] for s in data["studies"]]
    assert names == [s.name for s in report.STUDIES]
    assert all(s["error"] is None and s["claims"] for s in data["studies"]), [(s["name"], s["error"])
                                                                              for s in data["studies"]]
    papers = {c["paper"] for s in data["studies"] for c in s["claims"]}
    assert papers == set(C.TITLES)
    md = (out / "report.md").read_text()
    assert "## Claims our runs contradict" in md
    not_claims = [c for s in data["studies"] for c in s["claims"] if c["verdict"] == C.NOT]
    section = md.split("## Claims our runs contradict")[1].split("\n## ")[0]
    assert all(_md(c["statement"]) in section for c in not_claims)  # listed, never left out
    # every figure a study reported is on the page and next to it
    html = (out / "index.html").read_text()
    assert html.count("<img ") >= 15
