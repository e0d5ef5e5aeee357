"""One round of the live station, and what happens after its tick, step by step.

A round takes the people's requests (each applied by its own `apply`,
`app.station.requests`), steps the station cycle once with the round's actions, then hands
the round to the steps of `AFTER_TICK`, in order, the way py_trees hands a tick to its
post-tick handlers:

    follow_runs      the run tracker says where runs begin and end (`app.station.runs`)
    learn_durations  an operation that reached its goal teaches how long it takes
                     (`app.history.durations`): the next operation plans use it
    record_events    every event of the round becomes an audit record
    keep_alarms      the alarm book follows the runner's state; a run that ended closes
                     the alarms that came and went in it
    commit           records, alarm rows and the runner's snapshot in one transaction
    show             the pages' view of the round (`StationView`)
    answer           each request gets its answer: only now, so that whatever a person is
                     told has happened is on disk
    notify           the open pages hear what changed

A step that needs state of its own across rounds (what was last saved, the view) is an
object with that state; the others are functions.  The loop is the only caller.
"""

from __future__ import annotations

import json
import logging
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from typing import Any

from app.station import records
from app.station.alarm_grouping import rationalise
from app.station.alarms import AlarmChange, conditions
from app.station.cycle import CycleResult
from app.station.page_updates import PageUpdates
from app.station.running import Running
from app.station.view import DeviceLink, StationView
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from planner.runner import Action, Event, EventKind, snapshot

log = logging.getLogger(__name__)

RECENT_EVENTS = 200  # the events a view keeps for the pages

Answer = Callable[[CycleResult], Any]  # a request's answer, once its round has committed


@dataclass
class Round:
    """What one round gathers on its way: its time, the people's actions for its tick, its
    events and audit records in order, and the requests to answer when it has committed."""

    now: float  # station time
    wall: float  # seconds since the epoch, for records and alarms
    actions: list[Action] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    entries: list[AuditEntry] = field(default_factory=list)
    alarm_changes: list[AlarmChange] = field(default_factory=list)
    reset: str = ""  # why the station was put back to a start this round ("" if it was not)
    answers: list[tuple[Future[Any], Answer]] = field(default_factory=list)
    result: CycleResult = field(default_factory=lambda: CycleResult(()))
    changed: bool = False  # something worth saving and showing happened

    def act(self, action: Action) -> int:
        """Put a person's action into this round's tick; its place among the replies."""
        self.actions.append(action)
        return len(self.actions) - 1

    def record(self, entry: AuditEntry) -> None:
        self.entries.append(entry)

    def alarm_changed(self, change: AlarmChange) -> None:
        self.alarm_changes.append(change)
        self.entries.append(records.alarm_entry(change))

    def boundary(self) -> str:
        """Why a run began or ended this round, or the station was reset ("" if neither)."""
        if self.reset:
            return self.reset
        runs = [e for e in self.events if e.kind is EventKind.RUN]
        return str(runs[0].detail.get("why", "")) if runs else ""


RoundStep = Callable[[Running, Round], None]


def follow_runs(running: Running, round_: Round) -> None:
    """The round's events in their order: a reset's, a run that begins, the tick's, a run
    that ends (`RunTracker.around`)."""
    tick = round_.result.events
    round_.events += running.runs.around(round_.now, running.state, tick, round_.actions)


def learn_durations(running: Running, round_: Round) -> None:
    if round_.reset:  # an experiment puts the station back: nothing under way is timed
        running.durations.forget_starts()
    if running.durations.learn(round_.events):
        running.runner.learned = running.durations.medians()


def record_events(running: Running, round_: Round) -> None:
    round_.entries += [records.event_entry(running.runner, e) for e in round_.events]


