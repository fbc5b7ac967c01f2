"""Paper claims and their verdicts: the record every reproduction study returns for ``reproduce all``.

A :class:`Claim` is one thing a paper states that one of our studies can check: a number in a table,
an ordering, a convergence time.  Its ``verdict`` is computed by code from our run with a stated
tolerance (``criterion``), never typed in:

* ``reproduced`` -- our number or behaviour agrees within the stated tolerance;
* ``partly`` -- agrees in part (same direction but outside the tolerance, or holds in some cases only);
* ``not`` -- our run contradicts the claim;
* ``not checked`` -- this run did not produce the data (e.g. ``--quick`` flies fewer cases); the reason
  says which run would check it.

The helpers below hold the verdict rules shared by the studies (relative tolerances, "holds in k of n
cases", orderings), so each study states only its numbers and thresholds.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

from fawtgym.core.checks import shown

REPRODUCED = "reproduced"
PARTLY = "partly"
NOT = "not"
UNCHECKED = "not checked"
#: every verdict, best first
VERDICTS: tuple[str, ...] = (REPRODUCED, PARTLY, NOT, UNCHECKED)

#: the papers, as cited in the report (full references: docs/references.md)
WANG2024 = "Wang et al. 2024"
SHI2018 = "Shi, Wu and Chou 2018"
WANG2022 = "Wang and Sanyal 2022"
CAYERO2019 = "Cayero et al. 2019"
SILVA2023 = "Silva and Santos 2023"
#: paper -> title (for the report's headings)
TITLES: dict[str, str] = {
    WANG2024: "Geometric extended state observer on TSE(3) with fast finite-time stability: theory and "
              "validation on a multi-rotor vehicle",
    SHI2018: "Generalized extended state observer based high precision attitude control of quadrotor vehicles "
             "subject to wind disturbance",
    WANG2022: "A Hölder-continuous extended state observer for rigid body attitude dynamics",
    CAYERO2019: "Optimal state observation using quadratic boundedness: application to UAV disturbance estimation",
    SILVA2023: "Attitude determination for multirotor aerial vehicles using a predefined-time super twisting "
               "algorithm",
}


@dataclasses.dataclass(frozen=True)
class Claim:
    """One checkable statement of a paper, our value beside it, and the verdict with its reason.

    ``paper``: author(s) and year; ``where``: Table / Fig. / eq. / Sec. of the paper; ``statement``:
    what the paper says, in words; ``paper_value`` / ``our_value``: the numbers (or "yes"/"no") side by
    side, as text; ``criterion``: the tolerance or rule in words; ``verdict``: one of :data:`VERDICTS`;
    ``reason``: why this verdict (the deciding numbers).
    """

    paper: str
    where: str
    statement: str
    paper_value: str
    our_value: str
    criterion: str
    verdict: str
    reason: str

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict must be one of {VERDICTS}, got {shown(self.verdict)}")

    @property
    def holds(self) -> bool:
        """True when the verdict is ``reproduced``."""
        return self.verdict == REPRODUCED


@dataclasses.dataclass
class StudyOutcome:
    """What one study hands to the combined report: its claims, figures and own summary file."""

    claims: list[Claim]
    figures: list[Path] = dataclasses.field(default_factory=list)
    summary: Path | None = None
    settings: str = ""


def fmt(x: float | None, digits: int = 3) -> str:
    """A number for a claim table: ``digits`` significant digits, ``-`` for None, ``inf``/``nan`` as such."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if not math.isfinite(x):
        return str(x)
    return f"{x:.{digits}g}"


def yes_no(flag: bool) -> str:
    return "yes" if flag else "no"


def relative_verdict(ours: float | None, paper: float, reproduced_tol: float, partly_factor: float
                     ) -> tuple[str, str]:
    """Verdict of a number against the paper's: within ``reproduced_tol`` relative error -> reproduced,
    within a factor ``partly_factor`` either way -> partly, else (or missing/non-finite) -> not.

    Returns (verdict, reason).
    """
    if not (reproduced_tol >= 0 and partly_factor >= 1):
        raise ValueError(f"need reproduced_tol >= 0 and partly_factor >= 1, got {reproduced_tol}, {partly_factor}")
    if ours is None or not math.isfinite(ours):
        return NOT, f"no finite value of ours ({ours})"
    if paper == 0:
        raise ValueError("relative_verdict needs a non-zero paper value")
    ratio = ours / paper
    rel = abs(ratio - 1.0)
    if rel <= reproduced_tol:
        return REPRODUCED, f"ours / paper = {ratio:.2f} (within +-{100 * reproduced_tol:.0f} %)"
    if ratio > 0 and 1.0 / partly_factor <= ratio <= partly_factor:
        return PARTLY, (f"ours / paper = {ratio:.2f}: outside +-{100 * reproduced_tol:.0f} % but within a "
                        f"factor {partly_factor:g}")
    return NOT, f"ours / paper = {ratio:.2f}: beyond a factor {partly_factor:g}"


