"""A small self-contained HTML page writer for reports (paper reproductions, the leaderboard).

The page is one ``index.html`` with inline CSS, no JavaScript, no web fonts and no network access:
it opens from the file system.  Figures are image files referenced by paths *relative to the page*
(usually in the same folder or a subfolder), so the folder can be zipped or copied as a whole.

Text is always HTML-escaped.  Paragraphs, list items and table cells accept a tiny inline markup:
```code``` spans, ``**bold**`` and relative links ``[text](path/inside/the/folder)``; links with a
scheme (``http:``, ``https:``, ``file:``, ...) or an absolute path are refused, so the page never
points off the folder.

Usage::

    page = HtmlPage("Paper reproductions", "fawtgym reproduce all --quick")
    page.heading("Summary", 2)
    page.paragraph("Every claim with a verdict computed by `fawtgym.eval.reproduce`.")
    page.table(["claim", "verdict"], [["Table 4, 50 %", "reproduced"]], cell_classes=[[None, "good"]])
    page.figure("table4/fig10_position_error.png", "Position error, cf. Fig. 10")
    page.write(folder / "index.html")

Cell/status classes understood by the stylesheet: ``good``, ``partial``, ``bad``, ``muted``, ``error``
(coloured backgrounds for verdicts and ranks), ``dim`` (grey text), ``num`` (right-aligned numbers;
added automatically to cells that look numeric).  This module imports only the standard library.
"""

from __future__ import annotations

import html
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

#: classes the stylesheet colours (anything else is passed through as a class name)
STATUS_CLASSES: tuple[str, ...] = ("good", "partial", "bad", "muted", "error", "dim", "num")

