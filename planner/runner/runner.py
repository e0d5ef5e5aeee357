"""The runner: the one place live state changes (DESIGN.md section 4, seed 000 sec. 4).

A deterministic state machine with an injected clock: `tick(state, inputs, now)` returns the
next state, the command values to publish, the events of the tick and a reply to each
person's action.  `run_tick` is the order of a tick, written once; each phase is a module
of this package, named after what it does.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from planner.model.expressions import Expr, Value
from planner.model.flat import VariableKind
from planner.model.semantics import Semantics, State
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.runner import (
    automatic,
    background,
    effects,
    forbidden,
    intentions,
    maintenance,
    observing,
    operations,
    people,
    restart,
    transitions,
)
from planner.runner.actions import Reply
from planner.runner.answers import InProcess, Pending, QueryAnswerer, QueryObserver
from planner.runner.state import RunnerState
from planner.runner.station_index import StationIndex
from planner.runner.tick import Tick
from planner.runner.tick_io import Inputs, RunnerConfig, TickResult
from planner.runner.vocabulary import IntentionState, OperationState

Stopwatch = Callable[[], float]

_BAD_CACHE = 4096  # states whose badness is remembered (plans are checked every tick)


def run_tick(tick: Tick, inputs: Inputs) -> list[Reply]:
    """One tick in the order of DESIGN.md section 4; the replies to people's actions."""
    observing.take_inputs(tick, inputs)  # 1. measurements, observed products, heartbeats
    replies = [people.act(tick, action) for action in inputs.actions]
    automatic.settle(tick)  # 2. automatic transitions to a fixpoint
    if forbidden.in_forbidden_state(tick):
        forbidden.announce_violation(tick)
        attempt(tick, forbidden.recover)  # 3. forbidden-state recovery, nothing else
    else:
        tick.state.announced = ()
        intentions.start_and_finish(tick)  # 4.
        attempt(tick, operations.follow_operation_plan)  # 5. the operation planner
        if tick.state.restart_mode:
            attempt(tick, restart.follow_reset_plan)  # 6. in restart mode: the resets
        else:
            attempt(tick, transitions.follow_transition_plan)  # 6. the transition planner
        attempt(tick, maintenance.follow_maintenance_plan)  # after errors: people's steps
    effects.monitor_effects(tick)  # 7. effect time-outs
    if background.due(tick):
        attempt(tick, background.background_check)  # errors that can be completed again
    return replies


def attempt(tick: Tick, phase: Callable[[Tick], None]) -> None:
    """Run a phase that may plan.  With answers that come later, a phase whose query is not
    answered yet is undone (state and events) and tried again next tick (`answers`)."""
    if not tick.runner.planning.asynchronous:
        phase(tick)
        return
    saved, mark = tick.state.copy(), len(tick.events)
    try:
        phase(tick)
    except Pending:
        tick.state = saved
        del tick.events[mark:]


class Runner:
    """Runs one station model; built once, ticked forever."""

    def __init__(
        self,
        station: Station,
        transition_planner: TransitionPlanner,
        operation_planner: OperationPlanner,
        config: RunnerConfig | None = None,
        stopwatch: Stopwatch | None = None,
        observer: QueryObserver | None = None,
        planning: QueryAnswerer | None = None,
    ) -> None:
        self.station = station
        self.model = station.model
        self.config = config or RunnerConfig()
        self.transition_planner = transition_planner
        self.operation_planner = operation_planner
        self.semantics = Semantics(self.model)
        self.index = StationIndex(station, self.semantics)
        self.stopwatch = stopwatch
        self.observer = observer
        self.planning: QueryAnswerer = planning or InProcess(
            transition_planner, operation_planner, stopwatch
        )
        self._bad: dict[State, bool] = {}
        # what the station has learned: seconds per operation, the median of its last runs
        # (`app.history.durations`); the app keeps it up to date, planning reads it
        self.learned: Mapping[str, float] = {}

    def durations(self) -> dict[str, float]:
        """Seconds per operation for the operation planner: what was learned, else the
        model's estimate; none at all when nothing is known (the first plan found)."""
        estimates = {o.name: o.duration for o in self.station.operations if o.duration}
        return {**estimates, **self.learned}

    def initial(self, now: float = 0.0, values: Mapping[str, Value] | None = None) -> RunnerState:
        start = {v.name: v.initial for v in self.model.variables}
        start.update(values or {})
        chosen = self.config.auto_intentions
        auto_start = set(self.index.intentions) if chosen is None else set(chosen)
        return RunnerState(
            values=start,
            intentions=dict.fromkeys(self.index.intentions, IntentionState.INITIAL),
            operations=dict.fromkeys(self.index.operations, OperationState.INITIAL),
            last_heard={r.name: now for r in self.station.resources},
            auto_start=auto_start,
            next_background_check=now,
        )

    def tick(self, state: RunnerState, inputs: Inputs, now: float) -> TickResult:
        work = Tick(self, state.copy(), now)
        replies = run_tick(work, inputs)
        return TickResult(work.state, self.commands(work.state), tuple(work.events), tuple(replies))

    def commands(self, state: RunnerState) -> dict[str, Value]:
        """The command values of `state`: what the devices are told."""
        kinds = self.index.variable_kind
        return {n: v for n, v in state.values.items() if kinds[n] is VariableKind.COMMAND}

    def holds(self, expr: Expr, values: Mapping[str, Value]) -> bool:
        return self.index.holds(expr, values)

    def is_bad(self, state: State) -> bool:
        """Is `state` bad (section 8: a specification is violated, or uncontrollable steps
        alone can lead to a violation)?  Remembered for the states seen lately."""
        bad = self._bad.get(state)
        if bad is None:
            planner = self.transition_planner
            bad = planner.sym.contains(planner.bad, state)
            if len(self._bad) >= _BAD_CACHE:
                self._bad.clear()
            self._bad[state] = bad
        return bad
