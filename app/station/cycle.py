"""One station cycle: devices, runner, devices again, the same for `sp run` and the web.

Every round of a station, headless (`app.station.player.play`) or live (`app.station.live`), is
one `StationCycle.step`:

    1. armed faults whose time or condition has come are injected (simulated devices)
    2. a stand-in for the people, if the play has one (`app.station.stand_in`), taps the
       watches' cards that waited their delay
    3. the devices act on the last commands up to now, and report
    4. the runner ticks on the report and people's actions (a scenario's, the stand-in's,
       then the round's), in their order; the stand-in hears the tick's events
    5. maintenance steps the runner accepted are done in the world too
    6. the runner's command values go to the devices

so that what the experiments E1-E9 test is the path the web station runs.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace

from app.station.stand_in import StandIn
from hw.devices import Devices, ModelSimulation
from hw.faults import Fault
from planner.model.expressions import Expr, Value
from planner.model.flat import VariableKind
from planner.runner import (
    Action,
    Event,
    EventKind,
    Inputs,
    MaintenanceDone,
    Reply,
    Runner,
    RunnerState,
)
from planner.runner.vocabulary import PersonAct


@dataclass(frozen=True)
class ScheduledFault:
    """A fault armed to happen `at` a time or `when` a condition first holds (and `after`
    seconds more: a network that comes back a few seconds after it went)."""

    fault: Fault
    at: float | None = None
    when: Expr | None = None
    text: str = ""
    after: float = 0.0


@dataclass(frozen=True)
class ScheduledAction:
    """A person's action planned `at` a time or `when` a condition first holds (and
    `after` seconds more: a person answers what they see a moment later)."""

    action: Action
    at: float | None = None
    when: Expr | None = None
    after: float = 0.0


def due(
    scheduled: ScheduledFault | ScheduledAction,
    now: float,
    runner: Runner,
    values: Mapping[str, Value],
) -> bool:
    """Its time has come, or its condition holds now."""
    if scheduled.at is not None and now >= scheduled.at:
        return True
    return scheduled.when is not None and runner.holds(scheduled.when, values)


@dataclass(frozen=True)
class CycleResult:
    """A round's events (faults first, then the tick's) and the replies to its actions."""

    events: tuple[Event, ...]
    replies: tuple[Reply, ...] = ()


@dataclass
class StationCycle:
    """A runner, its devices and its state, stepped one round at a time."""

    runner: Runner
    devices: Devices
    state: RunnerState
    faults: list[ScheduledFault] = field(default_factory=list)
    # a scenario's people: what they do at a time or on a condition (`Scenario.actions`)
    people: list[ScheduledAction] = field(default_factory=list)
    stand_in: StandIn | None = None  # answers for the people in a play (None: they do)

    def __post_init__(self) -> None:
        self.publish()

    def step(self, now: float, actions: Iterable[Action] = ()) -> CycleResult:
        events = self.fire_faults(now)
        stand_in = self.stand_in
        if stand_in is not None:
            for effect, card in stand_in.cards_to_tap(now, self.state.values):
                if self.devices.perform(effect):  # recorded as a person's tap would be
                    detail = {"user": stand_in.user, "card": str(card), "transition": effect}
                    events.append(Event(now, EventKind.OPERATOR, PersonAct.CARD_DONE, detail))
            actions = (*stand_in.due(now), *actions)
        actions = (*self.people_due(now), *actions)
        self.devices.advance(now)
        report = self.devices.read()
        inputs = Inputs(
            report.measured,
            report.observed,
            report.heartbeats,
            tuple(actions),
            cannot_act=report.cannot_act,
            silent=report.silent,
            stale=report.stale,
        )
        result = self.runner.tick(self.state, inputs, now)
        self.state = result.state
        for reply in result.replies:
            if reply.accepted and isinstance(reply.action, MaintenanceDone):
                self.devices.maintenance_done(reply.action.transition)
        self.publish()
        if stand_in is not None:
            for event in result.events:
                stand_in.answer(event, now)
        return CycleResult((*events, *result.events), result.replies)

    def fire_faults(self, now: float) -> list[Event]:
        fired = []
        for scheduled in [f for f in self.faults if due(f, now, self.runner, self.state.values)]:
            self.faults.remove(scheduled)
            if scheduled.after > 0:  # its condition held: it happens `after` seconds later
                self.faults.append(replace(scheduled, at=now + scheduled.after, when=None, after=0))
                continue
            self.inject(scheduled.fault)
            detail = {"fault": scheduled.text}
            fired.append(Event(now, EventKind.FAULT, scheduled.fault.kind.value, detail))
        return fired

    def people_due(self, now: float) -> list[Action]:
        """The scheduled actions whose time has come, in their order."""
        taken = []
        for scheduled in [a for a in self.people if due(a, now, self.runner, self.state.values)]:
            self.people.remove(scheduled)
            if scheduled.after > 0:  # its condition held: done `after` seconds later
                self.people.append(replace(scheduled, at=now + scheduled.after, when=None, after=0))
                continue
            taken.append(scheduled.action)
        return taken

    def inject(self, fault: Fault) -> None:
        """`fault` in the devices now (ValueError on real devices)."""
        self.devices.inject(fault)

    def publish(self) -> None:
        """The runner's commands to the devices (and its estimates to a simulation)."""
        self.devices.write(self.runner.commands(self.state))
        if isinstance(self.devices, ModelSimulation):
            kinds = self.runner.index.variable_kind
            estimates = {
                name: value
                for name, value in self.state.values.items()
                if kinds[name] in (VariableKind.ESTIMATED, VariableKind.DECISION)
            }
            self.devices.follow_estimates(estimates)