_CSS = """
:root { --fg: #1f2328; --muted: #59636e; --bg: #ffffff; --panel: #f6f8fa; --line: #d1d9e0;
  --accent: #0b5cad; --good-bg: #dcf5e3; --good-fg: #115c2b; --partial-bg: #fff1c7; --partial-fg: #7a4b00;
  --bad-bg: #ffe0dc; --bad-fg: #9b1c12; --muted-bg: #eef0f2; --muted-fg: #59636e; --error-bg: #6e1010;
  --error-fg: #ffffff; }
@media (prefers-color-scheme: dark) {
  :root { --fg: #e6edf3; --muted: #9198a1; --bg: #0d1117; --panel: #161b22; --line: #30363d; --accent: #58a6ff;
    --good-bg: #11361f; --good-fg: #7ee2a0; --partial-bg: #3d2e00; --partial-fg: #f2cc60; --bad-bg: #4a1410;
    --bad-fg: #ffa198; --muted-bg: #21262d; --muted-fg: #9198a1; --error-bg: #8e1519; --error-fg: #ffffff; }
  img { background: #ffffff; }
}
* { box-sizing: border-box; }
html { -webkit-text-size-adjust: 100%; }
body { margin: 0; color: var(--fg); background: var(--bg); line-height: 1.5;
  font: 15px/1.55 -apple-system, BlinkMacSystemFont, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
header.page { background: var(--panel); border-bottom: 1px solid var(--line); }
header.page .wrap { padding: 28px 24px 20px; }
header.page h1 { margin: 0 0 4px; font-size: 1.75rem; line-height: 1.25; }
header.page p.subtitle { margin: 0; color: var(--muted); }
main.wrap, header.page .wrap, footer.page .wrap { max-width: 1180px; margin: 0 auto; }
main.wrap { padding: 8px 24px 40px; }
h2 { font-size: 1.35rem; margin: 2.2em 0 0.5em; padding-bottom: 0.25em; border-bottom: 1px solid var(--line); }
h3 { font-size: 1.12rem; margin: 1.8em 0 0.4em; }
h4 { font-size: 1rem; margin: 1.4em 0 0.3em; }
h2 a.anchor, h3 a.anchor, h4 a.anchor { color: var(--line); text-decoration: none; margin-left: 0.35em;
  font-weight: normal; }
h2:hover a.anchor, h3:hover a.anchor, h4:hover a.anchor { color: var(--muted); }
p, ul, ol { margin: 0.5em 0 0.9em; max-width: 80ch; }
a { color: var(--accent); }
code { font: 0.9em/1.4 ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; background: var(--panel);
  border: 1px solid var(--line); border-radius: 4px; padding: 0 0.3em; }
nav.toc { background: var(--panel); border: 1px solid var(--line); border-radius: 8px; padding: 10px 16px;
  margin: 18px 0; }
nav.toc ol { margin: 0.2em 0; padding-left: 1.4em; }
nav.toc strong { font-size: 0.9rem; color: var(--muted); }
.table-wrap { overflow-x: auto; margin: 0.6em 0 1.4em; border: 1px solid var(--line); border-radius: 8px; }
table { border-collapse: collapse; width: 100%; font-size: 0.9rem; }
caption { caption-side: top; text-align: left; padding: 8px 12px; color: var(--muted); font-size: 0.88rem;
  border-bottom: 1px solid var(--line); background: var(--panel); }
th, td { padding: 6px 10px; border-bottom: 1px solid var(--line); vertical-align: top; text-align: left; }
th { background: var(--panel); font-weight: 600; white-space: nowrap; position: sticky; top: 0; }
tbody tr:nth-child(even) td:not(.good):not(.partial):not(.bad):not(.muted):not(.error) {
  background: color-mix(in srgb, var(--panel) 55%, transparent); }
tbody tr:last-child td { border-bottom: none; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.good { background: var(--good-bg); color: var(--good-fg); font-weight: 600; }
td.partial { background: var(--partial-bg); color: var(--partial-fg); font-weight: 600; }
td.bad { background: var(--bad-bg); color: var(--bad-fg); font-weight: 600; }
td.muted { background: var(--muted-bg); color: var(--muted-fg); }
td.error { background: var(--error-bg); color: var(--error-fg); font-weight: 600; }
td.dim { color: var(--muted); }
p.title { font-style: italic; color: var(--muted); margin-top: -0.3em; }
.stats { display: flex; flex-wrap: wrap; gap: 10px; margin: 12px 0 18px; }
.stat { border: 1px solid var(--line); border-radius: 8px; padding: 8px 14px; min-width: 120px;
  background: var(--panel); }
.stat .value { font-size: 1.5rem; font-weight: 700; line-height: 1.2; }
.stat .label { font-size: 0.82rem; color: var(--muted); }
.stat.good { background: var(--good-bg); color: var(--good-fg); border-color: transparent; }
.stat.partial { background: var(--partial-bg); color: var(--partial-fg); border-color: transparent; }
.stat.bad { background: var(--bad-bg); color: var(--bad-fg); border-color: transparent; }
.stat.muted { background: var(--muted-bg); color: var(--muted-fg); border-color: transparent; }
.stat.error { background: var(--error-bg); color: var(--error-fg); border-color: transparent; }
.stat.good .label, .stat.partial .label, .stat.bad .label, .stat.muted .label, .stat.error .label { color: inherit; }
.note { border-left: 4px solid var(--line); background: var(--panel); padding: 8px 14px; margin: 0.8em 0;
  max-width: 80ch; border-radius: 0 6px 6px 0; }
.note.error { border-left-color: var(--error-bg); }
.note.bad { border-left-color: var(--bad-fg); }
.note.partial { border-left-color: var(--partial-fg); }
.note.good { border-left-color: var(--good-fg); }
.figures { display: grid; grid-template-columns: repeat(auto-fill, minmax(440px, 1fr)); gap: 16px;
  margin: 0.8em 0 1.6em; }
figure { margin: 0; border: 1px solid var(--line); border-radius: 8px; padding: 10px; background: var(--bg); }
figure img { display: block; max-width: 100%; height: auto; margin: 0 auto; }
figure figcaption { font-size: 0.85rem; color: var(--muted); margin-top: 6px; }
figure.missing { color: var(--bad-fg); background: var(--bad-bg); }
details { margin: 0.6em 0 1em; }
details > summary { cursor: pointer; color: var(--accent); }
footer.page { border-top: 1px solid var(--line); color: var(--muted); font-size: 0.82rem; }
footer.page .wrap { padding: 14px 24px 28px; }
@media print { th { position: static; } .figures { display: block; }
  figure { break-inside: avoid; margin-bottom: 12px; } }
"""

_CODE = re.compile(r"`([^`]+)`")
_BOLD = re.compile(r"\*\*(.+?)\*\*")
_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
_NUMBER = re.compile(r"^[-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?\s*(%|x)?$")


def check_relative(target: str) -> str:
    """``target`` if it is a relative path inside the page's folder tree, else ValueError.

    Refused: a URL scheme (``http:``, ``https:``, ``file:``, ``data:`` ...), protocol-relative ``//``,
    absolute paths and drive letters (the page must open from any copy of its folder, offline).
    """
    t = str(target)
    if not t or _SCHEME.match(t) or t.startswith(("/", "\\")) or os.path.isabs(t):
        raise ValueError(f"only relative paths inside the page's folder are allowed, got {target!r}")
    return t


