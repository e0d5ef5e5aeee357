"""The live station: the runner loop of one station process, its devices and its store.

One thread owns the station cycle (runner and devices) and the alarm book, and steps the
cycle every `period` seconds, with all people's actions of the round in one tick
(`app.station.cycle`, the same cycle the scenario player runs).  Everything else talks to
it through requests that the loop takes between rounds, so the runner stays the only place
live state changes (STYLE.md).  After each round the loop commits, in one transaction, the
round's audit records, alarm rows and the runner's snapshot (`app.station.records`), and
only then answers the requests and tells the web pages: what a person was told has happened
is on disk.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import logging
import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from typing import Any

from app.station import records
from app.station.alarms import AlarmBook, AlarmChange, AlarmError, conditions
from app.station.cycle import StationCycle
from app.station.page_updates import PageUpdates
from app.station.planning_worker import PlanningWorker
from app.station.scenario import Scenario
from app.station.view import ActiveModel, DeviceLink, StationView
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from hw.devices import Devices, Restorable
from hw.faults import Fault, FaultInjection
from hw.simulated import SimulatedWorld
from hw.station_devices import StationDevices
from planner.model.expressions import Value
from planner.model.station import Station
from planner.runner import (
    Action,
    Event,
    EventKind,
    IntentionState,
    OperationState,
    Reply,
    Runner,
    RunnerConfig,
    RunnerState,
    StartIntention,
    snapshot,
)
from planner.runner.carry_over import carry_over

log = logging.getLogger(__name__)

RECENT_EVENTS = 200
LOOP_HISTORY = 5000  # rounds kept for the loop's period summary (`loop_summary`): 500 s at 0.1 s
LATE = 1.5  # a round that starts more than this many periods after the one before is late

# The station's devices for a model, from its start values; with a scenario's delays when an
# experiment is played (simulated devices only).
DeviceSetup = Callable[[Station, Mapping[str, Value], Scenario | None], Devices]


def simulated_devices(
    station: Station, start: Mapping[str, Value], scenario: Scenario | None = None
) -> Devices:
    """The simulated world; a tap on a watch is the person's own (never played by it)."""
    manual = frozenset(watch.confirm for _, watch in station.watches)
    if scenario is None:
        return SimulatedWorld(station, start=start, manual=manual)
    return SimulatedWorld(
        station,
        delays=scenario.delays,
        default_delay=scenario.default_delay,
        start=start,
        manual=manual,
    )


class StationError(Exception):
    """A request the station cannot carry out now; the message says why (shown as a 4xx)."""


@dataclass(frozen=True)
class Acted:
    """The answer to a person's action: the runner's reply and the events of its round."""

    reply: Reply
    events: tuple[Event, ...]


@dataclass
class _Request:
    kind: str
    payload: Any
    user: str
    future: Future[Any] = field(default_factory=Future)


