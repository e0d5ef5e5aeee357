"""Phase 5: the operation plan (DESIGN.md section 4.5, seed 000 sec. 4.2).

Operations finish when their goal holds (their actions are applied); the operation planner
is asked again when intentions, decision variables or operation states changed, or when the
rest of the operation plan no longer reaches the active intentions' goals; operations start
in the plan's partial order once their precondition holds.  An operation's goal for the
transition planner is fixed when it starts: its goal predicate and its effects evaluated
then ("x := y with y = 5" becomes "x == 5").

When no operation plan reaches every active intention, each intention is planned alone; the
ones that fail go to error, the rest are planned again, and a plan with maintenance
transitions is made for the operations in error (`planner.runner.maintenance`).
"""

from __future__ import annotations

from planner.model.expressions import Value, assigned
from planner.planning.partial_order import independent_operations
from planner.planning.query import PlanStatus
from planner.runner.maintenance import request_maintenance
from planner.runner.queries import announce, ask, no_plan_because
from planner.runner.retries import forget_failures, while_blocked
from planner.runner.state import OperationPlan
from planner.runner.tick import Tick
from planner.runner.vocabulary import (
    EventKind,
    IntentionState,
    OperationState,
    PlanLevel,
    RecoveryFlag,
    ReplanReason,
)

# at most this many operations are appended to mend the end of an operation plan
_MOST_APPENDED = 4


def follow_operation_plan(tick: Tick) -> None:
    state = tick.state
    for name in list(state.operation_goals):
        executing = state.operations[name] == OperationState.EXECUTING
        if executing and tick.index.holds(state.operation_goals[name], state.values):
            finish_operation(tick, name)
    active = state.intentions_in(IntentionState.EXECUTING)
    if not active:
        state.operation_plan = None
        state.replan_operations = None
        return
    if state.replan_operations is None and not operation_plan_reaches(tick, active):
        state.replan_operations = ReplanReason.DEVIATION
    if state.replan_operations is not None:
        plan_operations(tick, active, state.replan_operations)
        state.replan_operations = None
    start_operations(tick)


def finish_operation(tick: Tick, name: str) -> None:
    state = tick.state
    state.values.update(assigned(tick.index.operations[name].actions, state.values))
    state.operation_goals.pop(name)
    forget_failures(tick, name)
    tick.set_operation(name, OperationState.INITIAL, "goal reached")
    state.run_finished += (name,)
    if state.operation_plan is not None:
        state.operation_plan.finish(name)
    tick.replan_transitions(ReplanReason.GOALS)


def predicted(tick: Tick) -> dict[str, Value]:
    """The decision state once the executing operations have finished."""
    state = tick.state
    values = dict(state.values)
    for name in state.executing():  # one in error keeps its goal for maintenance planning only
        values.update(assigned(tick.index.operations[name].effects, state.values))
    return values