def absolute_verdict(ours: float | None, paper: float, reproduced_tol: float, partly_tol: float
                     ) -> tuple[str, str]:
    """Verdict of a number against the paper's by absolute difference: <= ``reproduced_tol`` -> reproduced,
    <= ``partly_tol`` -> partly, else (or missing) -> not."""
    if ours is None or not math.isfinite(ours):
        return NOT, f"no finite value of ours ({ours})"
    diff = ours - paper
    if abs(diff) <= reproduced_tol:
        return REPRODUCED, f"ours - paper = {diff:+.3g} (tolerance {reproduced_tol:g})"
    if abs(diff) <= partly_tol:
        return PARTLY, f"ours - paper = {diff:+.3g}: outside {reproduced_tol:g} but within {partly_tol:g}"
    return NOT, f"ours - paper = {diff:+.3g}: beyond {partly_tol:g}"


def count_verdict(flags: Sequence[bool], labels: Sequence[str] | None = None) -> tuple[str, str]:
    """All cases hold -> reproduced, some -> partly, none -> not; the reason names the failing cases."""
    flags = [bool(f) for f in flags]
    if not flags:
        return UNCHECKED, "no case of this claim was run"
    labels = list(labels) if labels is not None else [str(i) for i in range(len(flags))]
    failing = [lab for lab, f in zip(labels, flags, strict=True) if not f]
    k = sum(flags)
    if k == len(flags):
        return REPRODUCED, f"holds in all {k} cases" if k > 1 else f"holds in the one case run ({labels[0]})"
    if k:
        return PARTLY, f"holds in {k} of {len(flags)} cases; not in {', '.join(failing)}"
    if len(flags) == 1:
        return NOT, f"does not hold in the one case run ({labels[0]})"
    return NOT, f"holds in none of the {len(flags)} cases"


def decreasing_verdict(values: Sequence[float], labels: Sequence[str]) -> tuple[str, str]:
    """A sequence the paper says falls: strictly falling -> reproduced; last below first but not monotone
    -> partly; otherwise -> not.  ``inf`` (e.g. "never settles") counts as larger than any number."""
    vals = [float(v) for v in values]
    if len(vals) < 2:
        return UNCHECKED, "fewer than two values were run"
    if any(math.isnan(v) for v in vals):
        return NOT, "a value is not a number"
    rises = [f"{labels[i]} -> {labels[i + 1]}" for i in range(len(vals) - 1) if not vals[i + 1] < vals[i]]
    if not rises:
        return REPRODUCED, f"falls at every step ({labels[0]} {fmt(vals[0])} -> {labels[-1]} {fmt(vals[-1])})"
    if vals[-1] < vals[0]:
        return PARTLY, f"{labels[-1]} is below {labels[0]}, but not at every step (rises {', '.join(rises)})"
    return NOT, f"does not fall: {labels[-1]} {fmt(vals[-1])} >= {labels[0]} {fmt(vals[0])}"


def unchecked(paper: str, where: str, statement: str, paper_value: str, criterion: str, why: str) -> Claim:
    """A claim this run produced no data for (``not checked``), with the run that would check it."""
    return Claim(paper, where, statement, paper_value, "-", criterion, UNCHECKED, why)


def tally(claims: Iterable[Claim]) -> dict[str, int]:
    """Number of claims per verdict (every verdict present, zeros included)."""
    out = dict.fromkeys(VERDICTS, 0)
    for c in claims:
        out[c.verdict] += 1
    return out


def markdown_table(claims: Sequence[Claim], with_paper: bool = False) -> list[str]:
    """The claims as Markdown table lines (``|`` inside cells escaped)."""
    def cell(s: str) -> str:
        return str(s).replace("|", "\\|").replace("\n", " ")

    head = (["paper"] if with_paper else []) + ["where", "claim", "paper", "ours", "criterion", "verdict", "reason"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in claims:
        row = ([c.paper] if with_paper else []) + [c.where, c.statement, c.paper_value, c.our_value, c.criterion,
                                                   f"**{c.verdict}**", c.reason]
        lines.append("| " + " | ".join(cell(x) for x in row) + " |")
    return lines
