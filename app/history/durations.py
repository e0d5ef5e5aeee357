"""How long each operation takes at this station, learned from its own history.

An operation's time is from its start to reaching its goal, as the runner's `operation`
events say (one deferred, put in error or reset is not timed: it did not finish).  The
station plans with the median of each operation's last `LAST` times
(`planner.planning.makespan`); an operation names its resource (get_nr_r1), so the same
work by another robot is learned apart.  The median, so that one slow run (a person away, a
robot that waited for the other) does not steer the next plans.
"""

from __future__ import annotations

import statistics
from collections import deque
from collections.abc import Iterable
from typing import Any, Protocol

from planner.runner import EventKind, OperationState

LAST = 5  # the times of an operation the station remembers


class Record(Protocol):
    """An event of the runner or a `Happening` of the store."""

    @property
    def time(self) -> float: ...
    @property
    def kind(self) -> Any: ...
    @property
    def subject(self) -> str: ...
    @property
    def detail(self) -> Any: ...


class Durations:
    """The last `LAST` times of each operation, fed event by event."""

    def __init__(self, last: int = LAST) -> None:
        self.last = last
        self.times: dict[str, deque[float]] = {}
        self.started: dict[str, float] = {}

    def learn(self, records: Iterable[Record]) -> bool:
        """Take `records` in order; whether an operation finished among them."""
        finished = False
        for record in records:
            if record.kind != EventKind.OPERATION:
                continue
            before, after = record.detail.get("before"), record.detail.get("after")
            if after == OperationState.EXECUTING:
                self.started[record.subject] = record.time
            elif before == OperationState.EXECUTING:
                began = self.started.pop(record.subject, None)
                if began is not None and record.detail.get("why") == "goal reached":
                    times = self.times.setdefault(record.subject, deque(maxlen=self.last))
                    times.append(max(0.0, record.time - began))
                    finished = True
        return finished

    def forget_starts(self) -> None:
        """Operations under way are not timed across a restart or a new experiment."""
        self.started.clear()

    def medians(self) -> dict[str, float]:
        return {name: statistics.median(times) for name, times in sorted(self.times.items())}


def learned(records: Iterable[Record], last: int = LAST) -> dict[str, float]:
    """The medians of the last `last` times of each operation in `records`."""
    book = Durations(last)
    book.learn(records)
    return book.medians()
