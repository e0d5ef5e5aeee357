"""The background check (seed 000 sec. 4.5): what is in error and can be completed again.

Every `recheck_period` seconds each operation in error that has retries left is planned
for alone; if its goal can be reached it goes back to initial.  Each intention in error is
planned for alone by the operation planner (without the operations still in error); if its
goal can be reached it executes again.  Nothing is checked during forbidden-state recovery.
"""

from __future__ import annotations

from planner.runner.operations import predicted
from planner.runner.queries import ask, transition_query
from planner.runner.tick import Tick
from planner.runner.vocabulary import IntentionState, OperationState, PlanLevel, ReplanReason


def due(tick: Tick) -> bool:
    return tick.now >= tick.state.next_background_check


def background_check(tick: Tick) -> None:
    state = tick.state
    state.next_background_check = tick.now + tick.config.recheck_period
    if state.recovery is not None:
        return
    recheck_operations(tick)
    recheck_intentions(tick)


def recheck_operations(tick: Tick) -> None:
    state = tick.state
    for name in sorted(state.operations_in(OperationState.ERROR)):
        if state.failures.get(name, 0) >= tick.config.retries:
            continue  # treated as unreachable (seed 000 sec. 4.5: the retry counter)
        operation = tick.index.operations[name]
        goal = state.operation_goals.get(name) or operation.planning_goal(state.values)
        query = transition_query(tick, goal, [name])
        result, _ = ask(tick, PlanLevel.TRANSITIONS, query, "background check of an operation")
        if result.found:
            state.operation_goals.pop(name, None)
            tick.set_operation(name, OperationState.INITIAL, "its goal can be reached again")
            tick.replan_operations(ReplanReason.CLEARED)


def recheck_intentions(tick: Tick) -> None:
    state = tick.state
    planner = tick.runner.operation_planner
    for name in sorted(state.intentions_in(IntentionState.ERROR)):
        errors = sorted(state.operations_in(OperationState.ERROR))
        query = planner.query(
            predicted(tick),
            [tick.index.intentions[name]],
            disabled=errors,
            max_steps=tick.config.max_steps,
        )
        result, _ = ask(tick, PlanLevel.OPERATIONS, query, "background check of an intention")
        if result.found:
            state.maintenance = None
            tick.set_intention(name, IntentionState.EXECUTING, "its goal can be reached again")
