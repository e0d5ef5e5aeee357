"""Restart mode (seed 001 VIII-A, DESIGN.md section 4).

An engineer enters restart mode to put the station right by hand: intentions and
operations do not start by themselves, restart abilities become usable, estimated values
may be set to match reality (with a reason), and operations may be reset: each is put back
to initial and the transition planner brings the station to its precondition, so that it
can start again.  Every change is an event with the user's name.

    running --enter--> restart mode --reset an operation--> planned to its precondition
    precondition reached --> reset done;   no plan --> reset not done, said why
    restart mode --leave--> running again (resets not yet done are abandoned)
"""

from __future__ import annotations

from dataclasses import replace

from planner.model.expressions import Value, conjunction, variables_of
from planner.model.flat import VariableKind
from planner.runner.actions import Action, EnterRestart, Reply, ResetOperation, SetEstimated
from planner.runner.following import follow, plan_reaches, startable, take
from planner.runner.queries import announce, ask, recovery_flags, transition_query, unchanged
from planner.runner.retries import forget_failures
from planner.runner.tick import Tick
from planner.runner.vocabulary import (
    EventKind,
    OperationState,
    PersonAct,
    PlanLevel,
    ReplanReason,
    RestartMove,
)


def enter(tick: Tick, action: EnterRestart) -> Reply:
    state = tick.state
    state.restart_mode = True
    state.restart_reason, state.restart_user = action.reason, action.user
    tick.emit(EventKind.RESTART, RestartMove.ENTERED, user=action.user, reason=action.reason)
    tick.replan_transitions(ReplanReason.RESTART)
    return Reply.accept(action)


def leave(tick: Tick, action: Action) -> Reply:
    state = tick.state
    state.restart_mode = False
    state.restart_reason, state.restart_user = "", ""
    for name in sorted(state.resetting):
        tick.emit(EventKind.RESET, name, done=False, why="restart mode left before it")
    state.resetting.clear()
    tick.emit(EventKind.RESTART, RestartMove.LEFT, user=action.user)
    tick.replan_operations(ReplanReason.RESTART)
    tick.replan_transitions(ReplanReason.RESTART)
    return Reply.accept(action)


def set_estimated(tick: Tick, action: SetEstimated) -> Reply:
    state = tick.state
    name, value, who = action.variable, action.value, action.user
    why = _estimate_refused(tick, name, value, action.reason)
    if why:
        return tick.refuse(action, name, why)
    before = state.values[name]
    state.values[name] = value
    tick.emit(
        EventKind.OPERATOR,
        "set estimated",
        user=who,
        variable=name,
        before=before,
        after=value,
        reason=action.reason,
    )
    tick.replan_operations(ReplanReason.ESTIMATED)
    tick.errors_may_clear = True
    return Reply.accept(action)


def _estimate_refused(tick: Tick, name: str, value: Value, reason: str) -> str:
    kind = tick.index.variable_kind.get(name)
    if kind not in (VariableKind.ESTIMATED, VariableKind.DECISION):
        return "no such variable" if kind is None else f"'{name}' is {kind.value}, not estimated"
    if value not in tick.index.model.variable(name).domain:
        return f"{value!r} is outside the domain"
    if not tick.state.restart_mode:
        return "estimated variables are set in restart mode"
    if not reason.strip():
        return "a reason is required"
    return ""


def reset_operation(tick: Tick, action: ResetOperation) -> Reply:
    state = tick.state
    name, who = action.name, action.user
    why = ""
    if name not in state.operations:
        why = "there is no such operation"
    elif not state.restart_mode:
        why = "operations are reset in restart mode"
    if why:
        return tick.refuse(action, name, why)
    forget_failures(tick, name)
    state.operation_goals.pop(name, None)
    if state.operation_plan is not None:
        state.operation_plan.unstart(name)
    if state.operations[name] != OperationState.INITIAL:
        tick.set_operation(name, OperationState.INITIAL, "reset by " + who)
    tick.replan_operations(ReplanReason.RESET)
    tick.emit(EventKind.OPERATOR, PersonAct.RESET_OPERATION, user=who, operation=name)
    # seed 001 VIII-A: plan to reach its precondition, to start it again
    state.resetting.add(name)
    return Reply.accept(action)


def follow_reset_plan(tick: Tick) -> None:
    """Executing operations are paused; plan and take transitions (restart abilities
    included) that bring the operations being reset to their preconditions."""
    state = tick.state
    index = tick.index
    for name in sorted(state.resetting):
        if index.operation_precondition[name](tick.current()):
            state.resetting.discard(name)
            tick.emit(EventKind.RESET, name, done=True, why="its precondition holds")
    if not state.resetting:
        state.transition_plan = None
        return
    preconditions = [index.operations[n].precondition for n in sorted(state.resetting)]
    goal = conjunction(preconditions)
    plan = state.transition_plan
    if plan is None or plan.goal != goal or not plan_reaches(tick, plan):
        written = {v for p in preconditions for v in variables_of(p)}
        keep = unchanged(tick, set(index.decisions) - written)
        query = replace(transition_query(tick, goal, []), forbidden=keep)
        result, millis = ask(tick, PlanLevel.TRANSITIONS, query, "reset")
        flags = recovery_flags(tick)
        announce(tick, PlanLevel.TRANSITIONS, flags, ReplanReason.RESET, result, millis)
        if not result.found:
            for name in sorted(state.resetting):
                tick.emit(EventKind.RESET, name, done=False, why="no plan reaches its precondition")
            state.resetting.clear()
            state.transition_plan = None
            return
        state.transition_plan = plan = follow(tick, goal, result)
    for k in startable(tick, plan):
        take(tick, plan, k, supervised=True)
