"""Who answers the runner's planning queries, and when.

`InProcess` asks the planners at once, inside the tick: deterministic, what `sp run` and the
tests replay.  A station that must never stand still hands its queries to a worker instead
(`app.station.planning_worker`): `answer` returns None until the answer is ready, `ask` raises
`Pending`, and `run_tick` undoes the phase that asked (its state and events) so the tick
goes on with the other phases and the phase is tried again next tick.  A phase retried in
the same state asks the same queries, whose answers the worker keeps; a phase retried in a
state that has moved on asks new ones, and the old answers are never used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from planner.planning.operation_planner import OperationPlanner
from planner.planning.query import PlanQuery, PlanResult, PlanStatus
from planner.planning.transition_planner import TransitionPlanner
from planner.runner.vocabulary import PlanLevel


class Pending(Exception):
    """A planning query is not answered yet (its purpose is the message)."""


@dataclass(frozen=True)
class Answer:
    result: PlanResult
    millis: float | None  # planning time, None without a stopwatch


class QueryAnswerer(Protocol):
    """Who answers the runner's planning queries: `InProcess`, `Delayed`, or a station's
    planning worker (`app.station.planning_worker`)."""

    @property
    def asynchronous(self) -> bool:
        """Answers may come later than the tick that asks."""

    def answer(self, level: PlanLevel, query: PlanQuery) -> Answer | None:
        """The answer to `query` (None: not yet; ask again next tick)."""


class QueryObserver(Protocol):
    """Sees every planning query of a runner (benchmarks time them all, announced or not)."""

    def asked(self, now: float, level: PlanLevel, purpose: str) -> None: ...

    def answered(self, result: PlanResult, millis: float | None) -> None: ...

    def announced(self) -> None: ...


class InProcess:
    """The planners of this process, asked at once."""

    asynchronous = False

    def __init__(
        self,
        transition_planner: TransitionPlanner,
        operation_planner: OperationPlanner,
        stopwatch: Callable[[], float] | None = None,
    ) -> None:
        self.planners = {
            PlanLevel.TRANSITIONS: transition_planner.plan,
            PlanLevel.OPERATIONS: operation_planner.plan,
        }
        self.stopwatch = stopwatch

    def answer(self, level: PlanLevel, query: PlanQuery) -> Answer:
        plan = self.planners[level]
        watch = self.stopwatch
        if watch is None:
            return Answer(plan(query), None)
        started = watch()
        result = plan(query)
        return Answer(result, (watch() - started) * 1000)


class Delayed:
    """Answers as a planner that needs `delay` seconds per query would, on the caller's
    `clock`: the scenario player's deterministic stand-in for a slow planning worker.  A
    query whose delay is past `budget` is answered `over_budget` once the budget is used up,
    as the worker does.  Answers are kept, so a phase retried in the same state gets them."""

    asynchronous = True

    def __init__(
        self, planning: QueryAnswerer, delay: float, budget: float, clock: Callable[[], float]
    ) -> None:
        self.planning, self.delay, self.budget, self.clock = planning, delay, budget, clock
        self.asked: dict[tuple[PlanLevel, PlanQuery], float] = {}

    def answer(self, level: PlanLevel, query: PlanQuery) -> Answer | None:
        waited = self.clock() - self.asked.setdefault((level, query), self.clock())
        if waited < min(self.delay, self.budget):
            return None
        if self.delay > self.budget:
            over = PlanResult(PlanStatus.OVER_BUDGET, max_steps=query.max_steps, engine="delayed")
            return Answer(over, self.budget * 1000)
        return self.planning.answer(level, query)  # with the planner's own time