def operation_plan_reaches(tick: Tick, active: list[str]) -> bool:
    """Simulate the rest of the operation plan: does it still reach the intentions' goals?

    Repairs the plan in place where that needs no planning, so that robots moving about
    (their positions are measured, and in the goals) do not make the planner thrash
    between equally short plans: a step whose effects already hold is skipped, and when
    only the end falls short, operations enabled there that satisfy more of the goal are
    appended (a robot that moved needs parking again).  Only operations that change
    measured variables alone are skipped or appended: a product that is not as planned
    is a deviation the operation planner must see (E1).
    """
    state = tick.state
    plan = state.operation_plan
    if plan is None:
        return False
    index = tick.index
    values = predicted(tick)
    skipped = []
    inserted: list[tuple[int, list[str]]] = []
    for k, name in enumerate(plan.steps):
        if k in plan.started:
            continue
        if state.operations[name] == OperationState.ERROR:
            return False
        effects = assigned(index.operations[name].effects, values)
        if not index.operation_precondition[name](index.as_state(values)):
            if index.measures_only[name] and all(values[t] == v for t, v in effects.items()):
                skipped.append(k)
                continue
            before = mend_before(tick, name, values)
            if before is None:
                return False
            inserted.append((k, before))
            for extra in before:
                values.update(assigned(index.operations[extra].effects, values))
            effects = assigned(index.operations[name].effects, values)
        values.update(effects)
    appended = mend_the_end(tick, active, values)
    growth = sum(len(before) for _, before in inserted) + len(appended or ())
    if appended is None or len(plan.steps) + growth > tick.config.max_steps:
        return False
    for k in skipped:
        plan.started.add(k)
        plan.finished.add(k)
    for k, before in reversed(inserted):
        insert_before(plan, k, before)
    for name in appended:
        plan.steps += (name,)
        plan.after += (frozenset(range(len(plan.steps) - 1)),)
    if skipped or appended or inserted:
        skipped_names = [plan.steps[k] for k in skipped]
        if inserted:
            added = [name for _, before in inserted for name in before]
            tick.emit(
                EventKind.REPAIRED, "OP", skipped=skipped_names, appended=appended, inserted=added
            )
        else:
            tick.emit(EventKind.REPAIRED, "OP", skipped=skipped_names, appended=appended)
    return True


def mend_before(tick: Tick, name: str, values: dict[str, Value]) -> list[str] | None:
    """At most two operations that change measurements only and make `name`'s precondition
    hold again at `values` (None when there are none).

    A robot that made way for another undid a measurement a later step needs (a camera
    forgets the tool it found once its robot leaves the scan pose).  Planning the
    operations again then picks among equally short plans, and the one it picks may undo
    the other robot's work in turn: the two robots take turns for ever.  Doing the
    measuring operation again where it is needed keeps the plan the station committed to.
    """
    index = tick.index
    wanted = index.operation_precondition[name]
    candidates = [
        n
        for n in index.operations
        if index.measures_only[n] and n != name and tick.state.operations[n] != OperationState.ERROR
    ]
    frontier: list[tuple[list[str], dict[str, Value]]] = [([], values)]
    for _ in range(2):
        reached = []
        for done, at in frontier:
            for n in candidates:
                if n in done or not index.operation_precondition[n](index.as_state(at)):
                    continue
                after = at | assigned(index.operations[n].effects, at)
                if after == at:
                    continue
                if wanted(index.as_state(after)):
                    return [*done, n]
                reached.append(([*done, n], after))
        frontier = reached
    return None


def insert_before(plan: OperationPlan, k: int, names: list[str]) -> None:
    """Puts `names` into `plan` before step `k`, in order: each waits for every step before
    it, and the steps from `k` on wait for them."""
    n = len(names)

    def shift(indices: frozenset[int]) -> frozenset[int]:
        return frozenset(i if i < k else i + n for i in indices)

    extra = frozenset(range(k, k + n))
    plan.after = (
        tuple(shift(a) for a in plan.after[:k])
        + tuple(frozenset(range(k + j)) for j in range(n))
        + tuple(shift(a) | extra for a in plan.after[k:])
    )
    plan.steps = plan.steps[:k] + tuple(names) + plan.steps[k:]
    plan.started = set(shift(frozenset(plan.started)))
    plan.finished = set(shift(frozenset(plan.finished)))


def mend_the_end(tick: Tick, active: list[str], values: dict[str, Value]) -> list[str] | None:
    """Operations to append so that the plan's end `values` meet every active goal (None
    when that takes more than a few, or operations that change more than measurements)."""
    index = tick.index
    parts = [part for name in active for part in index.goal_parts[name]]
    met = sum(part(index.as_state(values)) for part in parts)
    appended: list[str] = []
    while met < len(parts) and len(appended) < _MOST_APPENDED:
        found = None
        for name, operation in index.operations.items():
            if (
                tick.state.operations[name] == OperationState.ERROR
                or not index.measures_only[name]
                or not index.operation_precondition[name](index.as_state(values))
            ):
                continue
            after = values | assigned(operation.effects, values)
            satisfied = sum(part(index.as_state(after)) for part in parts)
            if satisfied > met:
                found = (name, after, satisfied)
                break
        if found is None:
            return None
        appended.append(found[0])
        values, met = found[1], found[2]
    return appended if met == len(parts) else None


