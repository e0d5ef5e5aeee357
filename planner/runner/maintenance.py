"""Error propagation's last step: maintenance for what is in error (seed 000 sec. 4.5).

When intentions are in error, the transition planner is asked, with maintenance transitions
allowed, for a plan that completes an operation in error.  The plan is followed up to its
last maintenance step: the runner takes its controlled steps (supervised), and each
maintenance step becomes an instruction for the operator once the steps before it are done;
the operator reports it done.  When every step is done, the operation it was made for may
be tried again, if it has retries left.

    no maintenance --intentions in error, a plan found--> following it
    its turn comes --> instruction shown --> the operator reports it done --> next step
    what it waits for can no longer happen --> made again from here
    every step done --> the operation goes back to initial (within its retries)
    a person's step done, the next one's turn not come --> shown ahead (`next_maintenance`)
    no intention in error any more --> the plan is dropped

With operations in parallel, an intention can go to error while other operations still
execute (the operator placing a bolt pair beside a robot that failed).  They are let finish,
and the plan is made once they have come to rest (`maintenance_due`): a plan made before
would be planned from a state their own steps are still changing, and both would steer the
same robots.
"""

from __future__ import annotations

from planner.model.flat import TransitionKind
from planner.planning.partial_order import blocks
from planner.runner.following import startable, stuck, take
from planner.runner.queries import announce, ask, recovery_flags, transition_query
from planner.runner.state import TransitionPlan
from planner.runner.station_index import StationIndex
from planner.runner.tick import Tick
from planner.runner.vocabulary import (
    EventKind,
    IntentionState,
    OperationState,
    PlanLevel,
    ReplanReason,
)


def request_maintenance(tick: Tick) -> None:
    """Intentions went to error: plan maintenance now, or once the operations still
    executing have come to rest (module docstring)."""
    if tick.state.executing():
        tick.state.maintenance_due = True
        return
    plan_maintenance(tick)


def plan_maintenance(tick: Tick) -> None:
    """With intentions in error: a plan with maintenance transitions for the first operation
    in error that has one (those that were executing first)."""
    state = tick.state
    state.maintenance_due = False
    errors = state.operations_in(OperationState.ERROR)
    failed = [n for n in errors if n in state.operation_goals]
    failed += [n for n in errors if n not in state.operation_goals]
    semantics = tick.index.semantics
    for name in failed:
        goal = state.operation_goals.get(name) or tick.index.operations[name].planning_goal(
            state.values
        )
        query = transition_query(tick, goal, [name], maintenance=True)
        result, millis = ask(tick, PlanLevel.TRANSITIONS, query, "maintenance")
        flags = recovery_flags(tick, maintenance=True)
        reason = ReplanReason.MAINTENANCE
        announce(tick, PlanLevel.TRANSITIONS, flags, reason, result, millis, operation=name)
        maintenance = tuple(
            step for step in result.plan if tick.index.kind_of(step) is TransitionKind.MAINTENANCE
        )
        if not (result.found and maintenance):
            continue
        # followed up to its last maintenance step; the rest is production again
        last = max(k for k, step in enumerate(result.plan) if step in maintenance)
        prefix = result.plan[: last + 1]
        pending = len(result.states) > last + 1 and semantics.automatic_enabled(
            result.states[last + 1]
        )
        order = blocks(tick.index.model, prefix, automatic_at_end=pending)
        state.maintenance = TransitionPlan(goal, prefix, tuple(order))
        state.maintenance_for = name
        return


def follow_maintenance_plan(tick: Tick) -> None:
    state = tick.state
    if not state.intentions_in(IntentionState.ERROR):
        state.maintenance, state.maintenance_due = None, False
        return
    if state.maintenance_due and not state.executing():
        plan_maintenance(tick)
    plan = state.maintenance
    if plan is None:
        return
    if stuck(tick, plan, "maintenance plan"):  # made again (it asks: run it in `attempt`)
        state.maintenance = None
        plan_maintenance(tick)
        if state.maintenance is None:
            return
        plan = state.maintenance
    for k in startable(tick, plan):
        name = plan.blocks[k].transition
        if tick.index.kind_of(name) is not TransitionKind.MAINTENANCE:
            take(tick, plan, k, supervised=True)
        elif k not in plan.asked:
            plan.asked.add(k)
            steps = [b.transition for b in plan.blocks]
            tick.emit(
                EventKind.INSTRUCTION,
                name,
                operation=state.maintenance_for,
                step=steps.index(name) + 1,
                of=len(steps),
                what=tick.index.describe(name),
            )
    if len(plan.done) < len(plan.blocks):
        return
    name, state.maintenance, state.maintenance_for = state.maintenance_for, None, ""
    in_error = state.operations[name] == OperationState.ERROR
    if in_error and state.failures.get(name, 0) < tick.config.retries:
        state.operation_goals.pop(name, None)
        tick.set_operation(name, OperationState.INITIAL, "the maintenance it needed is done")
        tick.replan_operations(ReplanReason.CLEARED)


def pending_maintenance(tick: Tick) -> list[str]:
    """The maintenance steps the operator has been asked to do and may report done now."""
    recovery, maintenance = tick.state.recovery, tick.state.maintenance
    if recovery is not None:
        return [
            recovery.blocks[k].transition
            for k in startable(tick, recovery)
            if k in recovery.approved
            and tick.index.kind_of(recovery.blocks[k].transition) is TransitionKind.MAINTENANCE
        ]
    if maintenance is None:
        return []
    return [
        maintenance.blocks[k].transition
        for k in startable(tick, maintenance)
        if k in maintenance.asked
    ]


def next_maintenance(index: StationIndex, plan: TransitionPlan) -> tuple[int, list[int]] | None:
    """After a person's step of a maintenance plan, the plan's next person's step and the
    blocks it still waits for (the robots' steps between, which take seconds): shown at
    once, ahead of its turn, so that the person is not told "nothing for you" between two
    steps of one plan.  None while a step is asked, or before the person did any."""
    person = TransitionKind.MAINTENANCE
    maintenance = [k for k, b in enumerate(plan.blocks) if index.kind_of(b.transition) is person]
    if plan.asked - plan.taken or not any(k in plan.taken for k in maintenance):
        return None
    ahead = [k for k in maintenance if k not in plan.taken and k not in plan.asked]
    if not ahead:
        return None
    done = plan.done
    return ahead[0], sorted(j for j in plan.blocks[ahead[0]].after if j not in done)
