"""The live station: one station process's runner loop, its devices and its store.

`LiveStation` is what the pages, the API and `sp serve` talk to.  One thread, the station
loop (`app.station.loop`), owns the station as it runs (`app.station.running`: the cycle of
runner and devices, the alarm book, the run tracker) and steps it every `period` seconds,
so that the runner stays the only place live state changes (STYLE.md).  Everything else
reaches it through typed requests (`app.station.requests`) that the loop takes between
rounds; a round is: take the requests and apply each, tick once with all the people's
actions, then the steps after the tick (`app.station.rounds`: runs, records, alarms, one
commit, the view, the answers, the pages told).  What a person was told has happened is on
disk; pages read the `StationView` the last round made, never the live state.
"""

from __future__ import annotations

import asyncio
import logging
import queue
import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

from app.history.durations import Durations
from app.history.run_history import happenings
from app.station import activation, records
from app.station.alarms import AlarmBook, AlarmChange
from app.station.cycle import StationCycle
from app.station.loop import StationLoop
from app.station.page_updates import PageUpdates
from app.station.requests import (
    Acknowledge,
    AcknowledgeAll,
    Act,
    Acted,
    Activate,
    ConfirmCard,
    InjectFault,
    PlayExperiment,
    PutDevicesBack,
    ReportTampering,
    Request,
    Shelve,
    StationError,
    Unshelve,
)
from app.station.rounds import Commit, Round, Show, after_tick
from app.station.running import DeviceSetup, PlanningSetup, Running, runner_for, simulated_devices
from app.station.runs import RunTracker
from app.station.scenario import Scenario
from app.station.view import ActiveModel, StationView
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from hw.devices import DeviceKind, Devices
from hw.faults import Fault
from planner.runner import Action, EventKind, Runner, RunnerConfig, RunnerState, snapshot

log = logging.getLogger(__name__)
LEARNED_FROM = 5000  # the newest operation records the durations are learned from at start

__all__ = ["Acted", "LiveStation", "StationError"]


@dataclass
class _Pending:
    request: Request
    future: Future[Any]


