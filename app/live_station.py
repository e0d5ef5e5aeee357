"""The live station: the runner loop of one station process, its devices and its store.

One thread owns the runner, the (simulated) devices and the alarm book, and ticks every
`period` seconds.  Everything else talks to it through requests that the loop takes between
ticks, so the runner stays the only place live state changes (STYLE.md).  After each round
the loop commits, in one transaction, the round's audit records, alarm rows and the
runner's snapshot, and only then answers the requests and tells the web pages: what a
person was told has happened is on disk.
"""

from __future__ import annotations

import asyncio
import json
import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from sqlalchemy import select

from app import supervisor_cache
from app.alarms import Alarm, AlarmBook, AlarmChange, conditions
from app.scenario import Scenario, ScheduledFault, due
from app.store import audit
from app.store.audit import AuditEntry
from app.store.db import Store
from app.store.tables import AlarmRecord, ModelVersion, StationRecord
from hw.sim import Fault, SimulatedWorld
from planner import runner_snapshot
from planner.expressions import Value
from planner.operation_planner import OperationPlanner
from planner.runner import Runner, RunnerState
from planner.runner_io import Action, Event, Inputs, MaintenanceDone, RunnerConfig, StartIntention
from planner.station import Station, load_station
from planner.transition_planner import TransitionPlanner

log = logging.getLogger(__name__)

# the effect a person's "Done" on a task card performs (the watch reports the confirmed card)
CONFIRM_EFFECT = "operator.confirm"
RECENT_EVENTS = 200
CLOCK_FIELDS = ("heard", "effect_since", "next_recheck")


class StationError(Exception):
    """A request the station cannot carry out now; the message says why (shown as a 4xx)."""


@dataclass(frozen=True)
class ActiveModel:
    """A model version made ready to run: parsed, its supervisor synthesised."""

    version_id: int
    number: int
    text: str
    station: Station
    transition_planner: TransitionPlanner
    operation_planner: OperationPlanner


@dataclass(frozen=True)
class StationView:
    """What pages read: replaced as a whole after every round, never changed in place."""

    version: int
    now: float
    model: ActiveModel
    runner: Runner
    state: RunnerState
    alarms: tuple[Alarm, ...]
    events: tuple[Event, ...]  # the most recent, oldest first
    simulated: bool
    armed_faults: tuple[str, ...] = ()
    experiment: str = ""


@dataclass
class _Request:
    kind: str
    payload: Any
    user: str
    future: Future[Any] = field(default_factory=Future)


def build_model(version: ModelVersion, cache: Path | None) -> ActiveModel:
    """Parse a stored version and build its planners (seconds, unless the supervisor is cached)."""
    station = load_station(version.text, f"model version {version.number}")
    planner = supervisor_cache.planner(station.model, version.text, "bdd", cache)
    planner.prepare()  # here, beside the loop, rather than in its first tick's plan
    supervisor_cache.remember_order(planner, version.text, cache)
    return ActiveModel(
        version.id, version.number, version.text, station, planner, OperationPlanner(station)
    )