def plan_operations(tick: Tick, active: list[str], reason: ReplanReason) -> None:
    state = tick.state
    errors = sorted(state.operations_in(OperationState.ERROR))
    intentions = [tick.index.intentions[n] for n in active]
    planner = tick.runner.operation_planner
    durations = {} if tick.config.sequential else tick.runner.durations()
    query = planner.query(
        predicted(tick),
        intentions,
        disabled=errors,
        max_steps=tick.config.max_steps,
        durations=durations,
    )
    result, millis = ask(tick, PlanLevel.OPERATIONS, query, "operations")
    flags = (RecoveryFlag.DISABLED_OPERATIONS,) if errors else ()
    span = result.statistics.get("makespan")
    extra = {} if span is None else {"expected_cycle": round(span, 1)}
    announce(tick, PlanLevel.OPERATIONS, flags, reason, result, millis, **extra)
    if result.found:
        after = independent_operations(tick.index.operation_variables, result.plan)
        state.operation_plan = OperationPlan(result.plan, tuple(after))
        return
    state.operation_plan = None
    if result.status is PlanStatus.OVER_BUDGET:  # asking each alone would take as long
        for intention in intentions:
            why = no_plan_because(result, "")
            tick.set_intention(intention.name, IntentionState.ERROR, why)
        state.replan_operations = None
        return
    # which intentions fail: plan for each alone (seed 000 sec. 4.2)
    for intention in intentions:
        alone = planner.query(
            predicted(tick), [intention], disabled=errors, max_steps=tick.config.max_steps
        )
        single, _ = ask(tick, PlanLevel.OPERATIONS, alone, "which intentions fail")
        if not single.found:
            why = f"no operation plan reaches its goal{while_blocked(tick)}"
            tick.set_intention(intention.name, IntentionState.ERROR, why)
    state.replan_operations = None
    still = state.intentions_in(IntentionState.EXECUTING)
    if still and still != active:
        plan_operations(tick, still, ReplanReason.ERROR)
    if state.intentions_in(IntentionState.ERROR):
        request_maintenance(tick)


def start_operations(tick: Tick) -> None:
    """Start the plan's operations whose turn has come in its partial order.

    An operation never starts beside an executing one it shares a variable with, even one
    from an earlier plan (a plan made again while an operation runs does not list it):
    operations run at once only when independent (DESIGN.md section 3.4).
    """
    state = tick.state
    plan = state.operation_plan
    if plan is None or state.restart_mode:
        return
    index = tick.index
    for k, name in enumerate(plan.steps):
        if k in plan.started or not plan.after[k] <= plan.finished:
            continue
        if tick.config.sequential and state.operations_in(OperationState.EXECUTING):
            return
        if state.operations[name] != OperationState.INITIAL:
            continue
        if shares_with_executing(tick, name):
            continue
        if not index.operation_precondition[name](tick.current()):
            continue
        state.operation_goals[name] = index.operations[name].planning_goal(state.values)
        plan.started.add(k)
        tick.set_operation(name, OperationState.EXECUTING, "next in the operation plan")
        tick.replan_transitions(ReplanReason.GOALS)


def shares_with_executing(tick: Tick, name: str) -> bool:
    """Whether `name` shares a variable with an executing operation."""
    index = tick.index
    mine = index.operation_variables[name]
    executing = tick.state.operations_in(OperationState.EXECUTING)
    return any(mine & index.operation_variables[other] for other in executing)
