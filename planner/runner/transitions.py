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

from planner.model.expressions import Expr, conjunction
from planner.planning.query import PlanStatus
from planner.runner.following import follow, plan_reaches, startable, take
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
    if state.replan_transitions is None:
        plan = state.transition_plan
        if plan is None or plan.goal != goal:
            state.replan_transitions = ReplanReason.GOALS
        elif not plan_reaches(tick, plan):
            state.replan_transitions = ReplanReason.DEVIATION
    if state.replan_transitions is not None:
        reason = state.replan_transitions
        state.replan_transitions = None
        if not plan_transitions(tick, executing, goal, reason):
            return
    plan = state.transition_plan
    if plan is None:
        return
    for k in startable(tick, plan):
        take(tick, plan, k, supervised=True)


def plan_transitions(tick: Tick, executing: list[str], goal: Expr, reason: ReplanReason) -> bool:
    """Plan for the executing operations; whether a plan was found."""
    state = tick.state
    query = transition_query(tick, goal, executing)
    result, millis = ask(tick, PlanLevel.TRANSITIONS, query, "transitions")
    announce(tick, PlanLevel.TRANSITIONS, recovery_flags(tick), reason, result, millis)
    if result.found:
        state.transition_plan = follow(tick, goal, result)
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