class LiveStation:
    """The runner loop of one station (see the module docstring)."""

    def __init__(
        self,
        store: Store,
        name: str,
        model: ActiveModel,
        *,
        config: RunnerConfig | None = None,
        period: float = 0.1,
        clock: Callable[[], float] = time.monotonic,
        wall: Callable[[], float] = time.time,
        planning: PlanningSetup | None = None,
        devices: DeviceSetup = simulated_devices,
    ) -> None:
        self.store, self.name, self.wall = store, name, wall
        self.loop = StationLoop(name, self.round, self._round_failed, period=period, clock=clock)
        self.requests: queue.Queue[_Pending] = queue.Queue()
        self.running = _restored(
            store,
            name,
            model,
            config or RunnerConfig(auto_intentions=frozenset()),
            planning or PlanningSetup(),
            devices,
            self.now(),
        )
        # the simulation panel acts on all but real devices (tests may switch it off)
        self.simulated = self.running.devices.kind.can_fail_on_demand
        self.emulated = self.running.devices.kind is DeviceKind.EMULATED
        self.commit = Commit(store, name)
        self.show = Show(self.running, lambda: self.simulated, self.now())
        self.after_tick = after_tick(self.commit, self.show)

    def now(self) -> float:
        return self.loop.now()

    def start(self) -> None:
        self.loop.start()

    def stop(self) -> None:
        self.loop.stop()
        if self.running.worker is not None:
            self.running.worker.close()
        self.running.devices.close()

    def loop_summary(self, since: float | None = None) -> dict[str, float | int]:
        """How well the loop keeps its period (`StationLoop.summary`)."""
        return self.loop.summary(since)

    def round(self) -> None:
        """One round: take and apply the requests, tick once, then the steps after the tick."""
        running = self.running
        round_ = Round(self.now(), self.wall())
        round_.actions += running.next_actions
        running.next_actions = []
        for pending in self._take_requests():
            self._apply(pending, round_)
        try:
            round_.result = running.cycle.step(round_.now, round_.actions)
            for step in self.after_tick:
                step(running, round_)
        except Exception as exc:  # nobody waits 30 s for an answer that will not come
            failed = StationError(f"the station could not do that: {exc}")
            for future, _ in round_.answers:
                if not future.done():
                    future.set_exception(failed)
            raise

    def _apply(self, pending: _Pending, round_: Round) -> None:
        try:
            round_.answers.append((pending.future, pending.request.apply(self.running, round_)))
        except StationError as exc:
            pending.future.set_exception(exc)
        except Exception as exc:  # a fault of ours: said, and the person told at once
            log.exception("a %s request failed", type(pending.request).__name__)
            pending.future.set_exception(StationError(f"the station could not do that: {exc}"))

    def _take_requests(self) -> list[_Pending]:
        taken = []
        while True:
            try:
                taken.append(self.requests.get_nowait())
            except queue.Empty:
                return taken

    def _round_failed(self) -> None:
        """A round raised: said in the audit log, in a transaction of its own."""
        entry = AuditEntry(AuditKind.ERROR, "station round failed")
        try:
            records.audit_committed(self.store, self.name, [entry], self.wall())
        except Exception:
            log.exception("could not write the audit log")

    def submit(self, request: Request) -> Future[Any]:
        """Hand `request` to the loop; the future is answered once its round has committed."""
        if not self.loop.running:
            raise StationError("the station is not running")
        future: Future[Any] = Future()
        self.requests.put(_Pending(request, future))
        return future

    def act(self, action: Action) -> Future[Acted]:
        """A person's action for the runner; answered with its reply and the round's events."""
        return self.submit(Act(action))

    def confirm_card(self, user: str, card: str) -> Future[bool]:
        """The operator tapped "Done" on command card `card` (the watch's confirm)."""
        return self.submit(ConfirmCard(user, card))

    def inject(self, fault: Fault, text: str, user: str) -> Future[None]:
        self._require_simulated("faults are injected")
        return self.submit(InjectFault(user, fault, text))

    def play_experiment(
        self, scenario: Scenario, title: str, user: str, hands_free: bool = False
    ) -> Future[None]:
        """Put the station back to a scenario's start and arm its faults (not on real
        devices); `hands_free`: the station plays the scenario's operator too."""
        self._require_simulated("experiments are played")
        return self.submit(PlayExperiment(user, scenario, title, hands_free))

    def put_devices_back(self, user: str) -> Future[list[str]]:
        """The emulated devices out of the faults an experiment left (not on real devices,
        nor on a simulated world, which an experiment puts back whole)."""
        if not self.on_emulators:
            raise StationError("only emulated devices can be put back")
        return self.submit(PutDevicesBack(user))

    def acknowledge(self, key: str, user: str, note: str) -> Future[AlarmChange]:
        return self.submit(Acknowledge(user, key, note))

    def acknowledge_all(self, keys: list[str], user: str, note: str) -> Future[list[AlarmChange]]:
        """Acknowledge, in one round, those of the alarms a person was shown that still wait."""
        return self.submit(AcknowledgeAll(user, tuple(keys), note))

    def shelve(self, key: str, user: str, minutes: float, note: str) -> Future[AlarmChange]:
        return self.submit(Shelve(user, key, minutes, note))

    def unshelve(self, key: str, user: str) -> Future[AlarmChange]:
        return self.submit(Unshelve(user, key))

    def report_tampering(self, rows: str, what: str, user: str = "") -> Future[None]:
        """A high alarm from the next round on: a row of the store was changed outside the
        station (`rows` names it, one alarm each)."""
        return self.submit(ReportTampering(rows, what, user))

    def prepare(self, model: ActiveModel) -> activation.Prepared:
        """What running `model` needs that takes time, made on the caller's thread."""
        return activation.prepare(self.running, model)

    def activate(self, prepared: activation.Prepared, user: str) -> Future[None]:
        """Run another model version (`prepare` it first); refused unless the station is idle
        or in restart mode."""
        return self.submit(Activate(user, prepared))

    def busy(self) -> str:
        """Why a model cannot be swapped now ("" when it can)."""
        return activation.busy(self.view.state)

    def _require_simulated(self, what: str) -> None:
        if not self.simulated:
            raise StationError(f"{what} on simulated or emulated devices only")

    @property
    def view(self) -> StationView:
        """The view the last round that changed something made (never changed in place)."""
        return self.show.view

    @property
    def model(self) -> ActiveModel:
        return self.running.model

    @property
    def runner(self) -> Runner:
        return self.running.runner

    @property
    def book(self) -> AlarmBook:
        """The loop's alarm book (pages read `view.alarms`; tests may look here)."""
        return self.running.book

    @property
    def on_emulators(self) -> bool:
        """Experiments act on emulated devices through the station's drivers."""
        return self.simulated and self.running.devices.kind is DeviceKind.EMULATED

    @property
    def updates(self) -> PageUpdates[StationView]:
        return self.show.updates

    def watch_area(self, name: str, shows: Callable[[StationView], object]) -> None:
        """Announce SSE event `name` only when `shows(view)` changes."""
        self.show.updates.watch(name, shows, self.view)

    def subscribe(self) -> asyncio.Queue[str]:
        """A queue that receives the names of what changed ("station", "alarm", areas)."""
        return self.show.updates.subscribe()

    def unsubscribe(self, changes: asyncio.Queue[str]) -> None:
        self.show.updates.unsubscribe(changes)


def _restored(
    store: Store,
    name: str,
    model: ActiveModel,
    config: RunnerConfig,
    planning: PlanningSetup,
    setup: DeviceSetup,
    now: float,
) -> Running:
    """The station as it was at its last committed round, or new at its initial state."""
    saved = records.restore(store, name)
    worker = planning.worker(model)
    durations = Durations()
    durations.learn(happenings(store, name, LEARNED_FROM, frozenset({EventKind.OPERATION})))
    durations.forget_starts()
    runner = runner_for(model, config, worker, durations.medians())
    state: RunnerState
    if saved.snapshot is None:
        state = runner.initial(now)
        devices: Devices = setup(model.station, state.values)
    else:
        state = snapshot.load(runner, saved.snapshot, now, strict=False)
        devices = setup(model.station, state.values)
        if saved.world is not None:
            devices.restore(saved.world, now)
    cycle = StationCycle(runner, devices, state)
    runs = RunTracker(model.words, state)
    return Running(model, config, planning, worker, cycle, saved.alarms, runs, durations)
