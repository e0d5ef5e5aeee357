"""A run's timeline (`app.history.timeline`) drawn as an SVG Gantt chart, on the server, without a
JavaScript library.

One row per lane (the intentions, the operations packed into as few rows as ran at once,
each resource, the recoveries); a row's activity is a bar, what it waits for (a person, an
answer) a strip under it.  ISA-101: normal work is grey, colour is kept for the abnormal:
red for failures and errors, amber for waits for people, a hatch for a resource that does
not answer, purple for a forbidden state.  The drawing has a fixed coordinate system
(`WIDTH` units across) and takes the width of its container, so it fits a 1280 px desktop
and scales down on a phone; every bar and mark has a `<title>` with its words and times.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from html import escape

from markupsafe import Markup

from app.history.runs import Run, seconds
from app.history.timeline_data import Bar, BarKind, LaneGroup, Mark, MarkKind, Timeline

WIDTH = 1200  # viewBox units across
LABELS = 200  # the row labels' column
RIGHT = 16
AXIS = 30  # the time axis above the rows
ROW = 30
BAR = (4, 16)  # an activity bar's offset in its row and its height
STRIP = (22, 6)  # a waiting strip's
FONT = 12
CHAR = 6.4  # a character's width at FONT, roughly: a label is shown only if it fits
LABEL_CHARS = 30  # a row label's line (two lines at most)
TICKS = (1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 14400)
MAX_TICKS = 10


@dataclass(frozen=True)
class Swatch:
    """A legend entry: the CSS class the drawing uses, and what it means."""

    css: str
    words: str


LEGEND = (
    Swatch("tl-work", "work, as planned"),
    Swatch("tl-failed", "failed: timed out, another result, or no answer"),
    Swatch("tl-error", "in error"),
    Swatch("tl-waits", "waiting for a person"),
    Swatch("tl-outage", "not answering"),
    Swatch("tl-mark-error", "something went wrong"),
    Swatch("tl-mark-recovery", "a plan to recover"),
    Swatch("tl-mark-restored", "back to normal"),
    Swatch("tl-mark-fault", "simulated fault"),
)

_BAR_CSS = {
    BarKind.WORK: "tl-work",
    BarKind.PERSON: "tl-work",
    BarKind.EXECUTING: "tl-work",
    BarKind.FAILED: "tl-failed",
    BarKind.ERROR: "tl-error",
    BarKind.MAINTENANCE: "tl-waits",
    BarKind.WAITS: "tl-waits",
    BarKind.OUTAGE: "tl-outage",
}


def time_of_day(run: Run, time: float) -> str:
    """Station time `time` of `run` as the time of day ("14:03:07"), else "+12.0 s"."""
    wall = run.wall(time)
    if wall is None:
        return f"+{seconds(max(0.0, time - run.start))}"
    return datetime.fromtimestamp(wall).astimezone().strftime("%H:%M:%S")


def tick_step(duration: float) -> int:
    """The smallest round step that puts at most `MAX_TICKS` ticks on the axis."""
    return next((s for s in TICKS if duration / s <= MAX_TICKS), TICKS[-1])


def wrapped(text: str, width: int = LABEL_CHARS, lines: int = 2) -> list[str]:
    """`text` in at most `lines` lines of about `width` characters, broken at spaces; what
    does not fit ends in an ellipsis at a space (the row's title has the whole text)."""
    out: list[str] = []
    words = text.split()
    while words and len(out) < lines - 1:
        line = words.pop(0)
        while words and len(line) + 1 + len(words[0]) <= width:
            line += " " + words.pop(0)
        out.append(line)
    rest = " ".join(words)
    if len(rest) > width:
        cut = rest.rfind(" ", 0, width)
        rest = rest[: cut if cut > 0 else width - 1] + "…"
    return [*out, rest] if rest else out


class _Scale:
    def __init__(self, run: Run) -> None:
        self.start = run.start
        self.duration = max(run.cycle_time, 1.0)

    def x(self, time: float) -> float:
        plot = WIDTH - LABELS - RIGHT
        return LABELS + plot * min(1.0, max(0.0, (time - self.start) / self.duration))


def draw(found: Timeline, title: str) -> Markup:
    """The SVG of `found`, `title` its accessible name."""
    run, scale = found.run, _Scale(found.run)
    rows = {lane.key: k for k, lane in enumerate(found.lanes)}
    height = AXIS + ROW * len(found.lanes) + 4
    parts = [
        f'<svg class="timeline-chart" viewBox="0 0 {WIDTH} {height}" role="img" '
        f'aria-label="{escape(title)}" preserveAspectRatio="xMinYMin meet">',
        _defs(),
        *_rows(found, height),
        *_axis(run, scale, height),
        *(_bar(b, rows[b.lane], scale, run) for b in _drawn(found.bars, rows)),
        *(_mark(m, rows[m.lane], scale, run) for m in found.marks if m.lane in rows),
        "</svg>",
    ]
    return Markup("\n".join(parts))


def _defs() -> str:
    return (
        '<defs><pattern id="tl-hatch" width="6" height="6" patternUnits="userSpaceOnUse" '
        'patternTransform="rotate(45)"><rect width="6" height="6" class="tl-hatch-ground"/>'
        '<line x1="0" y1="0" x2="0" y2="6" class="tl-hatch-line"/></pattern></defs>'
    )


def _rows(found: Timeline, height: int) -> list[str]:
    out = []
    group: LaneGroup | None = None
    for k, lane in enumerate(found.lanes):
        y = AXIS + k * ROW
        if lane.group is not group and group is not None:
            out.append(f'<line class="tl-group" x1="0" x2="{WIDTH}" y1="{y}" y2="{y}"/>')
        group = lane.group
        lines = wrapped(lane.label)
        first = y + ROW / 2 + FONT / 3 - (len(lines) - 1) * FONT / 2
        spans = "".join(
            f'<tspan x="{LABELS - 8}" y="{first + j * FONT:.1f}">{escape(line)}</tspan>'
            for j, line in enumerate(lines)
        )
        tip = f"<title>{escape(lane.title or lane.label)}</title>" if lines else ""
        out.append(
            f'<g class="tl-row" data-lane="{escape(lane.key)}">'
            f'<rect class="tl-row-ground{" tl-odd" if k % 2 else ""}" x="0" y="{y}" '
            f'width="{WIDTH}" height="{ROW}"/>'
            f'<text class="tl-label" text-anchor="end">{spans}{tip}</text></g>'
        )
    return out


def _axis(run: Run, scale: _Scale, height: int) -> list[str]:
    step = tick_step(scale.duration)
    out = [f'<line class="tl-axis" x1="{LABELS}" x2="{WIDTH - RIGHT}" y1="{AXIS}" y2="{AXIS}"/>']
    wall = run.wall(run.start)
    first = 0.0 if wall is None else math.ceil(wall / step) * step - wall  # on round times
    for k in range(math.floor((scale.duration - first) / step) + 1):
        time = run.start + first + k * step
        x = scale.x(time)
        anchor = "start" if x < LABELS + 30 else "end" if x > WIDTH - RIGHT - 30 else "middle"
        out.append(
            f'<line class="tl-tick" x1="{x:.1f}" x2="{x:.1f}" y1="{AXIS - 5}" y2="{height}"/>'
            f'<text class="tl-time" x="{x:.1f}" y="{AXIS - 9}" text-anchor="{anchor}">'
            f"{escape(time_of_day(run, time))}</text>"
        )
    return out


def _drawn(bars: Sequence[Bar], rows: dict[str, int]) -> list[Bar]:
    """Strips under activity, so a bar's title is the one a pointer finds."""
    shown = [b for b in bars if b.lane in rows]
    return sorted(shown, key=lambda b: (b.kind.activity, b.start))


def _bar(bar: Bar, row: int, scale: _Scale, run: Run) -> str:
    x0, x1 = scale.x(bar.start), scale.x(bar.end)
    offset, height = BAR if bar.kind.activity else STRIP
    y = AXIS + row * ROW + offset
    width = max(x1 - x0, 2.0)
    fill = ' fill="url(#tl-hatch)"' if bar.kind is BarKind.OUTAGE else ""
    when = f"{time_of_day(run, bar.start)} to {time_of_day(run, bar.end)}"
    what = bar.title if bar.title.startswith(bar.label) else f"{bar.label}: {bar.title}"
    tip = f"{what} ({when}, {seconds(bar.end - bar.start)})"
    label = ""
    if bar.kind.activity and bar.label and len(bar.label) * CHAR + 8 <= width:
        label = (
            f'<text class="tl-bar-label" x="{x0 + 4:.1f}" y="{y + height - 4}">'
            f"{escape(bar.label)}</text>"
        )
    return (
        f'<g class="tl-bar {_BAR_CSS[bar.kind]}" data-kind="{bar.kind}" '
        f'data-lane="{escape(bar.lane)}"><rect x="{x0:.1f}" y="{y}" width="{width:.1f}" '
        f'height="{height}" rx="2"{fill}/>{label}<title>{escape(tip)}</title></g>'
    )


_MARK_SHAPES = {
    MarkKind.ERROR: "M{x},{top} l6,11 h-12 z",  # a triangle
    MarkKind.RECOVERY: "M{x},{top} l6,6 l-6,6 l-6,-6 z",  # a diamond
    MarkKind.RESTORED: "M{x},{top} m-5,6 a5,5 0 1,0 10,0 a5,5 0 1,0 -10,0",  # a circle
    MarkKind.FAULT: "M{x},{top} m-5,1 l10,10 m0,-10 l-10,10",  # a cross
}


def _mark(mark: Mark, row: int, scale: _Scale, run: Run) -> str:
    x, top = scale.x(mark.time), AXIS + row * ROW + 3
    path = _MARK_SHAPES[mark.kind].format(x=f"{x:.1f}", top=top)
    forbidden = " tl-mark-forbidden" if mark.forbidden else ""
    tip = f"{mark.label} ({time_of_day(run, mark.time)})"
    return (
        f'<g class="tl-mark tl-mark-{mark.kind}{forbidden}" data-kind="{mark.kind}" '
        f'data-lane="{escape(mark.lane)}"><path d="{path}"/><title>{escape(tip)}</title></g>'
    )
