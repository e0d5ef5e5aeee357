"""People's actions: operators, engineers and line systems telling the runner something.

Each action is taken in the tick it arrives in, after the devices' reports, and answered
with a `Reply`: accepted (and recorded as an `operator` event with the user's name) or
refused with the reason (a `refused` event).  Restart-mode actions are in
`planner.runner.restart`.
"""

from __future__ import annotations

from planner.model.flat import TransitionKind
from planner.runner import restart
from planner.runner.actions import (
    Action,
    Approve,
    ApprovePlan,
    CancelIntention,
    EnterRestart,
    LeaveRestart,
    MaintenanceDone,
    ReenableEffect,
    Reject,
    RejectPlan,
    Reply,
    ResetOperation,
    SetEstimated,
    StartIntention,
)
from planner.runner.forbidden import needs_approval, numbered
from planner.runner.maintenance import pending_maintenance
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind, IntentionState, PersonAct, ReplanReason


def act(tick: Tick, action: Action) -> Reply:
    match action:
        case StartIntention() | CancelIntention():
            return start_or_cancel(tick, action)
        case Approve() | Reject():
            return approve_or_reject(tick, action)
        case ApprovePlan() | RejectPlan():
            return decide_plan(tick, action)
        case MaintenanceDone():
            return maintenance_done(tick, action)
        case EnterRestart():
            return restart.enter(tick, action)
        case LeaveRestart():
            return restart.leave(tick, action)
        case SetEstimated():
            return restart.set_estimated(tick, action)
        case ResetOperation():
            return restart.reset_operation(tick, action)
        case ReenableEffect():
            return reenable_effect(tick, action)
    return tick.refuse(action, type(action).__name__, "the runner does not know this action")


def start_or_cancel(tick: Tick, action: StartIntention | CancelIntention) -> Reply:
    state = tick.state
    name, who = action.name, action.user
    if name not in state.intentions:
        return tick.refuse(action, name, "there is no such intention")
    current = state.intentions[name]
    if isinstance(action, StartIntention):
        state.auto_start.add(name)
        if current in (IntentionState.FINISHED, IntentionState.ERROR):
            tick.set_intention(name, IntentionState.INITIAL, "started again by " + who)
        tick.emit(EventKind.OPERATOR, PersonAct.START_INTENTION, user=who, intention=name)
    else:
        state.auto_start.discard(name)
        if current in (IntentionState.EXECUTING, IntentionState.ERROR):
            tick.set_intention(name, IntentionState.INITIAL, "cancelled")
        tick.emit(EventKind.OPERATOR, PersonAct.CANCEL_INTENTION, user=who, intention=name)
    return Reply.accept(action)


def approve_or_reject(tick: Tick, action: Approve | Reject) -> Reply:
    state = tick.state
    plan = state.recovery
    step = action.step
    if plan is None or not 0 <= step < len(plan.blocks):
        return tick.refuse(action, f"step {step}", "no such recovery step")
    if step not in plan.asked:  # a person answers what was shown, not what may come
        return tick.refuse(action, f"step {step}", "that step has not been asked for yet")
    transition = plan.blocks[step].transition
    number, of = numbered(tick.index, plan, step)  # as the screen numbers it, for the audit
    act = PersonAct.REJECT if isinstance(action, Reject) else PersonAct.APPROVE
    tick.emit(
        EventKind.OPERATOR,
        act,
        user=action.user,
        step=step,
        transition=transition,
        number=number,
        of=of,
    )
    if isinstance(action, Reject):
        _drop_recovery(tick, (transition,))
    else:
        plan.approved.add(step)
    return Reply.accept(action)


def _drop_recovery(tick: Tick, rejected: tuple[str, ...]) -> None:
    """A person refused these machine steps: the plan is dropped and planned again without
    them (the specifications it relaxed hold again)."""
    tick.state.recovery = None
    tick.state.relaxed = frozenset()
    tick.state.rejected.update(rejected)


def decide_plan(tick: Tick, action: ApprovePlan | RejectPlan) -> Reply:
    """One decision on every machine step of the recovery plan not yet approved, as the
    person was shown them; the event names each step (index and transition) for the audit."""
    state = tick.state
    plan = state.recovery
    if plan is None:
        return tick.refuse(action, "recovery plan", "there is no recovery plan to decide on")
    steps = needs_approval(tick.index, plan)
    shown = tuple(plan.blocks[k].transition for k in steps)
    if not steps or not plan.asked & set(steps):
        return tick.refuse(action, "recovery plan", "the recovery plan asks for no approval now")
    if tuple(action.steps) != shown:
        why = "the recovery plan changed since it was shown; look at it again"
        return tick.refuse(action, "recovery plan", why)
    act = PersonAct.APPROVE_PLAN if isinstance(action, ApprovePlan) else PersonAct.REJECT_PLAN
    numbers = [numbered(tick.index, plan, k)[0] for k in steps]
    of = numbered(tick.index, plan, steps[0])[1]
    tick.emit(
        EventKind.OPERATOR,
        act,
        user=action.user,
        steps=steps,
        transitions=list(shown),
        numbers=numbers,
        of=of,
    )
    if isinstance(action, RejectPlan):
        _drop_recovery(tick, shown)  # plan again, without any of its machine steps
    else:
        plan.approved.update(steps)
    return Reply.accept(action)


def maintenance_done(tick: Tick, action: MaintenanceDone) -> Reply:
    """The operator did a maintenance step asked for now: the runner applies it, measured
    values included (the devices will report what the operator did, and a disconnected
    one cannot), and the plan it belongs to moves on."""
    state = tick.state
    name = action.transition
    if name not in pending_maintenance(tick):
        return tick.refuse(action, name, "not a maintenance step asked for now")
    chosen = tick.index.transition(name)
    assert chosen.kind is TransitionKind.MAINTENANCE
    current = tick.current()
    if not chosen.guard(current):
        return tick.refuse(action, name, "its guard does not hold")
    tick.set_values(chosen.apply(current))
    tick.emit(EventKind.OPERATOR, PersonAct.MAINTENANCE_DONE, user=action.user, transition=name)
    tick.errors_may_clear = True
    plan = state.recovery if state.recovery is not None else state.maintenance
    if plan is not None:
        plan.mark_taken(name)
    return Reply.accept(action)


def reenable_effect(tick: Tick, action: ReenableEffect) -> Reply:
    state = tick.state
    name = action.name
    if name not in state.timed_out:
        return tick.refuse(action, name, "the effect is not timed out")
    state.timed_out.discard(name)
    state.effect_enabled_since.pop(name, None)
    tick.reenabled_by_people.add(name)
    tick.cause_gone()
    tick.emit(EventKind.REENABLED, name, user=action.user)
    tick.replan_transitions(ReplanReason.REENABLED)
    return Reply.accept(action)
