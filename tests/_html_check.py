"""Shared test helper: check that a written HTML page is well-formed, offline and self-contained.

Used by tests/test_html_page.py and tests/test_reproduce_all.py (not a test module itself).
"""

from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

_VOID = {"meta", "img", "br", "hr", "link", "input", "source", "col", "wbr"}


class _Checker(HTMLParser):
    """Tag balance, image sources, link targets and any absolute URL in attributes."""

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.srcs: list[str] = []
        self.hrefs: list[str] = []
        self.tags: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.add(tag)
        for k, v in attrs:
            if k == "src":
                self.srcs.append(v or "")
            if k == "href":
                self.hrefs.append(v or "")
        if tag not in _VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if tag in _VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
            return
        self.stack.pop()


def check_page(path: Path) -> _Checker:
    """Parse a written page; assert it is balanced, offline and its images exist beside it."""
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    chk = _Checker()
    chk.feed(text)
    chk.close()
    assert not chk.errors and not chk.stack, (chk.errors, chk.stack)
    assert not re.search(r"(https?:)?//[a-z0-9]", text.replace("<!DOCTYPE html>", ""), re.I), "absolute URL in page"
    assert "<script" not in text.lower()
    for src in chk.srcs:
        assert not src.startswith(("/", "http:", "https:", "file:", "data:")), src
        assert (path.parent / src).is_file(), f"missing image {src}"
    for href in chk.hrefs:
        if not href.startswith("#"):
            assert not re.match(r"^[a-z][a-z0-9+.-]*:", href, re.I), href
            assert (path.parent / href).exists(), f"dangling link {href}"
    return chk
