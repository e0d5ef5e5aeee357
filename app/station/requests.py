"""What people ask of the station, one frozen dataclass per request, each applied by its own
`apply` in the station loop.

The pages and the API hand a request to `LiveStation.submit`; the loop takes the requests
between rounds and applies each, in the order they came, in the round that takes it:
a person's action goes into that round's one tick, a tap on a card to the devices, an
alarm's acknowledgement into the alarm book, an experiment or a model version replaces
the station cycle.  `apply` gives back how the request is answered once its round has
committed (an `Answer`: the runner's reply for an action, the alarm's change for an
acknowledgement).  A request the station cannot carry out now raises `StationError`, which
the person sees as a 4xx with its words.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, TypeVar

from app.station import activation, experiments
from app.station.alarms import AlarmBook, AlarmChange, AlarmError, Condition, Priority
from app.station.cycle import CycleResult
from app.station.rounds import Answer, Round
from app.station.running import Running
from app.station.scenario import Scenario
from app.store.audit import AuditEntry, AuditKind
from hw.devices import DeviceKind
from hw.faults import Fault
from planner.runner import Action, Event, EventKind, Reply
from planner.runner.vocabulary import PersonAct

T = TypeVar("T")


class StationError(Exception):
    """A request the station cannot carry out now; the message says why (shown as a 4xx)."""


@dataclass(frozen=True)
class Acted:
    """The answer to a person's action: the runner's reply and the events of its round."""

    reply: Reply
    events: tuple[Event, ...]


class Request(Protocol):
    """A person's request to the station loop (module docstring)."""

    @property
    def user(self) -> str: ...

    def apply(self, running: Running, round_: Round) -> Answer: ...


def settled(value: T) -> Answer:
    """The answer of a request that is done when it is applied."""
    return lambda _result: value


@dataclass(frozen=True)
class Act:
    """A person's action for the runner (start, cancel, approve, reject, a maintenance step
    done, restart mode, an estimate, a reset): it goes into this round's tick, and the
    runner's reply answers it."""

    action: Action

    @property
    def user(self) -> str:
        return self.action.user

    def apply(self, running: Running, round_: Round) -> Answer:
        place = round_.act(self.action)

        def acted(result: CycleResult) -> Acted:
            return Acted(result.replies[place], result.events)

        return acted


@dataclass(frozen=True)
class ConfirmCard:
    """The operator tapped Done on command card `card`: the tap goes to the devices (the
    watch is a device, seed 001), and the runner sees its effect in this round's reading.
    Answered True when the watch took it, False when it did not: the card was confirmed
    already, by another device's tap in this round or before the reading showed it.  Either
    is answered once the round has committed, when the view no longer shows a card that was
    taken, and only a tap the watch took is recorded."""

    user: str
    card: str

    def apply(self, running: Running, round_: Round) -> Answer:
        values = running.state.values
        watches = running.model.station.watches
        shown = [(p, w) for p, w in watches if values.get(w.card) == self.card]
        if not shown:
            now_shown = ", ".join(str(values.get(w.card)) for _, w in watches)
            raise StationError(
                f"card '{self.card}' is no longer shown (now: {now_shown or 'none'})"
            )
        person, watch = shown[0]
        done = running.devices.perform(watch.confirm)
        if done:
            detail = {"card": str(self.card)}
            round_.record(
                AuditEntry(EventKind.OPERATOR, PersonAct.CARD_DONE, self.user, person.name, detail)
            )
        return settled(done)


@dataclass(frozen=True)
class InjectFault:
    """A fault from the simulation panel, on simulated or emulated devices; `text` is how
    the panel wrote it, for the record."""

    user: str
    fault: Fault
    text: str

    def apply(self, running: Running, round_: Round) -> Answer:
        running.cycle.inject(self.fault)
        fault = self.fault
        resource = fault.resource or running.model.station.owner_of(fault.effect)
        detail = {"fault": self.text}
        round_.record(AuditEntry(EventKind.FAULT, fault.kind, self.user, resource, detail))
        return settled(None)


