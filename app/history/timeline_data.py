"""What a run's timeline holds: lanes, bars, marks, and the time lost per cause.

A Gantt chart's data: `app.history.timeline` builds it from a run's records and
`app.history.timeline_drawing` draws it.  Lanes are grouped (intentions, operations,
resources, the planning lane); a bar is what a lane did or waited for over a span, a mark
what happened at a moment.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

from app.history.runs import Run

PLANNING_LANE = "planning"
NOT_ANSWERING = "not answering"


class Cause(StrEnum):
    """What lost time is put down to; when several hold, the first of these claims the moment
    (their order here)."""

    PERSON = "person"  # waiting for a person's maintenance step or approval
    OUTAGE = "outage"  # a resource that stopped answering
    TIMEOUT = "timeout"  # an effect that did not happen in time
    UNEXPECTED = "unexpected"  # a different result than planned (the scan found nothing)
    FORBIDDEN = "forbidden"  # a forbidden state, recovering
    RESTART = "restart"  # restart mode
    MAINTENANCE = "maintenance"  # in error while the station follows a maintenance plan
    ERROR = "error"  # in error with no plan to mend it (the engineer's to solve)


class LaneGroup(StrEnum):
    INTENTIONS = "intentions"
    OPERATIONS = "operations"
    RESOURCES = "resources"
    PLANNING = "planning"


class BarKind(StrEnum):
    WORK = "work"  # a device's ability running
    PERSON = "person"  # a person's task card
    EXECUTING = "executing"  # an intention or an operation
    FAILED = "failed"  # ended by a time-out, an unexpected effect or silence
    ERROR = "error"  # an intention or an operation in error
    # what a lane waits for, drawn as a strip under its activity (may overlap it):
    MAINTENANCE = "maintenance"  # a person's step after an error (also on what it mends)
    WAITS = "waits"  # a step waiting for a person's approval
    OUTAGE = "outage"  # the resource does not answer

    @property
    def activity(self) -> bool:
        """What the lane does (one at a time), rather than what it waits for."""
        return self not in (BarKind.MAINTENANCE, BarKind.WAITS, BarKind.OUTAGE)

    @property
    def abnormal(self) -> bool:
        """Coloured in the drawing (ISA-101: grey for normal work)."""
        return self not in (BarKind.WORK, BarKind.PERSON, BarKind.EXECUTING)


class MarkKind(StrEnum):
    ERROR = "error"
    RECOVERY = "recovery"  # a plan made to recover
    RESTORED = "restored"  # back to normal: answers again, error cleared, step done
    FAULT = "fault"  # injected into the simulated world


@dataclass(frozen=True)
class Lane:
    key: str
    label: str
    title: str
    group: LaneGroup


@dataclass(frozen=True)
class Bar:
    lane: str
    start: float
    end: float
    label: str
    title: str
    kind: BarKind


@dataclass(frozen=True)
class Mark:
    lane: str
    time: float
    kind: MarkKind
    label: str
    forbidden: bool = False  # an error mark for a forbidden state (drawn apart)


@dataclass(frozen=True)
class Loss:
    cause: str
    seconds: float


@dataclass(frozen=True)
class Timeline:
    run: Run
    lanes: tuple[Lane, ...]
    bars: tuple[Bar, ...]
    marks: tuple[Mark, ...]
    losses: tuple[Loss, ...]  # per cause, the most first

    @property
    def cycle_time(self) -> float:
        return self.run.cycle_time

    @property
    def lost(self) -> float:
        return sum(loss.seconds for loss in self.losses)

    def lane(self, key: str) -> Lane:
        return next(lane for lane in self.lanes if lane.key == key)

    @property
    def at_once(self) -> tuple[int, float]:
        """The most operations that executed at once, and for how many seconds two or more
        did: what parallel operations gave this run (section 3.4)."""
        lanes = {lane.key for lane in self.lanes if lane.group is LaneGroup.OPERATIONS}
        edges = sorted(
            edge
            for bar in self.bars
            if bar.lane in lanes and bar.kind is BarKind.EXECUTING
            for edge in ((bar.start, 1), (bar.end, -1))
        )  # an end sorts before a start at the same time: back to back is not at once
        most, running, together, since = 0, 0, 0.0, 0.0
        for time, step in edges:
            if running >= 2:
                together += time - since
            running, since = running + step, time
            most = max(most, running)
        return most, together


def pack_operations(
    bars: Sequence[Bar], marks: Sequence[Mark]
) -> tuple[list[Bar], list[Mark], list[Lane]]:
    """Operations packed into as few lanes as ran at once; their bars and marks move to
    them (an episode: from a start until the operation is idle again).  The bars and marks
    after the move, and the operations' lanes."""
    prefix = f"{LaneGroup.OPERATIONS}:"
    mine = sorted((b for b in bars if b.lane.startswith(prefix)), key=lambda b: b.start)
    episodes: list[list[Bar]] = []
    for bar in mine:
        same = [e for e in episodes if e[-1].lane == bar.lane and e[-1].end == bar.start]
        if same:
            same[-1].append(bar)
        else:
            episodes.append([bar])
    ends: list[float] = []
    packed = [b for b in bars if not b.lane.startswith(prefix)]
    moved: list[tuple[str, float, float, str]] = []
    for episode in episodes:
        start, end = episode[0].start, episode[-1].end
        free = [j for j, e in enumerate(ends) if e <= start]
        j = free[0] if free else len(ends)
        ends[j : j + 1] = [end]
        key = f"{LaneGroup.OPERATIONS}#{j}"
        packed += [Bar(key, b.start, b.end, b.label, b.title, b.kind) for b in episode]
        moved.append((episode[0].lane, start, end, key))
    lanes = [
        Lane(
            f"{LaneGroup.OPERATIONS}#{j}", "operations" if j == 0 else "", "", LaneGroup.OPERATIONS
        )
        for j in range(max(1, len(ends)))
    ]
    return packed, [_moved(m, moved, prefix) for m in marks], lanes


def _moved(mark: Mark, moved: Sequence[tuple[str, float, float, str]], prefix: str) -> Mark:
    if not mark.lane.startswith(prefix):
        return mark
    keys = [
        key for lane, start, end, key in moved if lane == mark.lane and start <= mark.time <= end
    ]
    lane = keys[0] if keys else f"{LaneGroup.OPERATIONS}#0"
    return Mark(lane, mark.time, mark.kind, mark.label, mark.forbidden)
