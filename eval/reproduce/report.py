"""``fawtgym reproduce all [--quick] [--out DIR] [--only NAMES]``: every paper reproduction, one report.

Runs each study of ``fawtgym reproduce`` in this process, one after the other, each writing its own files
into a subfolder of ``--out`` (``--out/table4/...``), and writes one report beside them:

* ``report.md`` and ``index.html`` (the same content; the page opens from the file system, no server or
  network, figures are the studies' own image files referenced relative to the page);
* ``claims.json``: every claim as a record (:class:`fawtgym.eval.reproduce.claims.Claim`).

For each paper, each claim a study can check, the paper's value beside ours, and a verdict computed by
the study's code with a stated tolerance: ``reproduced`` / ``partly`` / ``not``, or ``not checked`` when
this run did not produce the data (``--quick`` flies fewer cases).  Claims our runs contradict are listed
in their own section as well as in their paper's table.  A study that raises is reported as an error
with its message (traceback in its ``log.txt``), the others still run, and the exit status is 1.
Bad arguments (unknown option, unwritable ``--out``) print one line and exit with status 2.

``--quick`` runs every study in its short form (about 2 to 3 minutes on two cores); the full run takes
the studies' default lengths (tens of minutes: Table 4 alone flies 5 duties x 5 seeds x 2 controllers).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import importlib
import io
import json
import os
import sys
import time
import traceback
from collections.abc import Sequence
from pathlib import Path

from fawtgym.cli_parser import ArgumentParser
from fawtgym.eval.html_page import HtmlPage
from fawtgym.eval.reproduce import claims as C
from fawtgym.eval.reproduce.progress import FLAG, add_flag

PROG = "fawtgym reproduce all"


@dataclasses.dataclass(frozen=True)
class Study:
    """One reproduction study: its ``fawtgym reproduce`` name, module, paper and arguments per mode."""

    name: str
    module: str
    paper: str
    title: str
    quick_args: tuple[str, ...] = ("--quick",)
    full_args: tuple[str, ...] = ()


#: every study, in report order.  ``quick_args`` are what ``reproduce all --quick`` passes: the study's own
#: ``--quick`` and, where that alone would leave the paper's claims unchecked, the few cases that check them
#: (Table 4: the 70 % failure; pdt-sta: the paper's 1e-4 s step, at which its Sec. 5 claims are meaningful).
STUDIES: tuple[Study, ...] = (
    Study("seed000-sim", "seed000_sim", C.WANG2024,
          "Sec. 6 simulation: FFTS-ESO vs LESO and FxTSDO on four trajectories (Figs. 3-6)"),
    Study("table4", "table4", C.WANG2024,
          "Sec. 7 flight experiment rebuilt in simulation: PX4 vs PX4 + FFTS-ESO in FAWT wind (Table 4, Figs. 10-11)",
          quick_args=("--quick", "--duties", "50,70", "--seeds", "1")),
    Study("geso", "geso", C.SHI2018,
          "GESO orders 1-3 with quaternion backstepping (Sec. IV-C, Table 2, Fig. 3; Sec. VI-A, Figs. 5-12)"),
    Study("hc-eso", "hc_eso", C.WANG2022, "HC-ESO on SO(3) from vector measurements (Sec. 6, Figs. 1-3)"),
    Study("qb", "qb_observer", C.CAYERO2019, "QB observer designed by SDP (Sec. 4, Figs. 4-7)"),
    Study("pdt-sta", "pdt_sta", C.SILVA2023,
          "Predefined-time STA: Example 1 (Fig. 3) and the gyroless attitude observer (Sec. 5, Figs. 5-9)",
          quick_args=("--quick", "--ts", "1e-4", "--t-final", "2.5")),
)

#: what of each paper no study checks (so the report says so instead of staying silent)
NOT_COVERED: dict[str, tuple[str, ...]] = {
    C.WANG2024: ("Table 3 (FAWT turbulence statistics) is an input, not a result: the wind presets' mean and sigma "
                 "are set from it, so `fawtgym wind` prints it as calibration; what is not an input (spectrum "
                 "shape, autocorrelation and its dt independence, jet profile) is validated in "
                 "tests/test_wind_validation.py.",
                 "The finite-time stability theorems (Secs. 3-5) are proofs; only their simulated consequences are "
                 "checked."),
    C.SHI2018: ("The flight experiment (Sec. VI-B: Table 3, Figs. 13-16, the 57 %/62 % and 50 %/60 % RMS "
                "reductions on a GF360 with w_b = 4 rad/s) is not simulated.",),
    C.WANG2022: ("Theorem 1 (almost-global finite-time stability with a constant disturbance and exact "
                 "measurements) is not run as a separate case; the settling time is not measured.",),
    C.CAYERO2019: ("The paper prints no numbers for Figs. 4-7, so only their orderings are compared; the "
                   "Fig. 3 amplitudes and the hover controller are ours.",),
    C.SILVA2023: ("Fig. 1 (smoothness of the time-varying gain) and the values Algorithm 1 returns are not claims "
                  "with numbers; Algorithm 1 is run and its result printed in the study's summary.",),
}

#: figure file name -> caption
CAPTIONS: dict[str, str] = {
    "seed000_fig3_force_clean.png": "Force estimation error, noise-free (cf. Fig. 3)",
    "seed000_fig4_torque_clean.png": "Torque estimation error, noise-free (cf. Fig. 4)",
    "seed000_fig5_force_noisy.png": "Force estimation error, with noise (cf. Fig. 5)",
    "seed000_fig6_torque_noisy.png": "Torque estimation error, with noise (cf. Fig. 6)",
    "fig10_position_error.png": "Position error vs time per duty, PX4 (blue) and PX4 + FFTS-ESO (red), cf. Fig. 10",
    "fig11_attitude_error.png": "Attitude error vs time per duty, cf. Fig. 11",
    "geso_case1_attitude.png": "Case 1 attitude (cf. Figs. 5-7)",
    "geso_case1_estimation.png": "Case 1 disturbance estimation error (cf. Fig. 8)",
    "geso_case2_attitude.png": "Case 2 attitude (cf. Figs. 9-11)",
    "geso_case2_estimation.png": "Case 2 disturbance estimation error (cf. Fig. 12)",
    "geso_bode.png": "|G(jw)| of eq. 37 (cf. Fig. 3)",
    "hc_eso_fig1.png": "Attitude estimation error (cf. Fig. 1)",
    "hc_eso_fig2.png": "Angular velocity estimation error (cf. Fig. 2)",
    "hc_eso_fig3.png": "Disturbance estimation error (cf. Fig. 3)",
    "qb_fig4.png": "Optimal volume vs alpha (cf. Fig. 4)",
    "qb_fig5.png": "J_mu vs alpha (cf. Fig. 5)",
    "qb_fig6.png": "Optimal alpha and volume vs mu (cf. Fig. 6)",
    "qb_fig7.png": "Disturbance estimation for mu = 0.2 and 0.95 (cf. Fig. 7)",
    "fig3_ptc.png": "x2(t) and the PTC area for Example 1's three settings (cf. Fig. 3)",
    "fig5.png": "Estimation errors, t_c = 1.5 s (cf. Fig. 5)",
    "fig6.png": "Estimation errors, t_c = 0.5 s (cf. Fig. 6)",
    "fig7.png": "Conventional STSMO (cf. Fig. 7)",
    "fig8.png": "With noise, switching at t_c (cf. Fig. 8)",
    "fig9.png": "With noise, early switching at t_e (cf. Fig. 9)",
}

#: verdict -> CSS class of html_page
VERDICT_CLASS: dict[str, str] = {C.REPRODUCED: "good", C.PARTLY: "partial", C.NOT: "bad", C.UNCHECKED: "muted"}


@dataclasses.dataclass
class StudyRun:
    """The result of running one study: its outcome, or the error that stopped it."""

    study: Study
    argv: list[str]
    folder: Path
    seconds: float
    outcome: C.StudyOutcome | None = None
    error: str | None = None

    @property
    def claims(self) -> list[C.Claim]:
        return self.outcome.claims if self.outcome is not None else []


_Parser = ArgumentParser  # one-line errors, exit status 2, plain-text help (fawtgym.cli_parser)


def _parser() -> ArgumentParser:
    names = ", ".join(s.name for s in STUDIES)
    p = _Parser(prog=PROG, description=__doc__.split("\n\n")[0],
                epilog=f"studies: {names}")
    p.add_argument("--quick", action="store_true", help="the short form of every study (about 2-3 minutes)")
    p.add_argument("--out", type=Path, default=Path("results/reproduce"),
                   help="output folder: report.md, index.html, claims.json and one subfolder per study")
    p.add_argument("--only", type=str, default=None, metavar="NAMES",
                   help=f"comma list of studies to run (default all: {names})")
    add_flag(p)  # the bar over the studies; each study runs with --no-progress (its stderr goes to its log.txt)
    return p


def _check_writable(out: Path) -> str | None:
    """None if ``out`` can be created and written, else the reason."""
    try:
        if out.exists() and not out.is_dir():
            return f"--out {str(out)!r} exists and is not a folder"
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".write-test-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        return f"cannot write to --out {str(out)!r}: {exc.strerror or exc}"
    return None


def run_study(study: Study, out: Path, quick: bool) -> StudyRun:
    """Run one study into ``out / study.name``; its stdout and stderr go to ``log.txt`` there; never raises
    (except KeyboardInterrupt): an exception becomes the run's ``error``.  The study runs with ``--no-progress``
    (its bar would go to the log); ``argv`` records the command line without it."""
    folder = out / study.name
    argv = [*(study.quick_args if quick else study.full_args), "--out", str(folder)]
    folder.mkdir(parents=True, exist_ok=True)
    log = io.StringIO()
    t0 = time.perf_counter()
    run = StudyRun(study, argv, folder, 0.0)
    try:
        module = importlib.import_module(f"fawtgym.eval.reproduce.{study.module}")
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
            run.outcome = module.reproduce([*argv, FLAG])
    except KeyboardInterrupt:
        raise
    except SystemExit as exc:  # argparse inside a study: a bug of this table, reported as the study's error
        run.error = f"the study rejected its arguments {argv} (exit status {exc.code})"
        log.write(traceback.format_exc())
    except BaseException as exc:  # any failure of a study is reported, the others still run
        msg = str(exc).strip().splitlines()
        run.error = f"{type(exc).__name__}: {msg[0] if msg else ''}".rstrip(": ")
        log.write(traceback.format_exc())
    run.seconds = time.perf_counter() - t0
    with contextlib.suppress(OSError):
        (folder / "log.txt").write_text(log.getvalue())
    return run


# ---- report ---------------------------------------------------------------------------------------
def _papers(runs: Sequence[StudyRun]) -> list[str]:
    return list(dict.fromkeys(r.study.paper for r in runs))


def _figures(run: StudyRun, out: Path) -> list[tuple[str, str]]:
    """(path relative to ``out``, caption) of the run's figures that exist."""
    if run.outcome is None:
        return []
    figs = []
    for p in run.outcome.figures:
        p = Path(p)
        if not p.is_absolute():
            p = Path.cwd() / p
        if p.is_file():
            rel = Path(os.path.relpath(p, out.resolve())).as_posix()
            figs.append((rel, CAPTIONS.get(p.name, p.stem.replace("_", " "))))
    return figs


