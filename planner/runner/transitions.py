"""Phase 6: the transition plan for the executing operations (DESIGN.md section 4.6).

The goal is the conjunction of the executing operations' goals.  The transition planner is
asked again when the goal changed, when something asked for it (a time-out, a resource that
came or went, a person's action) or when the rest of the plan no longer reaches the goal
safely (`planner.runner.following.plan_reaches`); otherwise the plan's next steps are taken.

When no plan reaches the goal, each executing operation is planned for alone (seed 000
Figure 6); those that cannot reach their goal go to error (all of them if each can alone)
and count a failure, and the operation plan is made again without them.

In restart mode `planner.runner.restart.follow_reset_plan` takes this phase's place.
"""

from __future__ import annotations

from dataclasses import replace

from planner.model.expressions import Expr, conjunction
from planner.planning.query import PlanResult, PlanStatus
from planner.runner.following import follow, plan_reaches, startable, take
from planner.runner.links import Link, conditions, defer, deferrable, protected_links
from planner.runner.queries import (
    announce,
    ask,
    no_plan_because,
    recovery_flags,
    transition_query,
)
from planner.runner.retries import count_failure, fail_operation, while_blocked
from planner.runner.tick import Tick
from planner.runner.vocabulary import PlanLevel, ReplanReason


def follow_transition_plan(tick: Tick) -> None:
    state = tick.state
    executing = state.executing()
    if not executing:
        state.transition_plan = None
        state.replan_transitions = None
        return
    goal = conjunction([state.operation_goals[n] for n in executing])
    links = protected_links(tick)
    if state.replan_transitions is None:
        plan = state.transition_plan
        if plan is None or plan.goal != goal or plan.kept != conditions(links):
            state.replan_transitions = ReplanReason.GOALS
        elif not plan_reaches(tick, plan):
            state.replan_transitions = ReplanReason.DEVIATION
    if state.replan_transitions is not None:
        reason = state.replan_transitions
        state.replan_transitions = None
        if not plan_transitions(tick, executing, goal, reason, links):
            return
    plan = state.transition_plan
    if plan is None:
        return
    for k in startable(tick, plan):
        take(tick, plan, k, supervised=True)


def plan_transitions(
    tick: Tick,
    executing: list[str],
    goal: Expr,
    reason: ReplanReason,
    links: tuple[Link, ...] = (),
) -> bool:
    """Plan for the executing operations, keeping the next operations' `links`; whether a
    plan was found."""
    state = tick.state
    kept = conditions(links)
    query = transition_query(tick, goal, executing, kept=kept)
    result, millis = ask(tick, PlanLevel.TRANSITIONS, query, "transitions")
    if not result.found and links:
        kept, result, millis = without_breaking(tick, executing, links, (result, millis))
        goal = conjunction([state.operation_goals[n] for n in state.executing()])
    announce(tick, PlanLevel.TRANSITIONS, recovery_flags(tick), reason, result, millis)
    if result.found:
        state.transition_plan = replace(follow(tick, goal, result), kept=kept)
        return True
    state.transition_plan = None
    if result.status is PlanStatus.OVER_BUDGET:  # asking each alone would take as long
        fail_operations(tick, executing, no_plan_because(result, ""))
        state.replan_operations = ReplanReason.ERROR
        return False
    fail_operations(tick, which_operations_fail(tick, executing) or executing)
    state.replan_operations = ReplanReason.ERROR
    return False


def which_operations_fail(tick: Tick, executing: list[str]) -> list[str]:
    """The executing operations that cannot reach their goals, each planned alone."""
    failed = []
    for name in executing:
        query = transition_query(tick, tick.state.operation_goals[name], executing)
        alone, _ = ask(tick, PlanLevel.TRANSITIONS, query, "which operations fail")
        if not alone.found:
            failed.append(name)
    return failed


def fail_operations(tick: Tick, names: list[str], why: str = "") -> None:
    """`names` go to error; `why` defaults to the goal being out of reach, and what blocks
    it (a resource that does not answer, a disabled effect)."""
    why = why or f"its goal cannot be reached{while_blocked(tick)}"
    for name in names:
        count = count_failure(tick, name, blame_timeouts=True)
        counted = why + (f" ({count} failures)" if count > 1 else "")
        fail_operation(tick, name, counted)


def without_breaking(
    tick: Tick,
    executing: list[str],
    links: tuple[Link, ...],
    first: tuple[PlanResult, float | None],
) -> tuple[tuple[Expr, ...], PlanResult, float | None]:
    """No plan keeps the links (`first`): defer an executing operation that breaks them, if
    one can be and then the others have a plan that keeps them; else plan without the links
    (what undoes a link is mended later, `operations.mend_before`).  The links the answer
    was planned under, the answer and its time."""
    state = tick.state
    kept = conditions(links)
    free = transition_query(
        tick, conjunction([state.operation_goals[n] for n in executing]), executing
    )
    unkept, millis = ask(tick, PlanLevel.TRANSITIONS, free, "transitions without the links")
    if not unkept.found:
        return (), first[0], first[1]  # the goal itself is out of reach: the usual errors
    for name in deferrable(tick, links):
        others = [n for n in executing if n != name]
        if not others:
            continue
        goal = conjunction([state.operation_goals[n] for n in others])
        query = transition_query(tick, goal, others, kept=kept)
        result, spent = ask(tick, PlanLevel.TRANSITIONS, query, "transitions, one deferred")
        if result.found:
            defer(tick, name, links)
            return kept, result, spent
    return (), unkept, millis
