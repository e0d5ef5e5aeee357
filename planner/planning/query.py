"""What a planning query asks and what a planner answers, shared by every engine."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from planner.model.expressions import Expr, Value

State = tuple[Value, ...]


class PlanStatus(Enum):
    FOUND = "found"
    UNREACHABLE = "unreachable"  # no plan of at most `max_steps` steps
    BAD_START = "bad_start"  # the start state is bad (or forbidden for this query)
    # the runner's query ran past its time budget: no plan within it (treated as unreachable)
    OVER_BUDGET = "over_budget"


@dataclass(frozen=True)
class PlanQuery:
    """Plan from `start` to a state where `goal` holds, with the fewest steps.

    `forbidden` are extra state predicates the plan must avoid, e.g. the goals of operations
    that are not executing (monotonic abstraction, seed 000 sec. 4.3); `always` must hold in
    every state before the goal is reached (an intention's `phi U goal`); `disabled`
    transitions are removed for this query (timed-out effects, unavailable resources).

    `kept` are predicates the plan keeps true whatever the world does: every state of the
    plan satisfies them, and none is one from which automatic and effect steps can make
    one false (the causal links of the operations that come next, `planner.runner.links`:
    a robot that leaves the camera's pose lets the camera forget by itself).

    `relaxed` names specifications dropped for forbidden-state recovery (seed 000 sec. 4.6):
    the plan may pass through states that violate them, but never through a state that is
    bad for any other specification (the supervisor of the others keeps holding while the
    operator puts things right; those the start is already bad for are dropped too), and
    ends in a good state (bad for none); `goal` is conjoined with that.

    With `maintenance_cost` c > 1 (and `maintenance`), a plan has the least cost instead of
    the fewest steps, a maintenance step costing c and every other step 1 (ties: the fewer
    maintenance steps): a person is not asked to move a robot by hand that can move itself
    in a few steps more.  The default 1 is section 8's minimal plan.

    `durations` (operation planning only): seconds per operation.  Among the plans of the
    minimal length the operation planner then prefers one of the least expected makespan
    in the partial order (`planner.planning.makespan`); without them it takes the first.
    """

    start: State
    goal: Expr
    max_steps: int = 100
    maintenance: bool = False
    forbidden: tuple[Expr, ...] = ()
    always: Expr | None = None
    disabled: frozenset[str] = frozenset()
    kept: tuple[Expr, ...] = ()
    relaxed: frozenset[str] = frozenset()
    maintenance_cost: int = 1
    durations: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class PlanResult:
    status: PlanStatus
    plan: tuple[str, ...] = ()
    states: tuple[State, ...] = ()  # the states visited, start and end included
    violated: tuple[str, ...] = ()  # for BAD_START: the specifications (or forbidden[i])
    max_steps: int = 0
    engine: str = ""
    statistics: dict[str, float] = field(default_factory=dict, compare=False)

    @property
    def found(self) -> bool:
        return self.status is PlanStatus.FOUND

    @property
    def length(self) -> int:
        return len(self.plan)
