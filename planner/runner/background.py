"""The background check (seed 000 sec. 4.5): what is in error and can be completed again.

It runs every `recheck_period` seconds, and at once in a tick where something that can
clear an error happened: a resource answers again or a person re-enables an effect (both
also forget the failures counted so far: their cause is gone), an effect's guard stops
holding, a person did a maintenance step, set an estimate or changed a product by hand.

Each operation in error that has retries left is planned for alone; if its goal can be
reached it goes back to initial, or, when a late effect took back the failure that put it
in error and nothing else executes, it goes on where it was (`retries.late_effect`).
Each intention in error is planned for alone by the operation planner (without the
operations still in error); if its goal can be reached it executes again.  When a
resource answers again, intentions still in error without a maintenance plan are given one
if one exists now (the resource may be the way out that was missing when the error came).  An
operation's error does not outlive the intentions that needed it.  Nothing is checked
during forbidden-state recovery.
"""

from __future__ import annotations

from planner.runner.maintenance import request_maintenance
from planner.runner.operations import predicted
from planner.runner.queries import ask, disabled, transition_query
from planner.runner.retries import forget_failures
from planner.runner.tick import Tick
from planner.runner.vocabulary import IntentionState, OperationState, PlanLevel, ReplanReason


def due(tick: Tick) -> bool:
    """Every `recheck_period`, and at once when something that can clear an error happened."""
    return tick.errors_may_clear or tick.now >= tick.state.next_background_check


def background_check(tick: Tick) -> None:
    state = tick.state
    state.next_background_check = tick.now + tick.config.recheck_period
    if state.recovery is not None:
        return
    release_operations(tick)
    looked_at = what_the_check_reads(tick)
    if looked_at == state.rechecked:
        return  # the same questions would get the same answers: a stop stays quiet
    recheck_operations(tick)
    recheck_intentions(tick)
    answers_again = tick.availability_changed - state.unavailable
    if answers_again and state.intentions_in(IntentionState.ERROR) and state.maintenance is None:
        request_maintenance(tick)  # a resource that answers again may be the way out
    state.rechecked = what_the_check_reads(tick)


def what_the_check_reads(tick: Tick) -> tuple[object, ...]:
    """Everything the check's queries depend on: the values, what is in error with its
    failures, and what planning may not use."""
    state = tick.state
    return (
        tick.current(),
        tuple(sorted(state.operations_in(OperationState.ERROR))),
        tuple(sorted(state.intentions_in(IntentionState.ERROR))),
        tuple(sorted(state.failures.items())),
        disabled(tick),
    )


def release_operations(tick: Tick) -> None:
    """An operation's error does not outlive the intentions that needed it: with none
    executing or in error, it goes back to initial (its failures forgotten)."""
    state = tick.state
    needed = (IntentionState.EXECUTING, IntentionState.ERROR)
    if any(current in needed for current in state.intentions.values()):
        return
    for name in sorted(state.operations_in(OperationState.ERROR)):
        state.operation_goals.pop(name, None)
        forget_failures(tick, name)
        tick.set_operation(name, OperationState.INITIAL, "no intention needs it any more")


def recheck_operations(tick: Tick) -> None:
    state = tick.state
    for name in sorted(state.operations_in(OperationState.ERROR)):
        if state.failures.get(name, 0) >= tick.config.retries:
            continue  # treated as unreachable (seed 000 sec. 4.5: the retry counter)
        operation = tick.index.operations[name]
        goal = state.operation_goals.get(name) or operation.planning_goal(state.values)
        query = transition_query(tick, goal, [name])
        result, _ = ask(tick, PlanLevel.TRANSITIONS, query, "background check of an operation")
        if not result.found:
            continue
        if name in state.resumable and name in state.operation_goals and not state.executing():
            why = "the effect it waited for came late: it goes on where it was"
            tick.set_operation(name, OperationState.EXECUTING, why)
            tick.replan_transitions(ReplanReason.GOALS)
        else:
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