@dataclass(frozen=True)
class PlayExperiment:
    """Put the station back to a scenario's start, arm its faults and start its intentions
    (the simulation panel's experiments, `app.station.experiments`); `hands_free`: the
    station plays the scenario's operator too."""

    user: str
    scenario: Scenario
    title: str
    hands_free: bool = False

    def apply(self, running: Running, round_: Round) -> Answer:
        experiments.play(running, round_, self.scenario, self.title, self.user, self.hands_free)
        return settled(None)


@dataclass(frozen=True)
class PutDevicesBack:
    """The emulated devices out of the faults an experiment left (`EmulatedWorld.put_back`),
    audited with the user; refused on anything but emulated devices."""

    user: str

    def apply(self, running: Running, round_: Round) -> Answer:
        put_back = getattr(running.devices, "put_back", None)
        if running.devices.kind is not DeviceKind.EMULATED or put_back is None:
            raise StationError("only emulated devices can be put back")
        names: list[str] = put_back()
        detail = {"devices": ", ".join(names)}
        round_.record(AuditEntry(AuditKind.EXPERIMENT, "devices put back", self.user, "", detail))
        return settled(names)


@dataclass(frozen=True)
class Activate:
    """Run another model version, made ready beside the loop (`activation.prepare`);
    refused unless the station is idle or in restart mode."""

    user: str
    prepared: activation.Prepared

    def apply(self, running: Running, round_: Round) -> Answer:
        why = activation.busy(running.state)
        if why:
            self.prepared.discard(running.devices)
            raise StationError(f"{why}; activate when it is idle or in restart mode")
        activation.activate(running, round_, self.prepared, self.user)
        return settled(None)


@dataclass(frozen=True)
class Acknowledge:
    user: str
    key: str
    note: str

    def apply(self, running: Running, round_: Round) -> Answer:
        wall = round_.wall
        return _alarm(
            running, round_, lambda b: b.acknowledge(self.key, self.user, self.note, wall)
        )


@dataclass(frozen=True)
class AcknowledgeAll:
    """Acknowledge, with one note, those of the alarms a person was shown that still wait."""

    user: str
    keys: tuple[str, ...]
    note: str

    def apply(self, running: Running, round_: Round) -> Answer:
        try:
            changes = running.book.acknowledge_all(self.keys, self.user, self.note, round_.wall)
        except AlarmError as exc:
            raise StationError(str(exc)) from None
        for change in changes:
            round_.alarm_changed(change)
        return settled(changes)


@dataclass(frozen=True)
class Shelve:
    user: str
    key: str
    minutes: float
    note: str

    def apply(self, running: Running, round_: Round) -> Answer:
        wall = round_.wall
        return _alarm(
            running, round_, lambda b: b.shelve(self.key, self.user, self.minutes, self.note, wall)
        )


@dataclass(frozen=True)
class Unshelve:
    user: str
    key: str

    def apply(self, running: Running, round_: Round) -> Answer:
        wall = round_.wall
        return _alarm(running, round_, lambda b: b.unshelve(self.key, self.user, wall))


def _alarm(running: Running, round_: Round, change: Callable[[AlarmBook], AlarmChange]) -> Answer:
    """A person's change to an alarm, audited in the round that makes it."""
    try:
        done = change(running.book)
    except AlarmError as exc:
        raise StationError(str(exc)) from None
    round_.alarm_changed(done)
    return settled(done)


@dataclass(frozen=True)
class ReportTampering:
    """A check of the station's own found a row of its store changed outside it (a model
    version about to be activated, rows at start): a high alarm from this round on."""

    rows: str  # which rows, for the alarm's key: one alarm per thing found
    what: str  # in plain words: which rows, and what the station refused
    user: str = ""

    def apply(self, running: Running, round_: Round) -> Answer:
        key = f"store:{self.rows}"
        running.notices[key] = Condition(key, Priority.HIGH, self.what)
        return settled(None)