def keep_alarms(running: Running, round_: Round) -> None:
    """One alarm per fault (`app.station.alarm_grouping`): consequences are listed under
    their root, and a device still starting up is not a fault."""
    found = conditions(running.runner, running.state, running.model.words)
    found.update(running.notices)
    if round_.reset:
        running.startup.restart(round_.now)
    quiet = running.startup.quiet(running.state, round_.now)
    alarms = rationalise(found, running.book.active(), quiet)
    for change in running.book.update(alarms, round_.wall):
        round_.alarm_changed(change)
    why = round_.boundary()
    if why:
        note = f"closed: the run it belonged to ended ({why})"
        for change in running.book.end_run(note, round_.wall):
            round_.alarm_changed(change)


class Commit:
    """Saves a round when something worth saving happened: its audit records, the alarm rows
    that changed and the runner's snapshot with the devices' state, in one transaction.  A
    round that only moved the clock (heartbeats) writes nothing."""

    def __init__(self, store: Store, station: str) -> None:
        self.store, self.station = store, station
        self.saved = ""  # the last snapshot saved, without its clock fields
        self.links: tuple[tuple[str, bool, str], ...] = ()

    def __call__(self, running: Running, round_: Round) -> None:
        data = snapshot.dump(running.state)
        compared = records.without_clock(data)
        links = _links_signature(running)
        round_.changed = bool(round_.entries) or compared != self.saved or links != self.links
        self.links = links
        if not round_.changed:
            return
        world = json.dumps(running.devices.dump(round_.now), sort_keys=True)
        saved = records.RoundRecord(
            round_.entries, json.dumps(data, sort_keys=True), world, bool(round_.alarm_changes)
        )
        records.commit(
            self.store, self.station, running.model.version_id, saved, running.book, round_.wall
        )
        self.saved = compared


class Show:
    """The pages' view: made anew after every round that changed something (`StationView`,
    replaced as a whole, never changed in place), and what the open pages are told."""

    def __init__(self, running: Running, simulated: Callable[[], bool], now: float) -> None:
        self.simulated = simulated
        self.recent: deque[Event] = deque(maxlen=RECENT_EVENTS)
        self.updates: PageUpdates[StationView] = PageUpdates()
        self.serial = 0  # counts the views made: a page tells an old one from a new one
        self.view = self.make(running, now)

    def __call__(self, running: Running, round_: Round) -> None:
        if round_.changed:
            self.recent.extend(round_.events)
            self.serial += 1
            self.view = self.make(running, round_.now)

    def make(self, running: Running, now: float) -> StationView:
        return StationView(
            serial=self.serial,
            now=now,
            model=running.model,
            runner=running.runner,
            state=running.state,
            alarms=tuple(replace(a) for a in running.book.alarms(include_shelved=True)),
            events=tuple(self.recent),
            simulated=self.simulated(),
            armed_faults=tuple(f.text for f in running.cycle.faults),
            experiment=running.experiment,
            devices=_device_links(running),
        )

    def notify(self, running: Running, round_: Round) -> None:
        if not round_.changed:
            return
        kinds = {"station", *self.updates.changed_areas(self.view)}
        if any(entry.kind is AuditKind.ALARM for entry in round_.entries):  # people's too
            kinds.add("alarm")
        self.updates.notify(kinds)


def answer(running: Running, round_: Round) -> None:
    for future, answer_of in round_.answers:
        if not future.done():
            future.set_result(answer_of(round_.result))


def _links_signature(running: Running) -> tuple[tuple[str, bool, str], ...]:
    """What of the devices' links changes the view: connected or not, and why."""
    links = running.devices.links()
    return tuple((n, s.connected, s.error) for n, s in sorted(links.items()))


def _device_links(running: Running) -> tuple[DeviceLink, ...]:
    clock = time.monotonic()
    return tuple(
        DeviceLink(
            name,
            link.connected,
            link.latency_ms,
            None if link.last_data is None else max(0.0, clock - link.last_data),
            link.restarts,
            link.error,
        )
        for name, link in sorted(running.devices.links().items())
    )


def after_tick(commit: Commit, show: Show) -> tuple[RoundStep, ...]:
    """The steps after a tick, in their order (the module docstring)."""
    return (
        follow_runs,
        learn_durations,
        record_events,
        keep_alarms,
        commit,
        show,
        answer,
        show.notify,
    )