@dataclass(frozen=True)
class Prepared:
    """A model version ready to run: see `LiveStation.prepare`."""

    model: ActiveModel
    runner: Runner
    worker: PlanningWorker | None
    world: Devices | None

    def discard(self) -> None:
        if self.worker is not None:
            self.worker.close()
        if self.world is not None:
            self.world.close()


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
        planning_worker: bool = True,
        planning_delay: float = 0.0,
        devices: DeviceSetup | None = None,
    ) -> None:
        self.store = store
        self.setup = devices or simulated_devices
        self.name = name
        self.simulated = simulated
        self.period = period
        self.clock = clock
        self.wall = wall
        self.started_at = clock()
        self.model = model
        self.config = config or RunnerConfig(auto_intentions=frozenset())
        # planning beside the loop, so that no query stalls a round (app.station.planning_worker)
        self.planning_worker = planning_worker
        self.planning_delay = planning_delay  # tests: every query made slow on purpose
        self.worker = self._worker(model)
        self.requests: queue.Queue[_Request] = queue.Queue()
        self.recent: deque[Event] = deque(maxlen=RECENT_EVENTS)
        self.updates: PageUpdates[StationView] = PageUpdates()
        self.thread: threading.Thread | None = None
        self.stopping = threading.Event()
        # each round's start (on `clock`) and duration: what `loop_summary` reports
        self.rounds: deque[tuple[float, float]] = deque(maxlen=LOOP_HISTORY)
        self.experiment = ""
        # why the run ended this round ("" if it did not): its returned alarms are closed
        self.run_ended = ""
        self.version = 0
        now = self.now()
        saved = records.restore(store, name)
        self.book: AlarmBook = saved.alarms
        runner = self._runner(model, self.config)
        if saved.snapshot is None:
            state = runner.initial(now)
            self.devices = self.setup(model.station, state.values, None)
        else:
            state = snapshot.load(runner, saved.snapshot, now, strict=False)
            self.devices = self.setup(model.station, state.values, None)
            if saved.world is not None and isinstance(self.devices, Restorable):
                self.devices.load(saved.world, now)
        self.cycle = StationCycle(runner, self.devices, state)
        self.last_snapshot = ""
        self.last_links: tuple[tuple[str, bool, str], ...] = ()
        self.view = self._make_view(now)

    # -- set-up ---------------------------------------------------------------------------------

    def _worker(self, model: ActiveModel) -> PlanningWorker | None:
        if not self.planning_worker:
            return None
        file = f"model version {model.number}"
        return PlanningWorker(model.text, file, model.cache, delay=self.planning_delay)

    def _runner(
        self, model: ActiveModel, config: RunnerConfig, worker: PlanningWorker | None = None
    ) -> Runner:
        """A runner for `model` whose queries go to `worker` (by default the station's)."""
        return Runner(
            model.station,
            model.transition_planner,
            model.operation_planner,
            config,
            time.perf_counter,
            planning=worker or self.worker,
        )

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
        if self.worker is not None:
            self.worker.close()
        self.devices.close()

    def _loop(self) -> None:
        next_tick = self.clock()
        while not self.stopping.is_set():
            started = self.clock()
            try:
                self.round()
            except Exception:  # the loop must go on; the cause is logged and audited
                log.exception("station round failed")
                self._audit_now([AuditEntry(AuditKind.ERROR, "station round failed")])
            self.rounds.append((started, self.clock() - started))
            next_tick += self.period
            delay = next_tick - self.clock()
            if delay < 0:
                next_tick = self.clock()
            self.stopping.wait(max(0.0, delay))

    def loop_summary(self, since: float | None = None) -> dict[str, float | int]:
        """How well the loop keeps its period, over the rounds kept (the last `LOOP_HISTORY`)
        or those that started at or after station time `since` (`now()`'s seconds).

        On the loop's clock: `period_ms` are the gaps between successive round starts,
        `late` how many exceed `LATE` periods, `round_ms` the rounds' own durations (take,
        tick, commit, notify); `now` is the station time of this summary, to pass as `since`
        to a later one; `cpu_s` the loop thread's CPU seconds so far.  Computed on the
        caller's thread: the loop itself only appends a start and a duration each round.
        """
        rounds = tuple(self.rounds)  # one copy, under the GIL: no lock in the loop
        if since is not None:
            rounds = tuple(r for r in rounds if r[0] >= self.started_at + since)
        starts = [start for start, _ in rounds]
        gaps = sorted(b - a for a, b in itertools.pairwise(starts))
        took = sorted(duration for _, duration in rounds)
        late = sum(1 for gap in gaps if gap > LATE * self.period)
        return {
            "now": round(self.now(), 3),
            "rounds": len(starts),
            "period_ms_p50": _ms(_percentile(gaps, 0.50)),
            "period_ms_p99": _ms(_percentile(gaps, 0.99)),
            "period_ms_max": _ms(gaps[-1] if gaps else 0.0),
            "late": late,
            "round_ms_p50": _ms(_percentile(took, 0.50)),
            "round_ms_p99": _ms(_percentile(took, 0.99)),
            "round_ms_max": _ms(took[-1] if took else 0.0),
            "cpu_s": round(self._loop_cpu(), 3),
        }

    def _loop_cpu(self) -> float:
        """The loop thread's CPU seconds (0 when it is not running or the OS cannot say)."""
        thread = self.thread
        if thread is None or thread.ident is None or not thread.is_alive():
            return 0.0
        try:
            return time.clock_gettime(time.pthread_getcpuclockid(thread.ident))
        except (AttributeError, OSError):  # not on Linux, or the thread just ended
            return 0.0

    def round(self) -> None:
        """One round: take requests, step the station cycle, commit, then answer and notify."""
        now = self.now()
        entries: list[AuditEntry] = []
        answers: list[tuple[_Request, Any]] = []
        acting: list[_Request] = []
        for request in self._take_requests():
            if request.kind == "action":
                acting.append(request)
                continue
            try:
                answers.append((request, self._handle(request, now, entries)))
            except StationError as exc:
                request.future.set_exception(exc)
            except Exception as exc:  # a fault of ours: said, and the person told at once
                log.exception("a %s request failed", request.kind)
                request.future.set_exception(StationError(f"the station could not do that: {exc}"))
        try:
            self._step_and_commit(now, entries, answers, acting)
        except Exception as exc:  # nobody waits 30 s for an answer that will not come
            failed = StationError(f"the station could not do that: {exc}")
            for request, _ in [*answers, *((r, None) for r in acting)]:
                if not request.future.done():
                    request.future.set_exception(failed)
            raise

    def _step_and_commit(
        self,
        now: float,
        entries: list[AuditEntry],
        answers: list[tuple[_Request, Any]],
        acting: list[_Request],
    ) -> None:
        """The round's tick and commit; then its requests are answered and pages told."""
        busy = set(self.state.busy_intentions())
        result = self.cycle.step(now, [request.payload for request in acting])
        answers += [
            (request, Acted(reply, result.events))
            for request, reply in zip(acting, result.replies, strict=True)
        ]
        entries += [records.event_entry(self.runner, event) for event in result.events]
        found = conditions(self.runner, self.state, self.model.words)
        changes = self.book.update(found, self.wall())
        ended = self.run_ended or (self._run_over(busy) if busy else self._new_run(acting))
        if ended:
            why = f"closed: the run it belonged to ended ({ended})"
            changes += self.book.end_run(why, self.wall())
            self.run_ended = ""
        entries += [records.alarm_entry(c) for c in changes]
        data = snapshot.dump(self.state)
        compared = records.compared(data)
        links = self._links_signature()
        changed = bool(entries) or compared != self.last_snapshot or links != self.last_links
        self.last_links = links
        if changed:
            world = json.dumps(self.devices.dump(now), sort_keys=True)
            alarms_changed = bool(changes) or bool(answers)
            round_ = records.RoundRecord(
                entries, json.dumps(data, sort_keys=True), world, alarms_changed
            )
            records.commit(
                self.store, self.name, self.model.version_id, round_, self.book, self.wall()
            )
            self.last_snapshot = compared
            self.recent.extend(result.events)
            self.version += 1
            self.view = self._make_view(now)
        for request, answer in answers:
            request.future.set_result(answer)
        if changed:
            kinds = {"station", *self.updates.changed_areas(self.view)}
            if any(entry.kind == "alarm" for entry in entries):  # a person's changes too
                kinds.add("alarm")
            self.updates.notify(kinds)

    @property
    def state(self) -> RunnerState:
        return self.cycle.state

    @property
    def runner(self) -> Runner:
        return self.cycle.runner

    def _take_requests(self) -> list[_Request]:
        taken = []
        while True:
            try:
                taken.append(self.requests.get_nowait())
            except queue.Empty:
                return taken

    # -- requests -------------------------------------------------------------------------------

    def _submit(self, kind: str, payload: Any, user: str) -> Future[Any]:
        if self.thread is None or not self.thread.is_alive():
            raise StationError("the station is not running")
        request = _Request(kind, payload, user)
        self.requests.put(request)
        return request.future

    def act(self, action: Action) -> Future[Acted]:
        """A person's action for the runner; answered with its reply and the round's events."""
        return self._submit("action", action, action.user)

    def confirm_card(self, user: str, card: str) -> Future[bool]:
        """The operator tapped "Done" on command card `card` (the watch's confirm)."""
        return self._submit("confirm", card, user)

    def inject(self, fault: Fault, text: str, user: str) -> Future[None]:
        if not isinstance(self.devices, FaultInjection):
            raise StationError("faults are injected on simulated or emulated devices only")
        return self._submit("fault", (fault, text), user)

    def play_experiment(self, scenario: Scenario, title: str, user: str) -> Future[None]:
        """Reset the simulated station to a scenario's start and arm its faults (demo only)."""
        self._require_simulated()
        return self._submit("experiment", (scenario, title), user)

    def acknowledge(self, key: str, user: str, note: str) -> Future[AlarmChange]:
        return self._submit("acknowledge", (key, note), user)

    def acknowledge_all(self, keys: list[str], user: str, note: str) -> Future[list[AlarmChange]]:
        """Acknowledge, in one round, those of the alarms a person was shown that still wait."""
        return self._submit("acknowledge_all", (keys, note), user)

    def shelve(self, key: str, user: str, minutes: float, note: str) -> Future[AlarmChange]:
        return self._submit("shelve", (key, minutes, note), user)

    def unshelve(self, key: str, user: str) -> Future[AlarmChange]:
        return self._submit("unshelve", key, user)

    def activate(self, prepared: Prepared, user: str) -> Future[None]:
        """Run another model version (`prepare` it first); refused unless the station is idle
        or in restart mode."""
        return self._submit("activate", prepared, user)

    @property
    def on_emulators(self) -> bool:
        """Experiments act on emulated devices through the station's drivers."""
        return self.simulated and isinstance(self.devices, StationDevices)

    def _require_simulated(self) -> None:
        if not self.simulated:
            raise StationError("faults are injected on simulated stations only")

    def _handle(self, request: _Request, now: float, entries: list[AuditEntry]) -> Any:
        user, payload = request.user, request.payload
        match request.kind:
            case "confirm":
                values = self.state.values
                watches = self.model.station.watches
                shown = [(p, w) for p, w in watches if values.get(w.card) == payload]
                if not shown:
                    now_shown = ", ".join(str(values.get(w.card)) for _, w in watches)
                    raise StationError(
                        f"card '{payload}' is no longer shown (now: {now_shown or 'none'})"
                    )
                person, watch = shown[0]
                done = self.devices.perform(watch.confirm)
                detail = {"card": str(payload)}
                entries.append(
                    AuditEntry(EventKind.OPERATOR, "card done", user, person.name, detail)
                )
                return done
            case "fault":
                fault, text = payload
                self.cycle.inject(fault)
                resource = fault.resource or self.runner.index.owner.get(fault.effect, "")
                entries.append(
                    AuditEntry(EventKind.FAULT, fault.kind, user, resource, {"fault": text})
                )
                return None
            case "experiment":
                self._start_experiment(payload[0], payload[1], now, user, entries)
                return None
            case "acknowledge":
                key, note = payload
                return self._alarm(
                    entries, lambda: self.book.acknowledge(key, user, note, self.wall())
                )
            case "acknowledge_all":
                keys, note = payload
                try:
                    acknowledged = self.book.acknowledge_all(keys, user, note, self.wall())
                except AlarmError as exc:
                    raise StationError(str(exc)) from None
                entries.extend(records.alarm_entry(change) for change in acknowledged)
                return acknowledged
            case "shelve":
                key, minutes, note = payload
                return self._alarm(
                    entries, lambda: self.book.shelve(key, user, minutes, note, self.wall())
                )
            case "unshelve":
                return self._alarm(entries, lambda: self.book.unshelve(payload, user, self.wall()))
            case "activate":
                self._activate(payload, now, user, entries)
                return None
        raise StationError(f"unknown request '{request.kind}'")

    @staticmethod
    def _alarm(entries: list[AuditEntry], change: Callable[[], AlarmChange]) -> AlarmChange:
        """A person's change to an alarm, audited in the round that makes it."""
        try:
            done = change()
        except AlarmError as exc:
            raise StationError(str(exc)) from None
        entries.append(records.alarm_entry(done))
        return done

    def _run_over(self, busy: set[str]) -> str:
        """Why the run ended this round ("" if it did not): the intentions it was busy with
        finished or were cancelled, and none is executing or in error now."""
        if self.state.busy_intentions():
            return ""
        words = self.model.words
        finished = sorted(
            n for n in busy if self.state.intentions.get(n) == IntentionState.FINISHED
        )
        cancelled = sorted(n for n in busy if n not in finished)
        said = [f"{words.names(finished)} finished"] if finished else []
        said += [f"{words.names(cancelled)} stopped"] if cancelled else []
        return "; ".join(said)

    def _new_run(self, acting: list[_Request]) -> str:
        """Why this round began a new run on an idle station ("" if it did not): a person
        started an intention, and it left its initial or finished state (its precondition
        held)."""
        begun = self.state.busy_intentions()
        for request in acting:
            action = request.payload
            if isinstance(action, StartIntention) and action.name in begun:
                intention = self.model.words.intention(action.name)
                return f"{action.user} started {intention} on an idle station"
        return ""

    def busy(self) -> str:
        """Why a model cannot be swapped now ("" when it can)."""
        state = self.state
        if state.restart_mode:
            return ""
        executing = state.intentions_in(IntentionState.EXECUTING)
        executing += state.operations_in(OperationState.EXECUTING)
        if executing:
            return "the station is running " + ", ".join(sorted(executing)[:5])
        return ""

    def prepare(self, model: ActiveModel) -> Prepared:
        """What running `model` needs that takes time (its runner, a planning worker, a
        simulated world), made off the loop: the loop then only swaps (`activate`)."""
        world = None
        if isinstance(self.devices, SimulatedWorld):
            world = self.setup(model.station, {}, None)
        worker = self._worker(model)
        return Prepared(model, self._runner(model, self.config, worker), worker, world)

    def _activate(
        self, prepared: Prepared, now: float, user: str, entries: list[AuditEntry]
    ) -> None:
        why = self.busy()
        if why:
            prepared.discard()
            raise StationError(f"{why}; activate when it is idle or in restart mode")
        old, old_worker = self.model, self.worker
        self.model, self.worker = prepared.model, prepared.worker
        if old_worker is not None:  # its process may take a while to end: not in the loop
            threading.Thread(target=old_worker.close, name="old-planning-worker").start()
        runner = prepared.runner
        state = carry_over(self.state, runner, now)
        if isinstance(self.devices, SimulatedWorld) and prepared.world is not None:
            # the simulated world goes on in the new model, keeping what it measured
            variables = prepared.model.station.model.variable_index
            world = {n: v for n, v in self.devices.values.items() if n in variables}
            self.devices.close()
            self.devices = prepared.world
            if isinstance(self.devices, Restorable):
                self.devices.load({"values": {**state.values, **world}}, now)
        self.cycle = StationCycle(runner, self.devices, state)
        records.set_active_version(self.store, self.name, prepared.model.version_id)
        detail = {"version": prepared.model.number, "previous": old.number}
        entries.append(AuditEntry(AuditKind.MODEL, "activated", user, "", detail))

    def _start_experiment(
        self, scenario: Scenario, title: str, now: float, user: str, entries: list[AuditEntry]
    ) -> None:
        config = replace(scenario.config, auto_intentions=frozenset())
        runner = self._runner(self.model, config)
        state = runner.initial(now, scenario.start)
        if isinstance(self.devices, StationDevices):  # emulated: put back, keep the drivers
            self.devices.restart(state.values)
        else:
            self.devices.close()
            self.devices = self.setup(self.model.station, state.values, scenario)
        faults = [replace(f, at=None if f.at is None else now + f.at) for f in scenario.faults]
        self.cycle = StationCycle(runner, self.devices, state, faults)
        self.experiment = title
        self.run_ended = f"{user} played the experiment {title}"
        entries.append(AuditEntry(AuditKind.EXPERIMENT, title, user, "", {"file": scenario.file}))
        for name in scenario.intentions or ():
            self.requests.put(_Request("action", StartIntention(user=user, name=name), user))

    # -- store ----------------------------------------------------------------------------------

    def resource_of(self, event: Event) -> str:
        """The resource an event concerns, for the auditor's filter ("" if none or several)."""
        return records.resource_of(self.runner, event)

    def _audit_now(self, entries: list[AuditEntry]) -> None:
        try:
            records.audit_committed(self.store, self.name, entries, self.wall())
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
            armed_faults=tuple(f.text for f in self.cycle.faults),
            experiment=self.experiment,
            devices=self._device_links(),
        )

    def _links_signature(self) -> tuple[tuple[str, bool, str], ...]:
        """What of the devices' links changes the view: connected or not, and why."""
        return tuple((n, s.connected, s.error) for n, s in sorted(self.devices.links().items()))

    def _device_links(self) -> tuple[DeviceLink, ...]:
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
            for name, link in sorted(self.devices.links().items())
        )

    def watch_area(self, name: str, shows: Callable[[StationView], object]) -> None:
        """Announce SSE event `name` only when `shows(view)` changes."""
        self.updates.watch(name, shows, self.view)

    def subscribe(self) -> asyncio.Queue[str]:
        """A queue that receives the names of what changed ("station", "alarm", areas)."""
        return self.updates.subscribe()

    def unsubscribe(self, changes: asyncio.Queue[str]) -> None:
        self.updates.unsubscribe(changes)


def _percentile(ordered: list[float], share: float) -> float:
    """The nearest-rank percentile of sorted values (0 when there are none)."""
    if not ordered:
        return 0.0
    return ordered[max(0, math.ceil(share * len(ordered)) - 1)]


def _ms(seconds: float) -> float:
    return round(seconds * 1000.0, 2)
