"""Seed 000 Table 1 read off an event stream: the recovery types a fault led to, and whether
they are the paper's.

One definition for every reader: the runner's tests, the experiments on emulated devices
(events read back from `sp run --json`) and `bench.cycle`.  An event here is anything with a
`kind`, a `subject` and a `detail` mapping, so the runner's `Event` and a JSON line read
back both fit.

The recovery after a fault is every planning action from the first fault on that was not
routine: one made for another reason than new goals or intentions, or one that found no
plan (a routine query that fails is where error handling begins: with operations in
parallel, the plan that finds a silent robot's work out of reach may be the one made for the
operation just started).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

from planner.runner.vocabulary import EventKind, PersonAct, ReplanReason


class EventLike(Protocol):
    @property
    def kind(self) -> str: ...
    @property
    def subject(self) -> str: ...
    @property
    def detail(self) -> Mapping[str, Any]: ...


def label(event: EventLike) -> str:
    """A planning action's Table 1 label: "TP w/RTO w/MT"."""
    flags = "".join(f" w/{flag}" for flag in event.detail.get("flags", ()))
    return f"{event.detail['level']}{flags}"


def recovering(reason: str, status: str) -> bool:
    """Whether a planning action after a fault is part of the recovery (module docstring)."""
    return not ReplanReason(reason).routine or status != "found"


def recovery(events: Sequence[EventLike]) -> list[EventLike]:
    """The planning actions that recovered from the first fault (module docstring)."""
    first = next((k for k, e in enumerate(events) if e.kind == EventKind.FAULT), None)
    if first is None:
        return []
    return [
        e
        for e in events[first:]
        if e.kind == EventKind.PLAN and recovering(e.detail["reason"], e.detail["status"])
    ]


def matches(paper: str, ours: str) -> bool:
    """Our label is the paper's type: the same planner, with at least the paper's flags."""
    level, *flags = paper.replace(" w/", " ").split()
    our_level, *our_flags = ours.replace(" w/", " ").split()
    return level == our_level and set(flags) <= set(our_flags)


def as_the_paper(paper: Sequence[str], ours: Sequence[str]) -> bool:
    """Ours begin with the paper's first type and hold all of the paper's, in order."""
    if not paper:
        return True
    if not ours or not matches(paper[0], ours[0]):
        return False
    rest = iter(ours)
    return all(any(matches(p, o) for o in rest) for p in paper)


def operator_work(events: Sequence[EventLike]) -> list[str]:
    """The maintenance steps people reported done, in order (Table 1's last column)."""
    return [
        str(e.detail["transition"])
        for e in events
        if e.kind == EventKind.OPERATOR and e.subject == PersonAct.MAINTENANCE_DONE
    ]
