"""The planning benchmark's rows, targets and Markdown table (see `bench.planning`).

Which number each column shows, and how a target is judged, is decided here alone, so the
README's explanation of the table has one place to match.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.pddl_planners import ExternalResult
    from bench.process import ProcessRun

NUXMV_MS = {10: 776, 20: 1652, 30: 3836, 40: 6259, 50: 34576}  # seed 003 Table VII
PEAK_MB = 300.0  # every row, as the issue asks
EXTERNAL = ("Fast Downward", "SymK")


@dataclass(frozen=True)
class Target:
    """A row's target: its text as the issue words it, and what the Met column compares.

    `seconds` applies to the row's judged time (the median of its warm runs, or of its
    synthesis runs), `megabytes` to its peak over all its sp runs, cold included.
    """

    text: str
    seconds: float | None = None
    megabytes: float = PEAK_MB


@dataclass
class Row:
    name: str
    target: Target
    synthesis: bool = False  # every run synthesises (no cold/warm distinction)
    variables: int | None = None
    bits: int | None = None
    transitions: int | None = None
    reachable: int | None = None
    reachable_note: str = "?"  # shown when `reachable` is None
    length: int | None = None
    cold: ProcessRun | None = None  # plan rows: the run with an empty supervisor cache
    runs: list[ProcessRun] = field(default_factory=list)  # warm runs, or synthesis runs
    planned_runs: int = 0
    failure: str | None = None  # why a run did not answer (timeout, not run, ...)
    sat: float | str | None = None  # ms, or why not
    external: dict[str, str | tuple[ExternalResult, list[str]]] = field(default_factory=dict)
    cache: Path | None = None

    @property
    def median_ms(self) -> float | None:
        return statistics.median(r.wall for r in self.runs) * 1000 if self.runs else None

    @property
    def peak_mb(self) -> float | None:
        peaks = [r.peak_mb for r in [*self.runs, *([self.cold] if self.cold else [])]]
        return max(peaks) if peaks else None

    def met(self) -> str:
        median = self.median_ms
        if median is None:
            return "**no**: " + (self.failure or "no answer").split(":")[0]
        missed = []
        if self.target.seconds is not None and median > self.target.seconds * 1000:
            missed.append(_seconds(median))
        peak = self.peak_mb
        if peak is not None and peak > self.target.megabytes:
            missed.append(f"{peak:,.0f} MB")
        return "yes" if not missed else "**no**: " + ", ".join(missed)


HEADER = (
    "instance",
    "variables (bits)",
    "transitions",
    "reachable states",
    "plan length",
    "sp cold ms",
    "sp median ms",
    "sp max ms",
    "CPU s",
    "peak MB",
    "--engine sat ms",
    "Fast Downward ms (search), MB",
    "SymK ms (search), MB",
    "FD / sp",
    "SymK / sp",
    "nuXmv ms (seed)",
    "target",
    "met",
)


def table(rows: list[Row]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    for r in rows:
        lines.append("| " + " | ".join(_cells(r)) + " |")
    return "\n".join(lines) + "\n"


def _cells(r: Row) -> list[str]:
    median = r.median_ms
    failure = r.failure or "—"  # shown once: in the first sp column without a number
    if r.runs:
        shown = _ms(median)
        if r.planned_runs and len(r.runs) < r.planned_runs:
            shown += f" (n={len(r.runs)})"
        max_ms = _ms(max(x.wall for x in r.runs) * 1000)
        cpu = f"{statistics.median(x.cpu for x in r.runs):.1f}"
    else:
        shown, max_ms = (failure if r.synthesis or r.cold else ""), ""
        cpu = f"{r.cold.cpu:.1f}" if r.cold else ""
    cold = "—" if r.synthesis else _ms(r.cold.wall * 1000) if r.cold else failure
    sizes = f"{r.variables} ({r.bits})" if r.variables is not None else "?"
    reachable = f"{r.reachable:,}" if r.reachable is not None else r.reachable_note
    return [
        r.name,
        sizes,
        f"{r.transitions:,}" if r.transitions is not None else "?",
        reachable,
        str(r.length) if r.length is not None else "—",
        cold,
        shown,
        max_ms,
        cpu,
        f"{r.peak_mb:,.0f}" if r.peak_mb is not None else "",
        "" if r.synthesis else _sat(r.sat),
        *("" if r.synthesis else _external(r.external.get(e, ""), r.length) for e in EXTERNAL),
        *(_ratio(r.external.get(e), median) for e in EXTERNAL),
        "" if r.synthesis else _nuxmv(r.length),
        r.target.text,
        r.met(),
    ]


def _ms(ms: float | None) -> str:
    return f"{ms:,.0f}" if ms is not None else ""


def _seconds(ms: float) -> str:
    return f"{ms / 1000:.2f} s" if ms < 10_000 else f"{ms / 1000:,.0f} s"


def _sat(sat: float | str | None) -> str:
    if isinstance(sat, float):
        return _ms(sat)
    return sat or ""


def _external(cell: str | tuple[ExternalResult, list[str]], length: int | None) -> str:
    if isinstance(cell, str):
        return cell
    result, notes = cell
    if result.status != "found" or result.wall is None:
        return result.status
    text = _ms(result.wall * 1000)
    if result.search is not None:
        text += f" ({_ms(result.search * 1000)})"
    if result.peak_mb is not None:
        text += f", {result.peak_mb:,.0f}"
    if result.length != length:
        notes = [f"**length {result.length}!**", *notes]
    return " ".join([text, *notes])


def _ratio(cell: str | tuple[ExternalResult, list[str]] | None, median: float | None) -> str:
    if median is None or not isinstance(cell, tuple):
        return ""
    result = cell[0]
    if result.status != "found" or result.wall is None:
        return ""
    return f"{result.wall * 1000 / median:.1f}x"


def _nuxmv(length: int | None) -> str:
    if length is None:
        return ""
    nearest = min(NUXMV_MS, key=lambda n: abs(n - length))
    return f"{NUXMV_MS[nearest]:,} (n={nearest})"
