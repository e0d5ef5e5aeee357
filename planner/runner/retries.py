"""The retry counter (seed 000 sec. 4.5): every failed attempt of an operation counts.

An operation fails an attempt when the transition planner cannot reach its goal, or when a
device does something other than what its plan expected (a camera that misses instead of
finding, a nutrunner that ends NOK instead of at torque).  The first kind puts it in error at
once; attempts that go wrong are retried until `retries` of them have failed, then it goes
to error with the cause, so that a blinded camera is not tried for ever.  The count is
forgotten when the operation reaches its goal or the cause is gone (`Tick.cause_gone`).
"""

from __future__ import annotations

from planner.runner.tick import Tick
from planner.runner.vocabulary import OperationState, ReplanReason


def count_failure(tick: Tick, name: str) -> int:
    state = tick.state
    state.failures[name] = state.failures.get(name, 0) + 1
    return state.failures[name]


def fail_operation(tick: Tick, name: str, why: str) -> None:
    """`name` goes to error with `why`; the operation plan may not count it as started."""
    state = tick.state
    tick.set_operation(name, OperationState.ERROR, why)
    if state.operation_plan is not None:
        state.operation_plan.unstart(name)


def failed_attempt(tick: Tick, what: str) -> None:
    """The executing operations' attempt went wrong (`what` happened): each counts a
    failure, and those that used up their retries go to error."""
    state = tick.state
    failed = []
    for name in state.executing():
        count = count_failure(tick, name)
        if count >= tick.config.retries:
            fail_operation(tick, name, f"{what} ({count} failed attempts)")
            failed.append(name)
    if failed:
        state.transition_plan = None
        state.replan_operations = ReplanReason.ERROR
