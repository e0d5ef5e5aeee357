"""Who answers the runner's planning queries, and when.

`InProcess` asks the planners at once, inside the tick: deterministic, what `sp run` and the
tests replay.  A station that must never stand still hands its queries to a worker instead
(`app.planning_worker`): `answer` returns None until the answer is ready, `ask` raises
`Pending`, and `run_tick` undoes the phase that asked (its state and events) so the tick
goes on with the other phases and the phase is tried again next tick.  A phase retried in
the same state asks the same queries, whose answers the worker keeps; a phase retried in a
state that has moved on asks new ones, and the old answers are never used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from planner.operation_planner import OperationPlanner
from planner.planning import PlanQuery, PlanResult
from planner.runner.vocabulary import PlanLevel
from planner.transition_planner import TransitionPlanner


class Pending(Exception):
    """A planning query is not answered yet (its purpose is the message)."""


@dataclass(frozen=True)
class Answer:
    result: PlanResult
    millis: float | None  # planning time, None without a stopwatch


class Planning(Protocol):
    @property
    def asynchronous(self) -> bool:
        """Answers may come later than the tick that asks."""

    def answer(self, level: PlanLevel, query: PlanQuery) -> Answer | None:
        """The answer to `query` (None: not yet; ask again next tick)."""


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