def _rel(path: Path | None, out: Path) -> str | None:
    if path is None:
        return None
    p = path if path.is_absolute() else Path.cwd() / path
    return Path(os.path.relpath(p, out.resolve())).as_posix() if p.is_file() else None


def _claim_rows(claims: Sequence[C.Claim], with_paper: bool = False) -> tuple[list[str], list[list[str]],
                                                                                   list[list[str | None]]]:
    header = (["paper"] if with_paper else []) + ["where", "claim", "paper", "ours", "verdict", "reason",
                                                   "criterion"]
    rows, classes = [], []
    for c in claims:
        rows.append(([c.paper] if with_paper else []) + [c.where, c.statement, c.paper_value, c.our_value, c.verdict,
                                                         c.reason, c.criterion])
        cls: list[str | None] = ["dim" if c.verdict == C.UNCHECKED else None] * len(rows[-1])
        cls[-3] = VERDICT_CLASS[c.verdict]
        classes.append(cls)
    return header, rows, classes


def _md_escape(s: str) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def _md_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Markdown table; a ``verdict`` column is set in bold."""
    bold = {i for i, h in enumerate(header) if h == "verdict"}
    return (["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            + ["| " + " | ".join(f"**{_md_escape(x)}**" if i in bold else _md_escape(x) for i, x in enumerate(r))
               + " |" for r in rows])


def _summary_rows(runs: Sequence[StudyRun]) -> list[list[str]]:
    rows = []
    for paper in _papers(runs):
        prs = [r for r in runs if r.study.paper == paper]
        t = C.tally(c for r in prs for c in r.claims)
        errors = sum(r.error is not None for r in prs)
        rows.append([paper, ", ".join(r.study.name for r in prs), *(str(t[v]) for v in C.VERDICTS), str(errors)])
    return rows


def write_report(runs: Sequence[StudyRun], out: Path, command: str, wall: float, quick: bool) -> tuple[Path, Path]:
    """Write ``report.md``, ``index.html`` and ``claims.json`` into ``out``; returns (md, html) paths."""
    all_claims = [c for r in runs for c in r.claims]
    total = C.tally(all_claims)
    errors = [r for r in runs if r.error is not None]
    stamp = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    mode = "quick (the short form of every study)" if quick else "full (every study at its default length)"
    subtitle = f"`{command}` · {mode} · {len(runs)} studies in {wall:.0f} s · {stamp}"
    page = HtmlPage("Paper reproductions: every claim, our number, a verdict", subtitle,
                    footer="Written by `fawtgym reproduce all`. Verdict rules and tolerances are code in "
                           "`fawtgym.eval.reproduce` (each study's `paper_claims`); nothing here is typed in.")
    md = ["# Paper reproductions: every claim, our number, a verdict", "", subtitle.replace("·", "|"), ""]

    intro = ("Each study of `fawtgym reproduce` reruns a paper's numerical study (or rebuilds its experiment in "
             "simulation) and checks what the paper states: a number in a table, an ordering, a convergence time. "
             "The verdict is computed from our run with the tolerance shown in the last column: **reproduced** "
             "(agrees within it), **partly** (agrees in part: same direction outside the tolerance, or in some "
             "cases only), **not** (our run contradicts the claim), **not checked** (this run did not produce the "
             "data; the reason says which run does).")
    page.paragraph(intro)
    md += [intro, ""]
    stats = [("reproduced", total[C.REPRODUCED], "good"), ("partly", total[C.PARTLY], "partial"),
             ("not", total[C.NOT], "bad"), ("not checked", total[C.UNCHECKED], "muted")]
    if errors:
        stats.append(("studies failed", len(errors), "error"))
    page.stats(stats)
    md += ["**" + ", ".join(f"{label}: {n}" for label, n, _ in stats) + "**", ""]

    page.heading("Summary by paper", 2)
    md += ["## Summary by paper", ""]
    head = ["paper", "studies", *C.VERDICTS, "errors"]
    srows = _summary_rows(runs)
    scls: list[list[str | None]] = []
    for row in srows:
        cls: list[str | None] = [None, None]
        for v, n in zip(C.VERDICTS, row[2:6], strict=True):
            cls.append(VERDICT_CLASS[v] if n != "0" else None)
        cls.append("error" if row[-1] != "0" else None)
        scls.append(cls)
    page.table(head, srows, cell_classes=scls)
    md += [*_md_table(head, srows), ""]
    trows = [[r.study.name, r.study.paper, f"{r.seconds:.0f} s", "error" if r.error else "ok", " ".join(r.argv)]
             for r in runs]
    page.table(["study", "paper", "wall time", "status", "arguments"], trows,
               caption="Studies run (each in its own subfolder, with its own summary and `log.txt`)",
               cell_classes=[[None, None, None, "error" if r.error else "good", None] for r in runs])
    md += ["Studies run (each in its own subfolder, with its own summary and `log.txt`):", "",
           *_md_table(["study", "paper", "wall time", "status", "arguments"], trows), ""]

    if errors:
        page.heading("Studies that failed", 2)
        md += ["## Studies that failed", ""]
        for r in errors:
            text = f"**{r.study.name}** ({r.study.paper}): {r.error} — traceback in [{r.study.name}/log.txt]" \
                   f"({r.study.name}/log.txt)"
            page.note(text, "error")
            md += [f"- {text}"]
        md.append("")

    contradicted = [c for c in all_claims if c.verdict == C.NOT]
    page.heading("Claims our runs contradict", 2)
    md += ["## Claims our runs contradict", ""]
    if contradicted:
        h, rows, claim_cls = _claim_rows(contradicted, with_paper=True)
        page.paragraph(f"{len(contradicted)} claims get the verdict **not**; they also appear in their paper's "
                       "table below.")
        page.table(h, rows, cell_classes=claim_cls, numeric_auto=False)
        md += [*_md_table(h, rows), ""]
    else:
        page.paragraph("None: no claim checked in this run is contradicted.")
        md += ["None: no claim checked in this run is contradicted.", ""]

    for paper in _papers(runs):
        prs = [r for r in runs if r.study.paper == paper]
        page.heading(paper, 2)
        md += [f"## {paper}", ""]
        if paper in C.TITLES:
            page.paragraph(C.TITLES[paper], css_class="title")
            md += [f"*{C.TITLES[paper]}*", ""]
        for r in prs:
            page.heading(f"{r.study.name}: {r.study.title}", 3)
            md += [f"### {r.study.name}: {r.study.title}", ""]
            summary = _rel(r.outcome.summary, out) if r.outcome else None
            line = f"`fawtgym reproduce {r.study.name} {' '.join(r.argv)}` · {r.seconds:.0f} s"
            if r.outcome is not None and r.outcome.settings:
                line += f" · {r.outcome.settings}"
            if summary:
                line += f" · the study's own report: [{summary}]({summary})"
            page.paragraph(line)
            md += [line.replace("·", "|"), ""]
            if r.error is not None:
                text = (f"**This study failed**: {r.error}. Its claims could not be checked; traceback in "
                        f"[{r.study.name}/log.txt]({r.study.name}/log.txt).")
                page.note(text, "error")
                md += [text, ""]
                continue
            t = C.tally(r.claims)
            page.paragraph(", ".join(f"{v}: {t[v]}" for v in C.VERDICTS))
            h, rows, claim_cls = _claim_rows(r.claims)
            page.table(h, rows, cell_classes=claim_cls, numeric_auto=False)
            md += [*_md_table(h, rows), ""]
            figs = _figures(r, out)
            for rel, cap in figs:
                page.figure(rel, cap)
            md += [f"![{cap}]({rel})" for rel, cap in figs] + ([""] if figs else [])
        if NOT_COVERED.get(paper):
            page.note("Not checked by any study: " + " ".join(NOT_COVERED[paper]))
            md += ["Not checked by any study: " + " ".join(NOT_COVERED[paper]), ""]

    md_path = out / "report.md"
    md_path.write_text("\n".join(md) + "\n", encoding="utf-8")
    html_path = page.write(out / "index.html")
    records = {"command": command, "quick": quick, "wall_seconds": wall, "tally": total,
               "studies": [{"name": r.study.name, "paper": r.study.paper, "argv": r.argv, "seconds": r.seconds,
                            "error": r.error, "settings": r.outcome.settings if r.outcome else None,
                            "claims": [dataclasses.asdict(c) for c in r.claims]} for r in runs]}
    (out / "claims.json").write_text(json.dumps(records, indent=1), encoding="utf-8")
    return md_path, html_path


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ns = _parser().parse_args(argv)
    studies = list(STUDIES)
    if ns.only is not None:
        names = [n.strip() for n in ns.only.split(",") if n.strip()]
        unknown = [n for n in names if n not in {s.name for s in STUDIES}]
        if unknown or not names:
            print(f"{PROG}: error: --only {', '.join(unknown) or repr(ns.only)} unknown; valid: "
                  f"{', '.join(s.name for s in STUDIES)}", file=sys.stderr)
            return 2
        studies = [s for s in STUDIES if s.name in names]
    problem = _check_writable(ns.out)
    if problem is not None:
        print(f"{PROG}: error: {problem}", file=sys.stderr)
        return 2
    from tqdm.auto import tqdm

    command = " ".join([PROG, *argv])
    t0 = time.perf_counter()
    runs: list[StudyRun] = []
    with tqdm(total=len(studies), unit="study", file=sys.stderr, dynamic_ncols=True, disable=ns.no_progress) as bar:
        for study in studies:
            bar.set_description(f"{study.name}")
            run = run_study(study, ns.out, ns.quick)
            runs.append(run)
            t = C.tally(run.claims)
            status = (f"ERROR {run.error}" if run.error else
                      ", ".join(f"{n} {v}" for v, n in t.items() if n))
            bar.write(f"{study.name:12s} {run.seconds:6.0f} s  {status}", file=sys.stderr)
            bar.update(1)
    wall = time.perf_counter() - t0
    md_path, html_path = write_report(runs, ns.out, command, wall, ns.quick)
    total = C.tally(c for r in runs for c in r.claims)
    failed = [r.study.name for r in runs if r.error]
    print(f"{sum(total.values())} claims: " + ", ".join(f"{n} {v}" for v, n in total.items())
          + (f"; studies failed: {', '.join(failed)}" if failed else "") + f" ({wall:.0f} s)")
    print(f"report: {md_path} and {html_path}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
