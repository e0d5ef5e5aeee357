"""The retry counter (seed 000 sec. 4.5): every failed attempt of an operation counts.

An operation fails an attempt when the transition planner cannot reach its goal, or when a
device does something other than what its plan expected (a camera that misses instead of
finding, a nutrunner that ends NOK instead of at torque).  The first kind puts it in error at
once; attempts that go wrong are retried until `retries` of them have failed, then it goes
to error with the cause, so that a blinded camera is not tried for ever.  The count is
forgotten when the operation reaches its goal or the cause is gone (`Tick.cause_gone`).

A failure counted while device effects were timed out is blamed on them: a device that is
merely slow makes its effect come after the time-out, and then those failures are taken back
and the operations they put in error go on where they were (`late_effect`), instead of
starting over, timing out again and using up their retries.
"""

from __future__ import annotations

from collections.abc import Iterable

from planner.model.expressions import variables_of
from planner.runner.tick import Tick
from planner.runner.vocabulary import OperationState, ReplanReason


def count_failure(tick: Tick, name: str, *, blame_timeouts: bool = False) -> int:
    state = tick.state
    state.failures[name] = state.failures.get(name, 0) + 1
    timed_out = frozenset(state.timed_out - tick.index.person_effects)
    if blame_timeouts and timed_out:
        state.blamed_on_timeouts.setdefault(name, []).append(timed_out)
    return state.failures[name]


def late_effect(tick: Tick, effect: str) -> None:
    """`effect` timed out and happened after all: the failures blamed on its time-out are
    taken back, and the operations it put in error may go on where they were."""
    state = tick.state
    for name, blamed in sorted(state.blamed_on_timeouts.items()):
        kept = [effects for effects in blamed if effect not in effects]
        taken_back = len(blamed) - len(kept)
        if not taken_back:
            continue
        left = state.failures.get(name, 0) - taken_back
        if left > 0:
            state.failures[name] = left
        else:
            state.failures.pop(name, None)
        if kept:
            state.blamed_on_timeouts[name] = kept
        else:
            del state.blamed_on_timeouts[name]
        if state.operations[name] == OperationState.ERROR:
            state.resumable.add(name)
    tick.errors_may_clear = True


def forget_failures(tick: Tick, name: str) -> None:
    """The operation starts afresh: it reached its goal, was released or reset."""
    state = tick.state
    state.failures.pop(name, None)
    state.blamed_on_timeouts.pop(name, None)


def while_blocked(tick: Tick) -> str:
    """What keeps plans from reaching a goal besides the model itself, as the end of a cause
    (" while r2 does not answer"), so that the first cause names it: an operator told only
    that a camera's goal cannot be reached is not told that a robot stopped answering.
    Names stay model names; pages put them in words (`planner.words.Wording.text`)."""
    state = tick.state
    parts = []
    halted = sorted(state.unavailable & state.cannot_act.keys())
    if halted:  # it answers, and says why it cannot act
        verb = "does" if len(halted) == 1 else "do"
        parts.append(
            f"{_joined(halted)} {verb} not act ({'; '.join(state.cannot_act[r] for r in halted)})"
        )
    silent = sorted(state.unavailable - state.cannot_act.keys())
    if silent:
        verb = "does" if len(silent) == 1 else "do"
        parts.append(f"{_joined(silent)} {verb} not answer")
    disabled = sorted(state.timed_out)
    if disabled:
        verb = "is" if len(disabled) == 1 else "are"
        parts.append(f"{_joined(disabled)} {verb} disabled after a time-out")
    return f" while {' and '.join(parts)}" if parts else ""


def _joined(names: list[str]) -> str:
    return ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else names[0]


def fail_operation(tick: Tick, name: str, why: str) -> None:
    """`name` goes to error with `why`; the operation plan may not count it as started."""
    state = tick.state
    tick.set_operation(name, OperationState.ERROR, why)
    if state.operation_plan is not None:
        state.operation_plan.unstart(name)


def failed_attempt(tick: Tick, what: str, instead_of: Iterable[str] = ()) -> None:
    """The attempt of the operations that waited for `instead_of` went wrong (`what`
    happened): each counts a failure, and those that used up their retries go to error."""
    state = tick.state
    failed = []
    for name in waiting_for_effects(tick, set(instead_of)):
        count = count_failure(tick, name)
        if count >= tick.config.retries:
            fail_operation(tick, name, f"{what} ({count} failed attempts)")
            failed.append(name)
    if failed:
        state.transition_plan = None
        state.replan_operations = ReplanReason.ERROR


def waiting_for_effects(tick: Tick, effects: set[str]) -> list[str]:
    """The executing operations whose goals depend on `effects` in the transition plan: a
    goal reads what they write, or what a later step of the plan that reads it writes.
    Operations running beside them (the operator placing bolts while a camera misses) do
    not count a failure.  All executing ones when the plan does not tell."""
    state = tick.state
    executing = state.executing()
    plan = state.transition_plan
    at = next((k for k, step in enumerate(plan.steps) if step in effects), None) if plan else None
    if plan is None or at is None:
        return executing
    model = tick.index.model
    written: set[str] = set()
    for step in plan.steps[at:]:
        transition = model.transition(step)
        if step in effects or variables_of(transition.guard) & written:
            written |= {a.target for a in transition.actions}
    concerned = [n for n in executing if variables_of(state.operation_goals[n]) & written]
    return concerned or executing
