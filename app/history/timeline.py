"""The timeline of a run (`app.history.runs`): per resource what ran when, the waits, errors and
recoveries, the cycle time and the time lost per cause: a Gantt chart's data
(`app.history.timeline_data`), drawn by `app.history.timeline_drawing`.

A pure function of the run's `Happening`s and the station model (who owns which
transition).  A resource's *bar* starts when the runner takes one of its controlled
transitions (an ability starts) and lasts until its last effect before the resource's next
start; it ends *failed* at a time-out, an unexpected effect, or when the resource stops
answering.  Operations and intentions get bars for executing and for being in error.

*Time lost* is counted per cause, each moment once, given to the first of these that holds
(`Cause`): waiting for a person's maintenance step or approval; a resource that stopped
answering, from its last sign of life until work goes on with another resource (or it
answers again); an effect that timed out, from when it was due to start until the next
step; an unexpected result, from the start of the attempt until the next step; a forbidden
state; restart mode; an intention in error while the station follows a maintenance plan; an
intention in error with no plan to mend it (the engineer's to solve).  Waiting for a person
is one cause whoever the person is: a maintenance step, an approval, or a routine card that
waited past its reminder (the whole wait).  An outage counts in a run from its start at the
earliest; one that ended before the run began is not the run's.

Size: one builder, a handler per record kind sharing its open bars and wastes; split, each
part would need all of that state.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from app.history.runs import Happening, Run, within
from app.history.timeline_data import (
    NOT_ANSWERING,
    PLANNING_LANE,
    Bar,
    BarKind,
    Cause,
    Lane,
    LaneGroup,
    Loss,
    Mark,
    MarkKind,
    Timeline,
    pack_operations,
)
from app.history.timeline_words import fault_words, plan_words
from app.store.audit import AuditKind, RecordKind
from planner.model.flat import TransitionKind
from planner.model.station import Station
from planner.planning.query import PlanStatus
from planner.runner import EventKind, IntentionState, ReplanReason
from planner.runner.vocabulary import RestartMove
from planner.words import Wording

__all__ = ["KINDS", "Timeline", "losses", "timeline"]

KINDS: frozenset[RecordKind] = frozenset(
    {
        *(EventKind.TAKEN, EventKind.EFFECT, EventKind.UNEXPECTED, EventKind.TIMEOUT),
        *(EventKind.UNAVAILABLE, EventKind.AVAILABLE, EventKind.INTENTION, EventKind.OPERATION),
        *(EventKind.PLAN, EventKind.INSTRUCTION, EventKind.APPROVAL, EventKind.FORBIDDEN),
        *(EventKind.RECOVERED, EventKind.OPERATOR, EventKind.RESTART, EventKind.FAULT),
        *(EventKind.DONE, EventKind.STOPPED, EventKind.RUN, AuditKind.EXPERIMENT),
        EventKind.REMINDER,
    }
)
"""The record kinds a timeline reads (and `app.history.runs` needs), for the log's query."""

UNCONTROLLED = (TransitionKind.AUTOMATIC.value, TransitionKind.EFFECT.value)
ROUTINE = frozenset(r.value for r in ReplanReason if r.routine)  # replanning, not recovering
FOUND = PlanStatus.FOUND.value
# one cause, whoever the person is (the legend's words): a maintenance step, an approval, or
# a routine card that waited past its reminder
WAITING_FOR_PEOPLE = "waiting for a person"


def timeline(
    happenings: Sequence[Happening], station: Station, run: Run, words: Wording | None = None
) -> Timeline:
    """The run's timeline, every label in `words` (the station's, by default);
    `happenings` may hold more than the run (they are cut to it)."""
    found = words if words is not None else Wording(station)
    return _Builder(station, run, found).build(within(happenings, run))


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
    """Time lost to `cause` while it lasts (`end` None: still), said as `words`."""

    cause: Cause
    words: str
    start: float
    of: str = ""  # what it is about: a resource, a person's step, an intention
    until_next_step: bool = False  # ends at the next step taken anywhere
    end: float | None = None


