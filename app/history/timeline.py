"""The timeline of a run (`app.history.runs`): per resource what ran when, the waits, errors and
recoveries, the cycle time and the time lost per cause: a Gantt chart's data, drawn by
`app.history.timeline_drawing`.

A pure function of the run's `Happening`s and the station model (who owns which
transition).  A resource's *bar* starts when the runner takes one of its controlled
transitions (an ability starts) and lasts until its last effect before the resource's next
start; it ends *failed* at a time-out, an unexpected effect, or when the resource stops
answering.  Operations and intentions get bars for executing and for being in error.

*Time lost* is counted per cause, each moment once, given to the first of these that holds:
waiting for a person's maintenance step or approval; a resource that stopped answering, from
its last sign of life until work goes on with another resource (or it answers again); an
effect that timed out, from when it was due to start until the next step; an unexpected
result, from the start of the attempt until the next step; a forbidden state; restart mode;
an intention in error while the station follows a maintenance plan; an intention in error
with no plan to mend it (the engineer's to solve).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from app.history.runs import Happening, Run, seconds, within
from planner.model.station import Station
from planner.reading.display import humanised
from planner.words import Wording

# the event kinds a timeline reads (and `app.history.runs` needs), for the audit log's query
# fmt: off
KINDS = frozenset({
    "taken", "effect", "unexpected", "timeout", "unavailable", "available", "intention",
    "operation", "plan", "instruction", "approval", "forbidden", "recovered", "operator",
    "restart", "fault", "done", "stopped", "experiment",
})
# fmt: on
PLANNING_LANE = "planning"
NOT_ANSWERING = "not answering"
# the order in which causes claim a moment (first wins)
# fmt: off
PRIORITY = (
    "person", "outage", "timeout", "unexpected", "forbidden", "restart", "maintenance", "error"
)
# fmt: on
ROUTINE = frozenset({"goals", "intentions"})  # replanning that is not a recovery


# -- words ---------------------------------------------------------------------------------------

REASON_WORDS = {
    "goals": "planned for the operations running now",
    "intentions": "planned for the intentions",
    "deviation": "planned again after a deviation",
    "timeout": "planned again after a time-out",
    "availability": "planned again: a resource stopped answering or answers again",
    "error": "planned around operations in error",
    "maintenance": "maintenance planned",
    "forbidden state": "recovery from a forbidden state planned",
    "reset": "planned to reset an operation",
    "restart": "planned again for restart mode",
    "estimated": "planned again after an estimate was set",
    "recovered": "planned again after recovery",
    "cleared": "planned again: an operation left its error",
    "reenabled": "planned again: an effect was re-enabled",
}


def plan_words(detail: Mapping[str, Any]) -> str:
    """A recovery's planning in words: why, and what came of it (the paper's label, such as
    "TP w/RTO", stays out: people read this)."""
    reason = str(detail.get("reason", ""))
    length = int(detail.get("length", 0) or 0)
    found = detail.get("status") == "found"
    result = f"a plan of {length} step{'' if length == 1 else 's'}" if found else "no plan"
    return f"{REASON_WORDS.get(reason, 'planned again')}: {result}"


_SETTING = re.compile(r"(\w+)=([\w.]+)")


def fault_words(text: str, words: Wording) -> str:
    """A fault injected into the simulated world ("kind=disconnect, resource=r2") in words."""
    parts = dict(_SETTING.findall(text))
    kind, resource, effect = parts.get("kind", ""), parts.get("resource"), parts.get("effect")
    if resource and kind in ("disconnect", "reconnect"):
        verb = "stops answering" if kind == "disconnect" else "answers again"
        return f"simulated fault: {words.resource(resource)} {verb}"
    if effect:
        return f"simulated fault: {words.transition(effect)} ({humanised(kind)})"
    return f"simulated fault: {humanised(kind) or words.text(text)}"


# -- what a timeline holds -----------------------------------------------------------------------


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


def timeline(
    happenings: Sequence[Happening], station: Station, run: Run, words: Wording | None = None
) -> Timeline:
    """The run's timeline, every label in `words` (the station's, by default);
    `happenings` may hold more than the run (they are cut to it)."""
    found = words if words is not None else Wording(station)
    return _Builder(station, run, found).build(within(happenings, run))


def describe_losses(found: Sequence[Loss]) -> str:
    """ "robot 2 stopped answering 2.2 s, waiting for the operator 2.0 s" ("" if none)."""
    return ", ".join(f"{loss.cause} {seconds(loss.seconds)}" for loss in found)


# -- building it ---------------------------------------------------------------------------------


@dataclass
class _Open:
    """A bar still growing: an ability running, an operation's or intention's state, a wait."""

    lane: str
    start: float
    label: str
    title: str
    kind: BarKind
    last: float | None = None  # an ability's last effect so far
    settled: float | None = None  # without effects: when the operations next changed

    def until(self, end: float, kind: BarKind | None = None, title: str = "") -> Bar:
        return Bar(self.lane, self.start, end, self.label, title or self.title, kind or self.kind)


@dataclass
class _Waste:
    """A cause of lost time while it lasts (`end` None: still)."""

    rank: str
    cause: str
    start: float
    of: str = ""  # what it is about: a resource, a person's step, an intention
    until_next_step: bool = False  # ends at the next step taken anywhere
    end: float | None = None


class _Builder:
    def __init__(self, station: Station, run: Run, words: Wording) -> None:
        self.station, self.run, self.words = station, run, words
        self.written = {t.name: t.written for t in station.model.transitions}
        self.owner = {t: r.name for r in station.resources for t in r.transitions}
        self.owner.update({v: r.name for r in station.resources for v in r.variables})
        self.people = {r.name for r in station.resources if r.person}
        self.starts = {a.transitions[0]: a for a in station.abilities if a.transitions}
        self.bars: list[Bar] = []
        self.marks: list[Mark] = []
        self.running: dict[str, _Open] = {}  # resource -> its ability running
        self.silent: dict[str, float] = {}  # resource -> since when it does not answer
        self.states: dict[str, _Open] = {}  # lane of an operation or intention -> its state
        self.waits: dict[str, _Open] = {}  # a person's step -> the wait for it
        self.mending: dict[tuple[str, str], _Open] = {}  # (step, resource it mends) -> wait
        self.wastes: list[_Waste] = []

    def build(self, happenings: Sequence[Happening]) -> Timeline:
        for h in happenings:
            handler = getattr(self, "on_" + h.kind, None)
            if handler is not None:
                handler(h)
        end = self.run.end
        for resource in list(self.running):
            self.close(resource, end)
        for resource, since in self.silent.items():
            self.bars.append(Bar(resource, since, end, "", NOT_ANSWERING, BarKind.OUTAGE))
        waiting = [*self.states.values(), *self.waits.values(), *self.mending.values()]
        self.bars += [s.until(end) for s in waiting]
        lanes = [*self.state_lanes(), *self.operation_lanes(), *self.resource_lanes()]
        bars = tuple(b for b in self.bars if b.end >= b.start)
        found = losses(self.wastes, self.run.start, end)
        return Timeline(self.run, tuple(lanes), bars, tuple(self.marks), tuple(found))

    def mark(self, lane: str, time: float, kind: MarkKind, label: str) -> None:
        self.marks.append(Mark(lane, time, kind, label))

    # -- resources -----------------------------------------------------------------------------

    def on_taken(self, h: Happening) -> None:
        resource = self.owner.get(h.subject)
        controlled = h.detail.get("type") not in ("automatic", "effect")
        if controlled:
            self.next_step(h.time, resource or "")
        ability = self.starts.get(h.subject)
        if resource is None:
            return
        if not (controlled and ability is not None):
            self.on_effect(h)
            return
        self.close(resource, h.time)
        kind = BarKind.PERSON if resource in self.people else BarKind.WORK
        label = self.words.ability(ability.qualified)
        self.running[resource] = _Open(resource, h.time, label, label, kind)

    def on_effect(self, h: Happening) -> None:
        running = self.running.get(self.owner.get(h.subject, ""))
        if running is not None:
            running.last = h.time

    def close(self, resource: str, time: float, failed: str = "") -> None:
        running = self.running.pop(resource, None)
        if running is None:
            return
        if failed:
            self.bars.append(running.until(time, BarKind.FAILED, f"{running.title}: {failed}"))
        else:
            ended = running.last if running.last is not None else running.settled
            self.bars.append(running.until(time if ended is None else ended))

    def on_timeout(self, h: Happening) -> None:
        resource = self.owner.get(h.subject, h.resource)
        waited = float(h.detail.get("waited", 0) or 0)
        what = self.words.transition(h.subject)
        self.close(resource, h.time, f"{what} timed out")
        self.mark(resource, h.time, MarkKind.ERROR, f"{what} timed out")
        cause = f"{self.words.resource(resource)}: {what} timed out"
        self.wastes.append(_Waste("timeout", cause, h.time - waited, until_next_step=True))

    def on_unexpected(self, h: Happening) -> None:
        resource = self.owner.get(h.subject, h.resource)
        if not resource:
            return
        attempt = self.running.get(resource)
        what = self.words.transition(h.subject)
        self.close(resource, h.time, f"another result than planned: {what}")
        self.mark(resource, h.time, MarkKind.ERROR, f"another result than planned: {what}")
        cause = f"{self.words.resource(resource)}: another result than planned"
        start = attempt.start if attempt is not None else h.time
        self.wastes.append(_Waste("unexpected", cause, start, until_next_step=True))

    def on_unavailable(self, h: Happening) -> None:
        resource = h.subject
        since = max(self.run.start, h.time - float(h.detail.get("silent_for", 0) or 0))
        self.close(resource, h.time, "no answer")
        self.silent.setdefault(resource, since)
        cause = f"{self.words.resource(resource)} stopped answering"
        self.mark(resource, h.time, MarkKind.ERROR, cause)
        self.wastes.append(_Waste("outage", cause, since, of=resource))

    def on_available(self, h: Happening) -> None:
        resource = h.subject
        since = self.silent.pop(resource, self.run.start)
        self.bars.append(Bar(resource, since, h.time, "", NOT_ANSWERING, BarKind.OUTAGE))
        again = f"{self.words.resource(resource)} answers again"
        self.mark(resource, h.time, MarkKind.RESTORED, again)
        self.end_wastes("outage", h.time, of=resource)

    def on_fault(self, h: Happening) -> None:
        text = str(h.detail.get("fault", h.subject))
        named = re.search(r"(?:resource|effect)=([\w.]+)", text)
        target = h.resource or (named.group(1) if named else "")
        lane = self.owner.get(target, target) or PLANNING_LANE
        self.mark(lane, h.time, MarkKind.FAULT, fault_words(text, self.words))

    def next_step(self, time: float, resource: str) -> None:
        """A step was taken by `resource`: work goes on, and what only held it up ends."""
        for waste in self.wastes:
            if waste.end is not None or time <= waste.start:
                continue
            elsewhere = waste.of != resource and resource not in self.silent
            if waste.until_next_step or (waste.rank == "outage" and elsewhere):
                waste.end = time

    # -- people --------------------------------------------------------------------------------

    def on_instruction(self, h: Happening) -> None:
        person = self.owner.get(h.subject, h.resource or PLANNING_LANE)
        what = self.words.transition(h.subject)
        self.wait(h, person, BarKind.MAINTENANCE, what)
        mended = {self.owner.get(v, "") for v in self.written.get(h.subject, ())}
        for resource in sorted(mended - {"", person}):
            if (h.subject, resource) not in self.mending:
                title = f"waits for {self.words.resource(person)}: {what}"
                wait = _Open(resource, h.time, what, title, BarKind.MAINTENANCE)
                self.mending[(h.subject, resource)] = wait

    def on_approval(self, h: Happening) -> None:
        resource = self.owner.get(h.subject, h.resource or PLANNING_LANE)
        what = self.words.transition(h.subject)
        self.wait(h, resource, BarKind.WAITS, f"waits for approval: {what}")

    def wait(self, h: Happening, lane: str, kind: BarKind, what: str) -> None:
        if h.subject not in self.waits:
            self.waits[h.subject] = _Open(lane, h.time, what, what, kind)
            person = self.words.resource(lane) if lane in self.people else "a person"
            cause = f"waiting for {person}"
            self.wastes.append(_Waste("person", cause, h.time, of=h.subject))

    def on_operator(self, h: Happening) -> None:
        step = str(h.detail.get("transition", ""))
        wait = self.waits.pop(step, None)
        if wait is not None:
            self.bars.append(wait.until(h.time))
            done = f"{wait.label}: done by {h.user or 'someone'}"
            self.mark(wait.lane, h.time, MarkKind.RESTORED, done)
            self.end_wastes("person", h.time, of=step)
        for key in [k for k in self.mending if k[0] == step]:
            self.bars.append(self.mending.pop(key).until(h.time))

    # -- the station as a whole ----------------------------------------------------------------

    def on_plan(self, h: Happening) -> None:
        reason, found = str(h.detail.get("reason", "")), h.detail.get("status") == "found"
        if reason in ROUTINE:
            return
        self.mark(
            PLANNING_LANE,
            h.time,
            MarkKind.RECOVERY if found else MarkKind.ERROR,
            plan_words(h.detail),
        )
        open_errors = [w for w in self.wastes if w.rank == "error" and w.end is None]
        if reason == "maintenance" and found and open_errors:  # the station mends it itself
            self.end_wastes("error", h.time)
            for waste in open_errors:
                cause = "in error, following a maintenance plan"
                self.wastes.append(_Waste("maintenance", cause, h.time, of=waste.of))

    def on_forbidden(self, h: Happening) -> None:
        broken = [str(n) for n in h.detail.get("violated") or ()] or [h.subject]
        what = ", ".join(self.words.specification(n) for n in broken)
        self.mark(PLANNING_LANE, h.time, MarkKind.ERROR, f"forbidden state: {what}")
        self.wastes.append(_Waste("forbidden", "forbidden state, recovering", h.time))

    def on_recovered(self, h: Happening) -> None:
        self.mark(PLANNING_LANE, h.time, MarkKind.RESTORED, "every specification holds again")
        self.end_wastes("forbidden", h.time)

    def on_restart(self, h: Happening) -> None:
        if h.subject == "entered":
            self.wastes.append(_Waste("restart", "in restart mode", h.time))
        else:
            self.end_wastes("restart", h.time)

    def end_wastes(self, rank: str, time: float, of: str = "") -> None:
        for waste in self.wastes:
            if waste.rank == rank and waste.end is None and (not of or waste.of == of):
                waste.end = time

    # -- intentions and operations -------------------------------------------------------------

    def on_intention(self, h: Happening) -> None:
        self.state_change(LaneGroup.INTENTIONS, h)

    def on_operation(self, h: Happening) -> None:
        for running in self.running.values():  # an ability that finished at once
            if running.last is None and running.settled is None:
                running.settled = h.time
        self.state_change(LaneGroup.OPERATIONS, h)

    def state_change(self, group: LaneGroup, h: Happening) -> None:
        name, after = h.subject, str(h.detail.get("after"))
        why = self.words.text(str(h.detail.get("why", "")))
        lane = f"{group}:{name}"
        current = self.states.pop(lane, None)
        if current is not None:
            self.bars.append(current.until(h.time))
        was_error = current is not None and current.kind is BarKind.ERROR
        label = self.label(group, name)
        if after == "e":
            self.states[lane] = _Open(
                lane, h.time, label, self.label(group, name), BarKind.EXECUTING
            )
        elif after == "error":
            self.states[lane] = _Open(lane, h.time, label, f"in error: {why}", BarKind.ERROR)
            self.mark(lane, h.time, MarkKind.ERROR, f"{label} in error: {why}")
            if group is LaneGroup.INTENTIONS:
                cause = "in error, waiting for the engineer"
                self.wastes.append(_Waste("error", cause, h.time, of=name))
        if was_error and after != "error":
            self.mark(lane, h.time, MarkKind.RESTORED, f"{label}: {why}")
            self.end_wastes("error", h.time, of=name)
            self.end_wastes("maintenance", h.time, of=name)

    def label(self, group: LaneGroup, name: str) -> str:
        if group is LaneGroup.OPERATIONS:
            return self.words.operation(name)
        return self.words.intention(name)

    # -- the lanes -----------------------------------------------------------------------------

    def state_lanes(self) -> list[Lane]:
        group = LaneGroup.INTENTIONS
        return [
            Lane(f"{group}:{n}", self.label(group, n), self.label(group, n), group)
            for n in self.run.intentions
        ]

    def resource_lanes(self) -> list[Lane]:
        lanes = [
            Lane(r.name, self.words.resource(r.name), "", LaneGroup.RESOURCES)
            for r in self.station.resources
        ]
        title = "planning to recover, and back to normal"
        return [*lanes, Lane(PLANNING_LANE, "recovery", title, LaneGroup.PLANNING)]

    def operation_lanes(self) -> list[Lane]:
        """Operations packed into as few lanes as ran at once; their bars and marks move to
        them (an episode: from a start until the operation is idle again)."""
        prefix = f"{LaneGroup.OPERATIONS}:"
        mine = sorted((b for b in self.bars if b.lane.startswith(prefix)), key=lambda b: b.start)
        episodes: list[list[Bar]] = []
        for bar in mine:
            same = [e for e in episodes if e[-1].lane == bar.lane and e[-1].end == bar.start]
            if same:
                same[-1].append(bar)
            else:
                episodes.append([bar])
        ends: list[float] = []
        self.bars = [b for b in self.bars if not b.lane.startswith(prefix)]
        moved: list[tuple[str, float, float, str]] = []
        for episode in episodes:
            start, end = episode[0].start, episode[-1].end
            free = [j for j, e in enumerate(ends) if e <= start]
            j = free[0] if free else len(ends)
            ends[j : j + 1] = [end]
            key = f"{LaneGroup.OPERATIONS}#{j}"
            self.bars += [Bar(key, b.start, b.end, b.label, b.title, b.kind) for b in episode]
            moved.append((episode[0].lane, start, end, key))
        self.marks = [_moved(m, moved, prefix) for m in self.marks]
        return [
            Lane(
                f"{LaneGroup.OPERATIONS}#{j}",
                "operations" if j == 0 else "",
                "",
                LaneGroup.OPERATIONS,
            )
            for j in range(max(1, len(ends)))
        ]


def _moved(mark: Mark, moved: Sequence[tuple[str, float, float, str]], prefix: str) -> Mark:
    if not mark.lane.startswith(prefix):
        return mark
    keys = [
        key for lane, start, end, key in moved if lane == mark.lane and start <= mark.time <= end
    ]
    return Mark(keys[0] if keys else f"{LaneGroup.OPERATIONS}#0", mark.time, mark.kind, mark.label)


def losses(wastes: Sequence[_Waste], start: float, end: float) -> list[Loss]:
    """Each moment of the run given to the first cause (by `PRIORITY`) that holds then."""
    spans = [
        (
            PRIORITY.index(w.rank),
            w.cause,
            max(start, w.start),
            min(end, end if w.end is None else w.end),
        )
        for w in wastes
    ]
    spans = [s for s in spans if s[3] > s[2]]
    total: dict[str, float] = {}
    for a, b in itertools.pairwise(sorted({t for s in spans for t in (s[2], s[3])})):
        holding = [s for s in spans if s[2] <= a and s[3] >= b]
        if holding:
            cause = min(holding)[1]
            total[cause] = total.get(cause, 0.0) + (b - a)
    ranked = sorted(total.items(), key=lambda cs: -cs[1])
    return [Loss(c, round(s, 3)) for c, s in ranked if round(s, 3) > 0]  # no "0.0 s" rows
