"""eval/html_page.py: a self-contained page (well-formed, escaped, relative links only, no network)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from _html_check import check_page

from fawtgym.eval.html_page import HtmlPage, check_relative, inline


def _png(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 16)


def test_page_is_well_formed_offline_and_links_are_relative(tmp_path: Path) -> None:
    _png(tmp_path / "study" / "fig1.png")
    (tmp_path / "study" / "summary.md").write_text("# x\n")
    page = HtmlPage("Reproductions <all>", "`fawtgym reproduce all --quick` & more", footer="made by **us**")
    page.paragraph("Intro with `code <b>` and **bold** and a [summary](study/summary.md) link.")
    page.stats([("reproduced", 3, "good"), ("not", 1, "bad")])
    page.heading("Summary", 2)
    page.table(["claim", "paper", "ours", "verdict"],
               [["Table 4, 50 %", "0.0589", "0.0612", "reproduced"], ["a | b < c", "-", "2.1x", "not"]],
               caption="Claims", cell_classes=[[None, None, None, "good"], [None, None, None, "bad"]])
    page.heading("Figures", 2)
    page.figure("study/fig1.png", "Fig. 1 & friends")
    page.note("careful", "error")
    page.bullets(["one", "`two`"])
    page.details("more", ["x", "y"])
    path = page.write(tmp_path / "index.html")
    chk = check_page(path)
    text = path.read_text()
    assert {"table", "figure", "img", "nav", "style"} <= chk.tags
    assert "&lt;all&gt;" in text and "<code>code &lt;b&gt;</code>" in text and "<strong>bold</strong>" in text
    assert 'class="good' in text and 'class="bad' in text
    assert '<td class="num">0.0589</td>' in text  # numbers right-aligned
    assert 'href="#summary"' in text  # table of contents
    assert page.figures == ["study/fig1.png"]
    assert not (tmp_path / "index.html.tmp").exists()


def test_text_is_escaped_and_absolute_links_are_refused(tmp_path: Path) -> None:
    assert inline("<script>alert(1)</script>") == "&lt;script&gt;alert(1)&lt;/script&gt;"
    assert inline('x "y"') == "x &quot;y&quot;"
    for bad in ("https://example.org/a.png", "http://x", "//cdn.x/y.png", "/etc/passwd", "file:///tmp/x",
                "data:image/png;base64,AAA", ""):
        with pytest.raises(ValueError, match="relative"):
            check_relative(bad)
    with pytest.raises(ValueError, match="relative"):
        inline("see [there](https://example.org)")
    page = HtmlPage("t")
    with pytest.raises(ValueError, match="relative"):
        page.figure(tmp_path / "abs.png", "absolute")
    with pytest.raises(ValueError, match="level"):
        page.heading("x", 1)
    with pytest.raises(ValueError, match="cells"):
        page.table(["a", "b"], [["1"]])
    with pytest.raises(ValueError, match="cell_classes"):
        page.table(["a"], [["1"]], cell_classes=[[None], [None]])


def test_missing_figure_is_shown_not_linked(tmp_path: Path) -> None:
    page = HtmlPage("t")
    page.figure("nope.png", "lost")
    text = page.write(tmp_path / "index.html").read_text()
    assert "figure file missing" in text and "<img" not in text
    check_page(tmp_path / "index.html")


def test_module_imports_only_the_standard_library() -> None:
    import ast

    import fawtgym.eval.html_page as hp

    tree = ast.parse(Path(hp.__file__).read_text())
    roots = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    roots |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert roots <= set(sys.stdlib_module_names) | {"__future__"}, roots
    code = ("import sys, fawtgym.eval\nbefore = set(sys.modules)\nimport fawtgym.eval.html_page\n"
            "print(','.join(sorted(m for m in set(sys.modules) - before if not m.startswith('fawtgym'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert not {"matplotlib", "numpy", "scipy"} & set(out.split(",")), out