class _Builder:
    def __init__(self, station: Station, run: Run, words: Wording) -> None:
        self.station, self.run, self.words = station, run, words
        self.written = {t.name: t.written for t in station.model.transitions}
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
        self.handlers: dict[RecordKind, Callable[[Happening], None]] = {
            EventKind.TAKEN: self.on_taken,
            EventKind.EFFECT: self.on_effect,
            EventKind.TIMEOUT: self.on_timeout,
            EventKind.UNEXPECTED: self.on_unexpected,
            EventKind.UNAVAILABLE: self.on_unavailable,
            EventKind.AVAILABLE: self.on_available,
            EventKind.FAULT: self.on_fault,
            EventKind.INSTRUCTION: self.on_instruction,
            EventKind.APPROVAL: self.on_approval,
            EventKind.OPERATOR: self.on_operator,
            EventKind.PLAN: self.on_plan,
            EventKind.FORBIDDEN: self.on_forbidden,
            EventKind.RECOVERED: self.on_recovered,
            EventKind.RESTART: self.on_restart,
            EventKind.INTENTION: self.on_intention,
            EventKind.OPERATION: self.on_operation,
            EventKind.REMINDER: self.on_reminder,
        }

    def build(self, happenings: Sequence[Happening]) -> Timeline:
        for h in happenings:
            handler = self.handlers.get(h.kind)
            if handler is not None:
                handler(h)
        end = self.run.end
        for resource in list(self.running):
            self.close(resource, end)
        for resource, since in self.silent.items():
            self.bars.append(Bar(resource, since, end, "", NOT_ANSWERING, BarKind.OUTAGE))
        waiting = [*self.states.values(), *self.waits.values(), *self.mending.values()]
        self.bars += [s.until(end) for s in waiting]
        packed, marks, operations = pack_operations(self.bars, self.marks)
        lanes = [*self.state_lanes(), *operations, *self.resource_lanes()]
        bars = tuple(b for b in packed if b.end >= b.start)
        found = losses(self.wastes, self.run.start, end)
        return Timeline(self.run, tuple(lanes), bars, tuple(marks), tuple(found))

    def owner(self, name: str, default: str = "") -> str:
        """The resource a transition or variable belongs to (`default` if none)."""
        return self.station.owner_of(name) or default

    def mark(
        self, lane: str, time: float, kind: MarkKind, label: str, forbidden: bool = False
    ) -> None:
        self.marks.append(Mark(lane, time, kind, label, forbidden))

    def on_taken(self, h: Happening) -> None:
        resource = self.owner(h.subject)
        controlled = h.detail.get("type") not in UNCONTROLLED
        if controlled:
            self.next_step(h.time, resource or "")
        ability = self.starts.get(h.subject)
        if not resource:
            return
        if not (controlled and ability is not None):
            self.on_effect(h)  # an effect or automatic step
            return
        self.close(resource, h.time)
        kind = BarKind.PERSON if resource in self.people else BarKind.WORK
        label = self.words.ability(ability.qualified)
        self.running[resource] = _Open(resource, h.time, label, label, kind)

    def on_effect(self, h: Happening) -> None:
        self.end_wastes(Cause.PERSON, h.time, of=h.subject)  # a routine card done
        running = self.running.get(self.owner(h.subject, ""))
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
        resource = self.owner(h.subject, h.resource)
        waited = float(h.detail.get("waited", 0) or 0)
        what = self.words.transition(h.subject)
        self.close(resource, h.time, f"{what} timed out")
        self.mark(resource, h.time, MarkKind.ERROR, f"{what} timed out")
        cause = f"{self.words.resource(resource)}: {what} timed out"
        self.wastes.append(_Waste(Cause.TIMEOUT, cause, h.time - waited, until_next_step=True))

    def on_unexpected(self, h: Happening) -> None:
        resource = self.owner(h.subject, h.resource)
        if not resource:
            return
        attempt = self.running.get(resource)
        what = self.words.transition(h.subject)
        self.close(resource, h.time, f"not as planned: {what}")
        self.mark(resource, h.time, MarkKind.ERROR, f"not as planned: {what}")
        cause = f"{self.words.resource(resource)}: did not go as planned"
        start = attempt.start if attempt is not None else h.time
        self.wastes.append(_Waste(Cause.UNEXPECTED, cause, start, until_next_step=True))

    def on_unavailable(self, h: Happening) -> None:
        """A resource stopped answering: an outage of this run, counted from the run's start
        at the earliest (one that began in a run before is not this run's)."""
        resource = h.subject
        since = max(self.run.start, h.time - float(h.detail.get("silent_for", 0) or 0))
        self.close(resource, h.time, "no answer")
        self.silent.setdefault(resource, since)
        cause = f"{self.words.resource(resource)} stopped answering"
        if h.time >= self.run.start:  # one from before the run is its outage, not its mark
            self.mark(resource, h.time, MarkKind.ERROR, cause)
        self.wastes.append(_Waste(Cause.OUTAGE, cause, since, of=resource))

    def on_available(self, h: Happening) -> None:
        resource = h.subject
        if h.time <= self.run.start:  # an outage that ended before this run began
            self.silent.pop(resource, None)
            self.end_wastes(Cause.OUTAGE, h.time, of=resource)
            return
        since = self.silent.pop(resource, self.run.start)
        self.bars.append(Bar(resource, since, h.time, "", NOT_ANSWERING, BarKind.OUTAGE))
        again = f"{self.words.resource(resource)} answers again"
        self.mark(resource, h.time, MarkKind.RESTORED, again)
        self.end_wastes(Cause.OUTAGE, h.time, of=resource)

    def on_fault(self, h: Happening) -> None:
        text = str(h.detail.get("fault", h.subject))
        named = re.search(r"(?:resource|effect)=([\w.]+)", text)
        target = h.resource or (named.group(1) if named else "")
        lane = self.owner(target, target) or PLANNING_LANE
        self.mark(lane, h.time, MarkKind.FAULT, fault_words(text, self.words))

    def next_step(self, time: float, resource: str) -> None:
        """A step was taken by `resource`: work goes on, and what only held it up ends."""
        for waste in self.wastes:
            if waste.end is not None or time <= waste.start:
                continue
            elsewhere = waste.of != resource and resource not in self.silent
            if waste.until_next_step or (waste.cause is Cause.OUTAGE and elsewhere):
                waste.end = time

    def on_instruction(self, h: Happening) -> None:
        person = self.owner(h.subject, h.resource or PLANNING_LANE)
        what = self.words.transition(h.subject)
        self.wait(h, person, BarKind.MAINTENANCE, what)
        mended = {self.owner(v, "") for v in self.written.get(h.subject, ())}
        for resource in sorted(mended - {"", person}):
            if (h.subject, resource) not in self.mending:
                title = f"waits for {self.words.resource(person)}: {what}"
                wait = _Open(resource, h.time, what, title, BarKind.MAINTENANCE)
                self.mending[(h.subject, resource)] = wait

    def on_approval(self, h: Happening) -> None:
        resource = self.owner(h.subject, h.resource or PLANNING_LANE)
        what = self.words.transition(h.subject)
        self.wait(h, resource, BarKind.WAITS, f"waits for approval: {what}")

    def wait(self, h: Happening, lane: str, kind: BarKind, what: str) -> None:
        if h.subject not in self.waits:
            self.waits[h.subject] = _Open(lane, h.time, what, what, kind)
            self.wastes.append(_Waste(Cause.PERSON, WAITING_FOR_PEOPLE, h.time, of=h.subject))

    def on_reminder(self, h: Happening) -> None:
        """A routine card (a person's step in the plan) waited past its reminder: the whole
        wait is time lost waiting for a person, until the step is done."""
        started = max(self.run.start, h.time - float(h.detail.get("waited", 0) or 0))
        open_ = [w for w in self.wastes if w.of == h.subject and w.end is None]
        if not any(w.cause is Cause.PERSON for w in open_):
            self.wastes.append(_Waste(Cause.PERSON, WAITING_FOR_PEOPLE, started, of=h.subject))

    def on_operator(self, h: Happening) -> None:
        step = str(h.detail.get("transition", ""))
        wait = self.waits.pop(step, None)
        if wait is not None:
            self.bars.append(wait.until(h.time))
            done = f"{wait.label}: done by {h.user or 'someone'}"
            self.mark(wait.lane, h.time, MarkKind.RESTORED, done)
            self.end_wastes(Cause.PERSON, h.time, of=step)
        for key in [k for k in self.mending if k[0] == step]:
            self.bars.append(self.mending.pop(key).until(h.time))

    def on_plan(self, h: Happening) -> None:
        reason, found = str(h.detail.get("reason", "")), h.detail.get("status") == FOUND
        if reason in ROUTINE:
            return
        self.mark(
            PLANNING_LANE,
            h.time,
            MarkKind.RECOVERY if found else MarkKind.ERROR,
            plan_words(h.detail),
        )
        open_errors = [w for w in self.wastes if w.cause is Cause.ERROR and w.end is None]
        if (
            reason == ReplanReason.MAINTENANCE and found and open_errors
        ):  # the station mends it itself
            self.end_wastes(Cause.ERROR, h.time)
            for waste in open_errors:
                cause = "in error, following a maintenance plan"
                self.wastes.append(_Waste(Cause.MAINTENANCE, cause, h.time, of=waste.of))

    def on_forbidden(self, h: Happening) -> None:
        broken = [str(n) for n in h.detail.get("violated") or ()] or [h.subject]
        what = ", ".join(self.words.specification(n) for n in broken)
        self.mark(PLANNING_LANE, h.time, MarkKind.ERROR, f"forbidden state: {what}", True)
        self.wastes.append(_Waste(Cause.FORBIDDEN, "forbidden state, recovering", h.time))

    def on_recovered(self, h: Happening) -> None:
        self.mark(PLANNING_LANE, h.time, MarkKind.RESTORED, "every specification holds again")
        self.end_wastes(Cause.FORBIDDEN, h.time)

    def on_restart(self, h: Happening) -> None:
        if h.subject == RestartMove.ENTERED:
            self.wastes.append(_Waste(Cause.RESTART, "in restart mode", h.time))
        else:
            self.end_wastes(Cause.RESTART, h.time)

    def end_wastes(self, cause: Cause, time: float, of: str = "") -> None:
        for waste in self.wastes:
            if waste.cause is cause and waste.end is None and (not of or waste.of == of):
                waste.end = time

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
        if after == IntentionState.EXECUTING:
            self.states[lane] = _Open(
                lane, h.time, label, self.label(group, name), BarKind.EXECUTING
            )
        elif after == IntentionState.ERROR:
            self.states[lane] = _Open(lane, h.time, label, f"in error: {why}", BarKind.ERROR)
            self.mark(lane, h.time, MarkKind.ERROR, f"{label} in error: {why}")
            if group is LaneGroup.INTENTIONS:
                cause = "in error, waiting for the engineer"
                self.wastes.append(_Waste(Cause.ERROR, cause, h.time, of=name))
        if was_error and after != IntentionState.ERROR:
            self.mark(lane, h.time, MarkKind.RESTORED, f"{label}: {why}")
            self.end_wastes(Cause.ERROR, h.time, of=name)
            self.end_wastes(Cause.MAINTENANCE, h.time, of=name)

    def label(self, group: LaneGroup, name: str) -> str:
        if group is LaneGroup.OPERATIONS:
            return self.words.operation(name)
        return self.words.intention(name)

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


def losses(wastes: Sequence[_Waste], start: float, end: float) -> list[Loss]:
    """Each moment of the run given to the first cause (in `Cause`'s order) that holds then."""
    order = list(Cause)
    spans = [
        (
            order.index(w.cause),
            w.words,
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
