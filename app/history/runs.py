"""Runs of a station read back from its records: the engines it built, one by one.

What a run is, is said once, where the live station and `sp run` follow them
(`app.station.runs`): each beginning and end is a `run` record in the log.  Here a run is
read from its `started` record to its `ended` record, or, while it is still open, to the
last record.  A log written before runs were recorded has none: its runs are found as
they were then (`find_runs`, from the intentions' state changes), and a log that has both
is read the old way up to its first run record.

Pure functions of `Happening`s: the records as the audit log keeps them (read back by
`app.history.run_history`) or the events `sp run` and the scenario player yield
(`from_events`).  Times are station seconds.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from app.station.runs import Outcome, RunBoundary
from app.store.audit import AuditKind, RecordKind
from planner.runner import Event, EventKind, IntentionState

BACKWARDS = 0.5  # station time running back by more than this: the station process restarted


@dataclass(frozen=True, slots=True)
class Happening:
    """One record on a run's clock."""

    time: float
    kind: RecordKind
    subject: str
    detail: Mapping[str, Any] = field(default_factory=dict)
    user: str = ""
    resource: str = ""  # as the audit log names it ("" if none or unknown)
    key: int = 0  # its place in the log (the audit record's id): what names a run
    wall: float | None = None  # when it was recorded (seconds since the epoch), if known


def from_events(events: Iterable[Event]) -> list[Happening]:
    """The runner's events, keyed by their position."""
    return [
        Happening(e.time, e.kind, e.subject, dict(e.detail), str(e.detail.get("user", "")), key=k)
        for k, e in enumerate(events)
    ]


def on_one_clock(happenings: Sequence[Happening]) -> list[Happening]:
    """Times made monotonic: a restarted station counts its time from 0 again, and its
    records then go on from the last time before the restart."""
    out: list[Happening] = []
    offset, last = 0.0, float("-inf")
    for h in happenings:
        time = h.time + offset
        if time < last - BACKWARDS:
            offset += last - time
            time = last
        last = max(last, time)
        out.append(h if time == h.time else replace(h, time=time))
    return out


@dataclass(frozen=True)
class Run:
    """From the first intention's start to the last one's finish (or cancel)."""

    first: int  # the key of its first happening
    last: int  # of its last (inclusive)
    start: float
    end: float
    intentions: tuple[str, ...]
    outcome: Outcome
    started_at: float | None = None  # wall time of its start (for the time of day), if known

    @property
    def cycle_time(self) -> float:
        return max(0.0, self.end - self.start)

    def wall(self, time: float) -> float | None:
        """Station time `time` of this run as wall time (None when the start's is unknown)."""
        return None if self.started_at is None else self.started_at + (time - self.start)


def runs(happenings: Sequence[Happening]) -> list[Run]:
    """The runs in `happenings`, oldest first; the last may still be running."""
    first = next((k for k, h in enumerate(happenings) if h.kind == EventKind.RUN), None)
    if first is None:
        return find_runs(happenings)
    before = [_ended(r, happenings[first - 1]) for r in find_runs(happenings[:first])]
    return before + recorded_runs(happenings[first:])


def recorded_runs(happenings: Sequence[Happening]) -> list[Run]:
    """The runs the `run` records in `happenings` say."""
    found: list[Run] = []
    start: Happening | None = None
    for h in happenings:
        if h.kind != EventKind.RUN:
            continue
        if h.subject == RunBoundary.STARTED:
            if start is not None:  # a beginning without its end: the log was cut there
                found.append(_run(start, h, Outcome.INTERRUPTED))
            start = h
        elif h.subject == RunBoundary.ENDED and start is not None:
            found.append(_run(start, h, Outcome(str(h.detail.get("outcome", "finished")))))
            start = None
    if start is not None:
        found.append(_run(start, happenings[-1], Outcome.RUNNING))
    return found


def _run(start: Happening, end: Happening, outcome: Outcome) -> Run:
    names = end.detail.get("intentions") or start.detail.get("intentions") or ()
    intentions = tuple(str(n) for n in names)
    return Run(start.key, end.key, start.time, end.time, intentions, outcome, start.wall)


def _ended(run: Run, last: Happening) -> Run:
    """A run of the old log still open where run records begin: it ended there."""
    if run.outcome is not Outcome.RUNNING:
        return run
    return replace(run, last=last.key, end=last.time, outcome=Outcome.INTERRUPTED)


_ENDS = {
    AuditKind.EXPERIMENT: Outcome.INTERRUPTED,
    EventKind.DONE: Outcome.FINISHED,
    EventKind.STOPPED: Outcome.STOPPED,
}
_BUSY = (IntentionState.EXECUTING, IntentionState.ERROR)
_IDLE = (IntentionState.FINISHED, IntentionState.INITIAL)


def find_runs(happenings: Sequence[Happening]) -> list[Run]:
    """The runs of a log written before runs were recorded, oldest first: a run began when
    an intention went executing or in error while none was, and ended when none of its
    intentions was any more; a restart after an error was told by its cause's words."""
    found: list[Run] = []
    active: set[str] = set()  # executing or in error
    names: list[str] = []
    cancelled = False
    start: Happening | None = None

    def close(at: Happening, outcome: Outcome) -> None:
        nonlocal start, cancelled
        assert start is not None
        found.append(Run(start.key, at.key, start.time, at.time, tuple(names), outcome, start.wall))
        start, cancelled = None, False
        active.clear()
        names.clear()

    for h in happenings:
        if h.kind in _ENDS:
            if start is not None:
                close(h, _ENDS[h.kind])
            continue
        if h.kind != EventKind.INTENTION:
            continue
        before, after = str(h.detail.get("before", "")), str(h.detail.get("after", ""))
        if after in _BUSY:  # in error with no start seen: the log began after it
            start = start or h
            active.add(h.subject)
            names.extend([] if h.subject in names else [h.subject])
        elif after in _IDLE and h.subject in active:
            restarted = before == IntentionState.ERROR and "again" in str(h.detail.get("why"))
            if after == IntentionState.INITIAL and restarted:
                continue  # started again after an error: the run went on
            active.discard(h.subject)
            cancelled = cancelled or after == IntentionState.INITIAL
            if not active:
                close(h, Outcome.CANCELLED if cancelled else Outcome.FINISHED)
    if start is not None:
        last = happenings[-1]
        running = Outcome.RUNNING
        found.append(
            Run(start.key, last.key, start.time, last.time, tuple(names), running, start.wall)
        )
    return found


def within(happenings: Iterable[Happening], run: Run) -> list[Happening]:
    return [h for h in happenings if run.first <= h.key <= run.last]


def seconds(value: float) -> str:
    """12.4 s; from a minute on 3 min 05 s; from an hour on 1 h 02 min."""
    if value < 60:
        return f"{value:.1f} s"
    minutes, rest = divmod(round(value), 60)
    if minutes < 60:
        return f"{minutes} min {rest:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"
