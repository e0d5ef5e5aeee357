"""Planning queries: what the runner asks its two planners, how it times and reports them.

Every query goes through `ask`, which times it on the runner's stopwatch and tells the
runner's `QueryObserver` (a benchmark's hook); `announce` turns an answer into a `plan`
event labelled as in seed 000 Table 1 ("TP w/RTO w/MT").
"""

from __future__ import annotations

from collections.abc import Iterable

from planner.model.expressions import Assign, Expr, conjunction, negation
from planner.model.station import effect_as_goal
from planner.planning.query import PlanQuery, PlanResult, PlanStatus
from planner.runner.answers import Pending
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind, PlanLevel, RecoveryFlag, ReplanReason, plan_label

# a maintenance step (a person's work, planned in recovery) weighs as much as this many of
# the station's own steps: a robot that can move itself is not moved by hand
MAINTENANCE_COST = 10


def ask(
    tick: Tick, level: PlanLevel, query: PlanQuery, purpose: str
) -> tuple[PlanResult, float | None]:
    """Ask the planner of `level`; the answer and its time in milliseconds (None without a
    stopwatch).  `purpose` names the question for observers ("which operations fail")."""
    runner = tick.runner
    observer = runner.observer
    if observer is not None:
        observer.asked(tick.now, level, purpose)
    answer = runner.planning.answer(level, query)
    if answer is None:
        raise Pending(purpose)
    if observer is not None:
        observer.answered(answer.result, answer.millis)
    return answer.result, answer.millis


def no_plan_because(result: PlanResult, usual: str) -> str:
    """Why a query found no plan, in words: `usual`, unless it ran past its planning
    budget (then nothing was proved about the goal, only that planning was too slow)."""
    if result.status is PlanStatus.OVER_BUDGET:
        return "no plan within the planning budget"
    return usual


def announce(
    tick: Tick,
    level: PlanLevel,
    flags: Iterable[RecoveryFlag],
    reason: ReplanReason,
    result: PlanResult,
    millis: float | None,
    **extra: object,
) -> None:
    """The `plan` event of a planning action."""
    flags = tuple(flags)
    detail: dict[str, object] = {
        "level": level,
        "flags": list(flags),
        "reason": reason,
        "status": result.status.value,
    }
    if result.status is PlanStatus.FOUND:
        detail["length"] = result.length
        detail["plan"] = list(result.plan)
    if result.violated:
        detail["violated"] = list(result.violated)
    detail.update(extra)
    if tick.runner.observer is not None:
        tick.runner.observer.announced()
    tick.emit(EventKind.PLAN, plan_label(level, flags), millis, **detail)


def disabled(tick: Tick) -> frozenset[str]:
    """Transitions planning may not use now: timed-out effects, the transitions of resources
    that stopped answering, and restart abilities outside restart mode."""
    state = tick.state
    out = set(state.timed_out)
    for resource in state.unavailable:
        out |= tick.index.resource_transitions.get(resource, frozenset())
    if not state.restart_mode:
        out |= tick.index.station.restart_transitions
    return frozenset(out)


def recovery_flags(tick: Tick, *, maintenance: bool = False) -> tuple[RecoveryFlag, ...]:
    """What a transition planning query leaves out or adds now (its label's flags)."""
    flags = []
    if tick.state.timed_out:
        flags.append(RecoveryFlag.EFFECT_TIMED_OUT)
    if tick.state.unavailable:
        flags.append(RecoveryFlag.RESOURCE_TIMED_OUT)
    if maintenance:
        flags.append(RecoveryFlag.MAINTENANCE)
    return tuple(flags)


def monotonic_abstraction(tick: Tick, executing: Iterable[str]) -> tuple[Expr, ...]:
    """Seed 000 sec. 4.3: the transition planner may change no decision variable but those
    the executing operations' effects change (it may not reach the goals of others)."""
    written: set[str] = set()
    for name in executing:
        written |= {a.target for a in tick.index.operations[name].effects}
    return unchanged(tick, set(tick.index.decisions) - written)


def unchanged(tick: Tick, names: set[str]) -> tuple[Expr, ...]:
    """A forbidden predicate: any of the decision variables `names` changed from its value."""
    values = tick.state.values
    kept = [
        effect_as_goal(Assign(name, value=values[name]), values)
        for name in tick.index.decisions
        if name in names
    ]
    return (negation(conjunction(kept)),) if kept else ()


def transition_query(
    tick: Tick,
    goal: Expr,
    executing: Iterable[str],
    *,
    maintenance: bool = False,
    kept: tuple[Expr, ...] = (),
) -> PlanQuery:
    """A transition planning query from the current state; `kept`: what the plan keeps
    true whatever the world does (the next operations' causal links, `links`).

    Maintenance planning drops the monotonic abstraction: a person putting things right
    (hanging back the tool a dead robot holds) changes what the operations estimate.
    """
    return PlanQuery(
        tick.current(),
        goal,
        tick.config.max_steps,
        maintenance=maintenance,
        forbidden=() if maintenance else monotonic_abstraction(tick, executing),
        kept=kept,
        disabled=disabled(tick),
        maintenance_cost=MAINTENANCE_COST if maintenance else 1,
    )