class LiveStation:
    """The runner loop of one station (see the module docstring)."""

    def __init__(
        self,
        store: Store,
        name: str,
        model: ActiveModel,
        *,
        config: RunnerConfig | None = None,
        simulated: bool = True,
        period: float = 0.1,
        clock: Callable[[], float] = time.monotonic,
        wall: Callable[[], float] = time.time,
    ) -> None:
        self.store = store
        self.name = name
        self.config = config or RunnerConfig(auto_intentions=frozenset())
        self.simulated = simulated
        self.period = period
        self.clock = clock
        self.wall = wall
        self.started_at = clock()
        self.model = model
        self.config = self._person_config(self.config)
        self.runner = self._runner(model, self.config)
        self.requests: queue.Queue[_Request] = queue.Queue()
        self.recent: deque[Event] = deque(maxlen=RECENT_EVENTS)
        self.subscribers: list[tuple[asyncio.AbstractEventLoop, asyncio.Queue[str]]] = []
        # areas of the pages with what they show: an SSE event goes out only when it changed
        self.areas: dict[str, Callable[[StationView], object]] = {}
        self.shown: dict[str, object] = {}
        self.lock = threading.Lock()
        self.thread: threading.Thread | None = None
        self.stopping = threading.Event()
        self.pending_faults: list[ScheduledFault] = []
        self.experiment = ""
        self.version = 0
        now = self.now()
        self.state, self.world, self.book = self._restore(now)
        self.published: dict[str, Value] = dict(self.state.values)
        self.last_snapshot = ""
        self.view = self._make_view(now)

    # -- set-up ---------------------------------------------------------------------------------

    def _person_config(self, config: RunnerConfig) -> RunnerConfig:
        """A person's confirmation is never timed out: the operator takes the time it takes."""
        names = {t.name for t in self.model.station.model.transitions}
        if CONFIRM_EFFECT not in names:
            return config
        return replace(config, effect_timeouts={**config.effect_timeouts, CONFIRM_EFFECT: None})

    @staticmethod
    def _runner(model: ActiveModel, config: RunnerConfig) -> Runner:
        return Runner(
            model.station,
            model.transition_planner,
            model.operation_planner,
            config,
            time.perf_counter,
        )

    def _world(
        self, start: Mapping[str, Value], scenario: Scenario | None = None
    ) -> SimulatedWorld:
        manual = frozenset(
            t.name for t in self.model.station.model.transitions if t.name == CONFIRM_EFFECT
        )
        if scenario is None:
            return SimulatedWorld(self.model.station, start=start, manual=manual)
        return SimulatedWorld(
            self.model.station,
            delays=scenario.delays,
            default_delay=scenario.default_delay,
            start=start,
            manual=manual,
        )

    def _restore(self, now: float) -> tuple[RunnerState, SimulatedWorld, AlarmBook]:
        """The last committed state, or a fresh start when there is none."""
        with self.store.sessions() as session:
            record = session.get(StationRecord, self.name)
            alarm_rows = session.scalars(
                select(AlarmRecord).where(AlarmRecord.station == self.name)
            ).all()
            book = AlarmBook(_alarm_from_json(row.data) for row in alarm_rows)
        if record is None or not record.snapshot:
            state = self.runner.initial(now)
            return state, self._world(state.values), book
        data = json.loads(record.snapshot)
        state = runner_snapshot.load(self.runner, data, now, strict=False)
        world = self._world(state.values)
        if record.world:
            world.load(json.loads(record.world), now)
        return state, world, book

    # -- the loop -------------------------------------------------------------------------------

    def now(self) -> float:
        return self.clock() - self.started_at

    def start(self) -> None:
        self.thread = threading.Thread(target=self._loop, name=f"station-{self.name}", daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.stopping.set()
        if self.thread is not None:
            self.thread.join(timeout=10)

    def _loop(self) -> None:
        next_tick = self.clock()
        while not self.stopping.is_set():
            try:
                self.round()
            except Exception:  # the loop must go on; the cause is logged and audited
                log.exception("station round failed")
                self._audit_now([AuditEntry("error", "station round failed")])
            next_tick += self.period
            delay = next_tick - self.clock()
            if delay < 0:
                next_tick = self.clock()
            self.stopping.wait(max(0.0, delay))

    def round(self) -> None:
        """One round: take requests, tick, commit, then answer and notify."""
        now = self.now()
        requests = self._take_requests()
        entries: list[AuditEntry] = []
        answers: list[tuple[_Request, Any]] = []
        events: list[Event] = []
        actions: list[_Request] = []
        for request in requests:
            if request.kind == "action":
                actions.append(request)
                continue
            try:
                result = self._handle(request, now, entries)
            except StationError as exc:
                request.future.set_exception(exc)
                continue
            answers.append((request, result))
        events += self._fire_faults(now, entries)
        self.world.advance(self.published, now)
        report = self.world.report()
        events += self._tick(Inputs(report.measured, report.observed, report.heartbeats), now)
        for request in actions:
            action: Action = request.payload
            # the tick's measurements were taken above: this tick carries the action alone
            inputs = Inputs(heartbeats=report.heartbeats, actions=(action,))
            try:
                own = self._tick(inputs, now)
            except Exception as exc:  # one bad request must not cost the others their answer
                log.exception("action %r failed", action)
                request.future.set_exception(StationError(f"the station could not do that: {exc}"))
                continue
            if isinstance(action, MaintenanceDone) and _accepted(own, "maintenance done"):
                # the person did it in the world: the simulated devices see it too
                self.world.maintenance(action.transition)
            events += own
            answers.append((request, own))
        for event in events:
            entries.append(self._entry(event))
        changes = self.book.update(conditions(self.runner, self.state), self.wall())
        entries += [_alarm_entry(c) for c in changes]
        data = runner_snapshot.dump(self.state)
        snapshot = json.dumps(data, sort_keys=True)
        # heartbeat times change every round and are rebased on restore: not a change
        for clock_field in CLOCK_FIELDS:
            data.pop(clock_field, None)
        compared = json.dumps(data, sort_keys=True)
        changed = bool(entries) or compared != self.last_snapshot
        if changed:
            self._commit(entries, snapshot, now, alarms=bool(changes) or bool(answers))
            self.last_snapshot = compared
            self.recent.extend(events)
            self.version += 1
            self.view = self._make_view(now)
        for request, result in answers:
            request.future.set_result(result)
        if changed:
            kinds = {"station", *self._changed_areas()}
            if changes:
                kinds.add("alarm")
            self._notify(kinds)

    def _tick(self, inputs: Inputs, now: float) -> list[Event]:
        self.state, _commands, events = self.runner.tick(self.state, inputs, now)
        self.published = dict(self.state.values)
        return events

    def _take_requests(self) -> list[_Request]:
        taken = []
        while True:
            try:
                taken.append(self.requests.get_nowait())
            except queue.Empty:
                return taken

    def _fire_faults(self, now: float, entries: list[AuditEntry]) -> list[Event]:
        fired = []
        for scheduled in list(self.pending_faults):
            if due(scheduled, now, self.runner, self.state.values):
                self.pending_faults.remove(scheduled)
                self.world.inject(scheduled.fault)
                fired.append(Event(now, "fault", scheduled.fault.kind, {"fault": scheduled.text}))
        return fired

    # -- requests -------------------------------------------------------------------------------

    def _submit(self, kind: str, payload: Any, user: str) -> Future[Any]:
        if self.thread is None or not self.thread.is_alive():
            raise StationError("the station is not running")
        request = _Request(kind, payload, user)
        self.requests.put(request)
        return request.future

    def act(self, action: Action) -> Future[list[Event]]:
        """A person's action for the runner; answered with the events of its tick."""
        return self._submit("action", action, action.user)

    def confirm_card(self, user: str, card: str) -> Future[bool]:
        """The operator tapped "Done" on command card `card` (the watch's confirm)."""
        return self._submit("confirm", card, user)

    def inject(self, fault: Fault, text: str, user: str) -> Future[None]:
        self._require_simulated()
        return self._submit("fault", (fault, text), user)

    def play_experiment(self, scenario: Scenario, title: str, user: str) -> Future[None]:
        """Reset the simulated station to a scenario's start and arm its faults (demo only)."""
        self._require_simulated()
        return self._submit("experiment", (scenario, title), user)

    def acknowledge(self, key: str, user: str, note: str) -> Future[AlarmChange]:
        return self._submit("acknowledge", (key, note), user)

    def shelve(self, key: str, user: str, minutes: float, note: str) -> Future[AlarmChange]:
        return self._submit("shelve", (key, minutes, note), user)

    def unshelve(self, key: str, user: str) -> Future[AlarmChange]:
        return self._submit("unshelve", key, user)

    def activate(self, model: ActiveModel, user: str) -> Future[None]:
        """Run another model version; refused unless the station is idle or in restart mode."""
        return self._submit("activate", model, user)

    def _require_simulated(self) -> None:
        if not self.simulated:
            raise StationError("faults are injected on simulated stations only")

    def _handle(self, request: _Request, now: float, entries: list[AuditEntry]) -> Any:
        user, payload = request.user, request.payload
        match request.kind:
            case "confirm":
                card = self.state.values.get("operator.card")
                if card != payload:
                    raise StationError(f"card '{payload}' is no longer shown (now: {card})")
                done = self.world.perform(CONFIRM_EFFECT)
                entries.append(
                    AuditEntry("operator", "card done", user, "operator", {"card": card})
                )
                return done
            case "fault":
                fault, text = payload
                self.world.inject(fault)
                resource = fault.resource or self.runner.owner.get(fault.effect, "")
                entries.append(AuditEntry("fault", fault.kind, user, resource, {"fault": text}))
                return None
            case "experiment":
                self._start_experiment(payload[0], payload[1], now, user, entries)
                return None
            case "acknowledge":
                key, note = payload
                change = self._alarm(lambda: self.book.acknowledge(key, user, note, self.wall()))
                entries.append(_alarm_entry(change))
                return change
            case "shelve":
                key, minutes, note = payload
                change = self._alarm(
                    lambda: self.book.shelve(key, user, minutes, note, self.wall())
                )
                entries.append(_alarm_entry(change))
                return change
            case "unshelve":
                change = self._alarm(lambda: self.book.unshelve(payload, user, self.wall()))
                entries.append(_alarm_entry(change))
                return change
            case "activate":
                self._activate(payload, now, user, entries)
                return None
        raise StationError(f"unknown request '{request.kind}'")

    @staticmethod
    def _alarm(change: Callable[[], AlarmChange]) -> AlarmChange:
        from app.alarms import AlarmError

        try:
            return change()
        except AlarmError as exc:
            raise StationError(str(exc)) from None

    def busy(self) -> str:
        """Why a model cannot be swapped now ("" when it can)."""
        s = self.state
        if s.restart:
            return ""
        executing = [n for n, v in s.intentions.items() if v == "e"]
        executing += [n for n, v in s.operations.items() if v == "e"]
        if executing:
            return "the station is running " + ", ".join(sorted(executing)[:5])
        return ""

    def _activate(
        self, model: ActiveModel, now: float, user: str, entries: list[AuditEntry]
    ) -> None:
        why = self.busy()
        if why:
            raise StationError(f"{why}; activate when it is idle or in restart mode")
        old = self.model
        self.model = model
        self.config = self._person_config(self.config)
        self.runner = self._runner(model, self.config)
        kept = {
            name: value
            for name, value in self.state.values.items()
            if name in model.station.model.variable_index
            and value in model.station.model.variable(name).domain
        }
        state = self.runner.initial(now, kept)
        state.restart = self.state.restart
        for name, value in self.state.intentions.items():
            if name in state.intentions and value in ("f", "error"):
                state.intentions[name] = value
        self.state = state
        world_values = {
            n: v for n, v in self.world.values.items() if n in model.station.model.variable_index
        }
        self.world = self._world({**kept, **world_values})
        self.pending_faults = []
        with self.store.sessions.begin() as session:
            record = session.get(StationRecord, self.name)
            if record is not None:
                record.active_version_id = model.version_id
        entries.append(
            AuditEntry(
                "model",
                "activated",
                user,
                "",
                {"version": model.number, "previous": old.number},
            )
        )

    def _start_experiment(
        self, scenario: Scenario, title: str, now: float, user: str, entries: list[AuditEntry]
    ) -> None:
        config = self._person_config(replace(scenario.config, auto_intentions=frozenset()))
        self.runner = self._runner(self.model, config)
        self.state = self.runner.initial(now, scenario.start)
        self.world = self._world(self.state.values, scenario)
        self.published = dict(self.state.values)
        self.pending_faults = [
            replace(f, at=None if f.at is None else now + f.at) for f in scenario.faults
        ]
        self.experiment = title
        entries.append(AuditEntry("experiment", title, user, "", {"file": scenario.file}))
        for name in scenario.intentions or ():
            self.requests.put(_Request("action", StartIntention(user=user, name=name), user))

    # -- store ----------------------------------------------------------------------------------

    def _entry(self, event: Event) -> AuditEntry:
        detail = event.as_json()
        detail.pop("kind", None)
        detail.pop("subject", None)
        detail["station_time"] = detail.pop("time", round(event.time, 3))
        user = str(event.detail.get("user", ""))
        return AuditEntry(event.kind, event.subject, user, self.resource_of(event), detail)

    def resource_of(self, event: Event) -> str:
        """The resource an event concerns, for the auditor's filter ("" if none or several)."""
        subject = event.subject
        if subject in self.runner.resource_transitions:
            return subject
        owner = self.runner.owner.get(subject)
        if owner:
            return owner
        variable = str(event.detail.get("variable", ""))
        for resource in self.model.station.resources:
            if variable in resource.variables or subject in resource.variables:
                return resource.name
        return ""

    def _commit(self, entries: list[AuditEntry], snapshot: str, now: float, alarms: bool) -> None:
        wall = self.wall()
        with self.store.sessions.begin() as session:
            record = session.get(StationRecord, self.name)
            if record is None:
                record = StationRecord(name=self.name, active_version_id=self.model.version_id)
                session.add(record)
            record.snapshot = snapshot
            record.world = json.dumps(self.world.dump(now), sort_keys=True)
            record.updated_at = wall
            if alarms:
                for alarm in self.book.alarms(include_normal=True, include_shelved=True):
                    row = session.get(AlarmRecord, (self.name, alarm.key))
                    data = _alarm_to_json(alarm)
                    if row is None:
                        session.add(
                            AlarmRecord(
                                station=self.name, key=alarm.key, data=data, updated_at=wall
                            )
                        )
                    elif row.data != data:
                        row.data, row.updated_at = data, wall
            if entries:
                audit.append(session, self.name, entries, wall)

    def _audit_now(self, entries: list[AuditEntry]) -> None:
        try:
            audit.append_committed(self.store.sessions, self.name, entries, self.wall())
        except Exception:
            log.exception("could not write the audit log")

    # -- views and notification -----------------------------------------------------------------

    def _make_view(self, now: float) -> StationView:
        return StationView(
            version=self.version,
            now=now,
            model=self.model,
            runner=self.runner,
            state=self.state,
            alarms=tuple(replace(a) for a in self.book.alarms(include_shelved=True)),
            events=tuple(self.recent),
            simulated=self.simulated,
            armed_faults=tuple(f.text for f in self.pending_faults),
            experiment=self.experiment,
        )

    def watch_area(self, name: str, shows: Callable[[StationView], object]) -> None:
        """Announce SSE event `name` only when `shows(view)` changes (a page area that must
        not be re-rendered under a person's finger on every tick)."""
        self.areas[name] = shows
        self.shown[name] = shows(self.view)

    def _changed_areas(self) -> set[str]:
        changed = set()
        for name, shows in self.areas.items():
            now = shows(self.view)
            if now != self.shown.get(name):
                self.shown[name] = now
                changed.add(name)
        return changed

    def subscribe(self) -> asyncio.Queue[str]:
        """A queue that receives the names of what changed ("station", "alarm")."""
        changes: asyncio.Queue[str] = asyncio.Queue(maxsize=100)
        with self.lock:
            self.subscribers.append((asyncio.get_running_loop(), changes))
        return changes

    def unsubscribe(self, changes: asyncio.Queue[str]) -> None:
        with self.lock:
            self.subscribers = [(lp, q) for lp, q in self.subscribers if q is not changes]

    def _notify(self, kinds: set[str]) -> None:
        with self.lock:
            subscribers = list(self.subscribers)
        for loop, changes in subscribers:
            for kind in sorted(kinds):
                try:
                    loop.call_soon_threadsafe(_offer, changes, kind)
                except RuntimeError:  # that client's event loop is closed
                    self.unsubscribe(changes)


def _accepted(events: list[Event], what: str) -> bool:
    return any(e.kind == "operator" and e.subject == what for e in events)


def _offer(changes: asyncio.Queue[str], kind: str) -> None:
    if not changes.full():
        changes.put_nowait(kind)


def _alarm_entry(change: AlarmChange) -> AuditEntry:
    alarm = change.alarm
    detail: dict[str, Any] = {
        "before": None if change.before is None else str(change.before),
        "after": str(change.after),
        "priority": str(alarm.priority),
        "message": alarm.message,
    }
    if change.note:
        detail["note"] = change.note
    return AuditEntry("alarm", change.key, change.user or "", alarm.resource, detail)


def _alarm_to_json(alarm: Alarm) -> str:
    from dataclasses import asdict

    return json.dumps(asdict(alarm), sort_keys=True, default=str)


def _alarm_from_json(text: str) -> Alarm:
    from app.alarms import AlarmState, Priority

    data = json.loads(text)
    data["priority"] = Priority(data["priority"])
    data["state"] = AlarmState(data["state"])
    if data.get("shelved_state") is not None:
        data["shelved_state"] = AlarmState(data["shelved_state"])
    return Alarm(**data)
