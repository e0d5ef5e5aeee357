"""One tick's work: a private copy of the state, the clock reading and the events so far.

Every phase of the runner (`planner.runner.observing`, `.automatic`, `.forbidden`, ...) is
a set of functions of a `Tick`.  The tick is also the one place where an intention or an
operation changes state, so that every change is an event, follows its life cycle
(`planner.runner.vocabulary`) and keeps the first cause of an error.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol, TypeVar

from planner.model.expressions import Value
from planner.model.semantics import State
from planner.planning.operation_planner import OperationPlanner
from planner.runner.actions import Action, Reply
from planner.runner.answers import QueryAnswerer, QueryObserver
from planner.runner.state import RunnerState
from planner.runner.station_index import StationIndex
from planner.runner.tick_io import Event, RunnerConfig
from planner.runner.vocabulary import (
    INTENTION_LIFE_CYCLE,
    OPERATION_LIFE_CYCLE,
    EventKind,
    IntentionState,
    OperationState,
    ReplanReason,
)

_State = TypeVar("_State", IntentionState, OperationState)


class LifeCycleError(AssertionError):
    """A change of state its life cycle does not allow: a bug in the runner, never input."""


class TickRunner(Protocol):
    """What a phase may ask of the runner that ticks: its lookups and settings, whether a
    state is bad, the operation planner's queries, and who answers and watches them.
    `planner.runner.Runner` is one; the phases know it only through this."""

    @property
    def index(self) -> StationIndex: ...

    @property
    def config(self) -> RunnerConfig: ...

    @property
    def operation_planner(self) -> OperationPlanner: ...

    @property
    def planning(self) -> QueryAnswerer: ...

    @property
    def observer(self) -> QueryObserver | None: ...

    def is_bad(self, state: State) -> bool: ...

    def durations(self) -> dict[str, float]: ...


class Tick:
    """One tick's work on a private copy of the state."""

    def __init__(self, runner: TickRunner, state: RunnerState, now: float) -> None:
        self.runner = runner
        self.index: StationIndex = runner.index
        self.config = runner.config
        self.state = state
        self.now = now
        self.events: list[Event] = []
        self.availability_changed: set[str] = set()  # resources that came or went
        self.reenabled_by_people: set[str] = set()  # effects a person re-enabled
        # something that can clear an error happened (a resource answers again, an effect
        # is usable again, a person changed the world or the estimates): check now
        self.errors_may_clear = False

    def cause_gone(self) -> None:
        """What made operations fail is gone (a resource answers again, an effect is usable
        again): their failures are forgotten and what is in error is checked at once."""
        self.state.failures.clear()
        self.state.blamed_on_timeouts.clear()
        self.errors_may_clear = True

    def emit(
        self, kind: EventKind, subject: str, millis: float | None = None, **detail: object
    ) -> None:
        self.events.append(Event(self.now, kind, subject, detail, millis))

    def refuse(self, action: Action, subject: str, why: str) -> Reply:
        """Refuse a person's action: a `refused` event about `subject`, and the reply."""
        self.emit(EventKind.REFUSED, subject, user=action.user, why=why)
        return Reply.refuse(action, subject, why)

    def current(self) -> State:
        """The live values as a state of the model."""
        return self.index.as_state(self.state.values)

    def set_values(self, state: State) -> None:
        self.state.values = self.index.semantics.values(state)

    def replan_operations(self, reason: ReplanReason) -> None:
        """Make the operation plan again this tick (the first reason given is kept)."""
        if self.state.replan_operations is None:
            self.state.replan_operations = reason

    def replan_transitions(self, reason: ReplanReason) -> None:
        """Make the transition plan again this tick (the first reason given is kept)."""
        if self.state.replan_transitions is None:
            self.state.replan_transitions = reason

    def set_intention(self, name: str, new: IntentionState, why: str) -> None:
        state = self.state
        intentions, causes = state.intentions, state.intention_causes
        self._change(EventKind.INTENTION, INTENTION_LIFE_CYCLE, intentions, causes, name, new, why)
        self.replan_operations(ReplanReason.INTENTIONS)

    def set_operation(self, name: str, new: OperationState, why: str) -> None:
        state = self.state
        operations, causes = state.operations, state.operation_causes
        self._change(EventKind.OPERATION, OPERATION_LIFE_CYCLE, operations, causes, name, new, why)
        if new is not OperationState.ERROR:
            state.resumable.discard(name)

    def _change(
        self,
        kind: EventKind,
        life_cycle: Mapping[_State, frozenset[_State]],
        states: dict[str, _State],
        causes: dict[str, str],
        name: str,
        new: _State,
        why: str,
    ) -> None:
        """`name` goes to `new` if its life cycle allows it; the first cause of an error is
        kept until it leaves the error."""
        before = states[name]
        if new not in life_cycle[before]:
            raise LifeCycleError(f"{kind.value} {name}: {before.name} may not become {new.name}")
        states[name] = new
        if new in (IntentionState.ERROR, OperationState.ERROR):
            causes.setdefault(name, why)
        else:
            causes.pop(name, None)
        self.emit(kind, name, before=before, after=new, why=why)

    def value(self, name: str) -> Value:
        return self.state.values[name]
