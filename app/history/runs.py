"""Runs of a station's intentions, found in its events: the engines it built, one by one.

A *run* starts when an intention starts executing while none is, and ends when none of its
intentions is executing or in error any more: all finished, or cancelled.  Playing an
experiment puts the station back to a start, which interrupts a run; `sp run` ends with
`done` or `stopped`.  An intention started again after an error goes on in the same run.

Pure functions of `Happening`s: the runner's events as the audit log keeps them
(`app.station.records.event_entry`, read back by `app.history.run_history`) or as `sp run` and the
scenario player yield them (`from_events`).  Times are station seconds.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any

from planner.runner import Event

BACKWARDS = 0.5  # station time running back by more than this: the station process restarted


@dataclass(frozen=True, slots=True)
class Happening:
    """One event on a run's clock."""

    time: float
    kind: str
    subject: str
    detail: Mapping[str, Any] = field(default_factory=dict)
    user: str = ""
    resource: str = ""  # as the audit log names it ("" if none or unknown)
    key: int = 0  # its place in the log (the audit record's id): what names a run
    wall: float | None = None  # when it was recorded (seconds since the epoch), if known


def from_events(events: Iterable[Event]) -> list[Happening]:
    """The runner's events, keyed by their position."""
    return [
        Happening(
            e.time, e.kind.value, e.subject, dict(e.detail), str(e.detail.get("user", "")), key=k
        )
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


class Outcome(StrEnum):
    FINISHED = "finished"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"  # an experiment put the station back to a start
    STOPPED = "stopped"  # `sp run` ran out of time
    RUNNING = "running"


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


_ENDS = {"experiment": Outcome.INTERRUPTED, "done": Outcome.FINISHED, "stopped": Outcome.STOPPED}


def find_runs(happenings: Sequence[Happening]) -> list[Run]:
    """The runs in `happenings`, oldest first; the last may still be running."""
    runs: list[Run] = []
    active: set[str] = set()  # executing or in error
    names: list[str] = []
    cancelled = False
    start: Happening | None = None

    def close(at: Happening, outcome: Outcome) -> None:
        nonlocal start, cancelled
        assert start is not None
        run = Run(start.key, at.key, start.time, at.time, tuple(names), outcome, start.wall)
        runs.append(run)
        start, cancelled = None, False
        active.clear()
        names.clear()

    for h in happenings:
        if h.kind in _ENDS:
            if start is not None:
                close(h, _ENDS[h.kind])
            continue
        if h.kind != "intention":
            continue
        before, after = str(h.detail.get("before", "")), str(h.detail.get("after", ""))
        if after in ("e", "error"):  # in error with no start seen: the log began after it
            start = start or h
            active.add(h.subject)
            names.extend([] if h.subject in names else [h.subject])
        elif after in ("f", "i") and h.subject in active:
            if after == "i" and before == "error" and "again" in str(h.detail.get("why")):
                continue  # started again after an error: the run goes on
            active.discard(h.subject)
            cancelled = cancelled or after == "i"
            if not active:
                close(h, Outcome.CANCELLED if cancelled else Outcome.FINISHED)
    if start is not None:
        last = happenings[-1]
        running = Outcome.RUNNING
        runs.append(
            Run(start.key, last.key, start.time, last.time, tuple(names), running, start.wall)
        )
    return runs


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