def inline(text: object) -> str:
    """Escape ``text`` for HTML and apply the inline markup (```code```, ``**bold**``, relative links)."""
    out = []
    for i, part in enumerate(_CODE.split(str(text))):
        if i % 2:
            out.append(f"<code>{html.escape(part)}</code>")
            continue
        esc = html.escape(part)
        esc = _BOLD.sub(r"<strong>\1</strong>", esc)

        def link(m: re.Match[str]) -> str:
            href = check_relative(html.unescape(m.group(2)))
            return f'<a href="{html.escape(href, quote=True)}">{m.group(1)}</a>'

        out.append(_LINK.sub(link, esc))
    return "".join(out)


def _slug(text: str, used: set[str]) -> str:
    base = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"
    slug, k = base, 2
    while slug in used:
        slug, k = f"{base}-{k}", k + 1
    used.add(slug)
    return slug


class HtmlPage:
    """A single static HTML page built block by block, then written with :meth:`write`.

    ``title`` is the page's ``<title>`` and main heading; ``subtitle`` a line under it.  With
    ``toc=True`` a table of contents of the level-2 headings is placed after the first block that
    precedes the first level-2 heading (or at the top).
    """

    def __init__(self, title: str, subtitle: str = "", *, toc: bool = True, footer: str = "") -> None:
        self.title = str(title)
        self.subtitle = str(subtitle)
        self.footer = str(footer)
        self.toc = toc
        self._blocks: list[str] = []
        self._headings: list[tuple[int, str, str]] = []  # (level, text, id)
        self._ids: set[str] = set()
        self._figures: list[str] = []
        self._toc_at: int | None = None
        self._grid: list[str] | None = None

    # ---- blocks ---------------------------------------------------------------------------------
    def heading(self, text: str, level: int = 2, anchor: str | None = None) -> str:
        """Add a heading (level 2-4; level 1 is the page title); returns its anchor id."""
        if level not in (2, 3, 4):
            raise ValueError(f"heading level must be 2, 3 or 4 (1 is the page title), got {level!r}")
        self._close_grid()
        hid = _slug(anchor or str(text), self._ids)
        if level == 2 and self._toc_at is None:
            self._toc_at = len(self._blocks)
        self._headings.append((level, str(text), hid))
        self._blocks.append(f'<h{level} id="{hid}">{inline(text)}<a class="anchor" href="#{hid}">#</a></h{level}>')
        return hid

    def paragraph(self, text: str, css_class: str | None = None) -> None:
        """Add a paragraph of escaped text with inline markup."""
        self._close_grid()
        cls = f' class="{html.escape(css_class, quote=True)}"' if css_class else ""
        self._blocks.append(f"<p{cls}>{inline(text)}</p>")

    def note(self, text: str, css_class: str = "") -> None:
        """Add a highlighted side note (``css_class``: ``good``, ``partial``, ``bad``, ``error`` or empty)."""
        self._close_grid()
        cls = ("note " + css_class).strip()
        self._blocks.append(f'<div class="{html.escape(cls, quote=True)}">{inline(text)}</div>')

    def bullets(self, items: Iterable[str]) -> None:
        """Add an unordered list (each item escaped, inline markup allowed)."""
        self._close_grid()
        self._blocks.append("<ul>" + "".join(f"<li>{inline(i)}</li>" for i in items) + "</ul>")

    def stats(self, items: Sequence[tuple[str, object, str | None]]) -> None:
        """Add a row of big numbers: ``(label, value, css_class)`` each (class as for table cells)."""
        self._close_grid()
        cells = []
        for label, value, cls in items:
            c = f"stat {cls}" if cls else "stat"
            cells.append(f'<div class="{html.escape(c, quote=True)}"><div class="value">{inline(value)}</div>'
                         f'<div class="label">{inline(label)}</div></div>')
        self._blocks.append('<div class="stats">' + "".join(cells) + "</div>")

    def table(self, header: Sequence[object], rows: Sequence[Sequence[object]], caption: str | None = None,
              cell_classes: Sequence[Sequence[str | None]] | None = None, numeric_auto: bool = True) -> None:
        """Add a table.

        ``header``: column titles; ``rows``: cells (any object, shown as ``str``; escaped, inline markup
        allowed); ``cell_classes``: same shape as ``rows``, a CSS class (``good``, ``partial``, ``bad``,
        ``muted``, ``error``, ``num``, or several space-separated) or None per cell.  With ``numeric_auto``
        cells that read as a number (``0.25``, ``-3e-4``, ``57 %``, ``2.1x``) are right-aligned.
        """
        self._close_grid()
        ncol = len(header)
        if cell_classes is not None and len(cell_classes) != len(rows):
            raise ValueError(f"cell_classes has {len(cell_classes)} rows, the table {len(rows)}")
        parts = ['<div class="table-wrap"><table>']
        if caption:
            parts.append(f"<caption>{inline(caption)}</caption>")
        parts.append("<thead><tr>" + "".join(f'<th scope="col">{inline(h)}</th>' for h in header) + "</tr></thead>")
        parts.append("<tbody>")
        for r, row in enumerate(rows):
            if len(row) != ncol:
                raise ValueError(f"row {r} has {len(row)} cells, the header {ncol}")
            classes = cell_classes[r] if cell_classes is not None else [None] * ncol
            if len(classes) != ncol:
                raise ValueError(f"cell_classes row {r} has {len(classes)} entries, the header {ncol}")
            tds = []
            for cell, cls in zip(row, classes, strict=True):
                names = (cls or "").split()
                if numeric_auto and _NUMBER.match(str(cell).strip()) and "num" not in names:
                    names.append("num")
                attr = f' class="{html.escape(" ".join(names), quote=True)}"' if names else ""
                tds.append(f"<td{attr}>{inline(cell)}</td>")
            parts.append("<tr>" + "".join(tds) + "</tr>")
        parts.append("</tbody></table></div>")
        self._blocks.append("".join(parts))

    def figure(self, src: str | Path, caption: str = "", alt: str | None = None) -> None:
        """Add an image by its path relative to the page (consecutive figures share a responsive grid)."""
        rel = check_relative(Path(src).as_posix())
        self._figures.append(rel)
        if self._grid is None:
            self._grid = []
        alt_text = html.escape(alt if alt is not None else (caption or Path(rel).name), quote=True)
        cap = f"<figcaption>{inline(caption)}</figcaption>" if caption else ""
        self._grid.append(f'<figure data-src="{html.escape(rel, quote=True)}">'
                          f'<img src="{html.escape(rel, quote=True)}" alt="{alt_text}" loading="lazy">{cap}</figure>')

    def details(self, summary: str, lines: Iterable[str]) -> None:
        """Add a collapsed block (``<details>``, no script) holding a list of text lines."""
        self._close_grid()
        body = "".join(f"<li>{inline(x)}</li>" for x in lines)
        self._blocks.append(f"<details><summary>{inline(summary)}</summary><ul>{body}</ul></details>")

    # ---- output ---------------------------------------------------------------------------------
    @property
    def figures(self) -> list[str]:
        """The relative image paths added so far."""
        return list(self._figures)

    def _close_grid(self) -> None:
        if self._grid:
            self._blocks.append('<div class="figures">' + "".join(self._grid) + "</div>")
        self._grid = None

    def _toc_html(self) -> str:
        items = [(t, i) for lvl, t, i in self._headings if lvl == 2]
        if len(items) < 2:
            return ""
        return ('<nav class="toc"><strong>Contents</strong><ol>'
                + "".join(f'<li><a href="#{i}">{inline(t)}</a></li>' for t, i in items) + "</ol></nav>")

    def render(self, folder: Path | None = None) -> str:
        """The page as a string; with ``folder``, figures whose file is missing there are shown as such."""
        self._close_grid()
        blocks = list(self._blocks)
        if folder is not None:
            for k, b in enumerate(blocks):
                if b.startswith('<div class="figures">'):
                    blocks[k] = _mark_missing(b, Path(folder))
        if self.toc:
            toc = self._toc_html()
            if toc:
                blocks.insert(self._toc_at if self._toc_at is not None else 0, toc)
        sub = f'<p class="subtitle">{inline(self.subtitle)}</p>' if self.subtitle else ""
        foot = (f'<footer class="page"><div class="wrap">{inline(self.footer)}</div></footer>'
                if self.footer else "")
        body = "\n".join(blocks)
        return ("<!DOCTYPE html>\n"
                '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
                '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
                f"<title>{html.escape(self.title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
                f'<header class="page"><div class="wrap"><h1>{inline(self.title)}</h1>{sub}</div></header>\n'
                f'<main class="wrap">\n{body}\n</main>\n{foot}\n</body>\n</html>\n')

    def write(self, path: str | Path) -> Path:
        """Write the page to ``path`` (its folder is created); returns the path.

        Figures are referenced relative to ``path``'s folder; one whose file does not exist there is
        rendered as a visible "missing figure" box (the page is still written).
        """
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        text = self.render(path.parent)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
        return path


_FIG = re.compile(r'<figure data-src="([^"]*)">(.*?)</figure>', re.S)


def _mark_missing(block: str, folder: Path) -> str:
    def sub(m: re.Match[str]) -> str:
        rel = html.unescape(m.group(1))
        if (folder / rel).is_file():
            return m.group(0)
        return (f'<figure class="missing" data-src="{m.group(1)}"><p>figure file missing: '
                f"<code>{html.escape(rel)}</code></p></figure>")

    return _FIG.sub(sub, block)
