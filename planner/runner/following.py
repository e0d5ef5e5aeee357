"""Following a transition plan: its start order, taking its steps, checking its rest.

A plan found by the transition planner is cut into blocks (`planner.planning.partial_order`): a
controlled or maintenance step with the effects and automatic steps that follow it.  A
block starts when the blocks it comes after are done and its guard holds (DESIGN.md
section 3.4).  Before it takes a step the runner checks what the model and the supervisor
require; a step held back for a reason other than its guard is a `blocked` event (once per
reason), and one the supervisor holds back makes the plan a deviation, made again.

Each tick the rest of the plan is simulated from the current state as it would run: a plan
that no longer reaches its goal, or whose next controlled step the supervisor would hold
back with nothing else to wait for, is a deviation.
"""

from __future__ import annotations

from collections.abc import Callable

from planner.model.expressions import Expr
from planner.model.flat import UNCONTROLLABLE, TransitionKind
from planner.model.semantics import State
from planner.planning.partial_order import blocks
from planner.planning.query import PlanResult
from planner.runner.automatic import automatic_enabled, may_fire, settle
from planner.runner.queries import disabled
from planner.runner.state import TransitionPlan
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind, ReplanReason

_STARTED_BY_US = (TransitionKind.CONTROLLED, TransitionKind.MAINTENANCE)


def follow(tick: Tick, goal: Expr, result: PlanResult) -> TransitionPlan:
    """The plan `result` found for `goal`, cut into blocks, ready to be followed."""
    semantics = tick.index.semantics
    pending = bool(result.states) and semantics.automatic_enabled(result.states[-1])
    order = blocks(tick.index.model, result.plan, automatic_at_end=pending)
    plan = TransitionPlan(goal, result.plan, tuple(order))
    if plan.blocks and tick.index.kind_of(plan.steps[0]) in UNCONTROLLABLE:
        plan.taken.add(0)  # leading effects and automatics happen by themselves
        plan.remaining[0] = list(plan.blocks[0].steps)
    return plan


def startable(tick: Tick, plan: TransitionPlan) -> list[int]:
    """The blocks whose turn it is: not taken, every block they come after done."""
    done = plan.done
    return [
        k
        for k, block in enumerate(plan.blocks)
        if k not in plan.taken
        and block.after <= done
        and tick.index.kind_of(block.transition) in _STARTED_BY_US
    ]


def stuck(tick: Tick, plan: TransitionPlan, what: str) -> bool:
    """Nothing the plan waits for can happen any more: no block's turn has come and no
    effect or automatic step it expects is enabled (an effect that timed out counts as not
    enabled: it is disabled in planning).  A person's step that was under way
    when the plan was made can end before its block is taken; the plan would wait for it
    for ever.  Recovery and maintenance plans, which have no deviation check, use this to
    be made again; a stuck plan is said (a `blocked` event about `what`)."""
    if startable(tick, plan) or not plan.expected():
        return False
    current = tick.current()
    state = tick.state
    for name in plan.expected():
        owner = tick.index.station.owner_of(name)
        if owner in state.unavailable:
            return False  # it may yet happen (a resource may answer again)
        if name not in state.timed_out and tick.index.transition(name).guard(current):
            return False  # it may yet happen; one that timed out is disabled in planning,
            # so a plan made again goes without it (and waits again only once it is
            # re-enabled or seen to happen)
    waits = ", ".join(sorted(plan.expected()))
    tick.emit(EventKind.BLOCKED, what, why=f"{waits} can no longer happen")
    return True


def take(tick: Tick, plan: TransitionPlan, k: int, *, supervised: bool) -> bool:
    """Take block k's transition if the model (and, `supervised`, the supervisor) allow it
    now; whether it was taken.  A guard that does not hold yet is waited for quietly."""
    name = plan.blocks[k].transition
    chosen = tick.index.transition(name)
    why = held_back(tick, name)
    current = tick.current()
    if not why and not chosen.guard(current):
        return False
    after = chosen.apply(current)
    if not why and supervised and tick.runner.is_bad(after):
        why = "the supervisor holds it back: it would lead into a bad state"
        if plan is tick.state.transition_plan:  # a maintenance plan waits, or is stuck
            tick.replan_transitions(ReplanReason.DEVIATION)
    if why:
        if plan.held.get(k) != why:
            plan.held[k] = why
            tick.emit(EventKind.BLOCKED, name, step=k, why=why)
        return False
    tick.set_values(after)
    plan.start(k, enabled_in(tick, after))
    tick.emit(EventKind.TAKEN, name, type=chosen.kind.value)
    settle(tick)
    return True


def held_back(tick: Tick, name: str) -> str:
    """Why the model does not let the runner take transition `name` now ("" if it does):
    its resource does not answer, it is a restart ability outside restart mode, or an
    automatic transition goes first."""
    state = tick.state
    if name in disabled(tick):
        owner = tick.index.station.owner_of(name)
        if owner in state.cannot_act:
            return f"{owner} cannot act: {state.cannot_act[owner]}"
        if owner in state.unavailable:
            return f"{owner} is not answering"
        if name in state.timed_out:
            return "it did not happen in time and is disabled"
        return "a restart ability: it is used in restart mode only"
    current = tick.current()
    if automatic_enabled(tick, current):
        automatics = tick.index.semantics.automatic
        k = next(k for k, a in enumerate(automatics) if a.guard(current))
        if may_fire(tick, k, current):
            return f"automatic transition {automatics[k].name} is enabled and goes first"
        return (
            f"automatic transition {automatics[k].name} goes first and waits until what it"
            " reads is known again (a device does not answer)"
        )
    return ""


def plan_reaches(tick: Tick, plan: TransitionPlan) -> bool:
    """Simulate the rest of the plan from the current state: does it still reach the goal?

    Controlled steps are taken in the start order when their guards hold and the supervisor
    lets them (a step into a bad state waits, as at run time), the plan's effects happen
    when theirs do, automatic steps first.  A rest that gets stuck does not reach the goal.
    """
    semantics = tick.index.semantics
    index = tick.index
    current = tick.current()
    goal = index.compiled(plan.goal)
    simulated = TransitionPlan(
        plan.goal,
        plan.steps,
        plan.blocks,
        set(plan.taken),
        {k: list(v) for k, v in plan.remaining.items()},
        early=list(plan.early),
    )
    expected = set(plan.steps)
    planned_effects = [
        index.effects[k]
        for k in sorted(index.effect_position[n] for n in expected if n in index.effect_position)
    ]
    unusable = disabled(tick)
    for _ in range(2 * len(plan.steps) + 2):
        if goal(current):
            return True
        automatics = [a for a in semantics.automatic if a.guard(current)]
        if automatics:
            current = automatics[0].apply(current)
            simulated.happened(automatics[0].name)
            continue
        step = None
        for k in startable(tick, simulated):
            chosen = index.transition(plan.blocks[k].transition)
            if (
                chosen.kind is TransitionKind.CONTROLLED
                and chosen.guard(current)
                and not tick.runner.is_bad(chosen.apply(current))
            ):
                step = k
                break
        if step is not None:
            current = index.transition(plan.blocks[step].transition).apply(current)
            simulated.start(step, enabled_in(tick, current))
            continue
        waiting = [n for k in sorted(simulated.remaining) for n in simulated.remaining[k]]
        usable = [e for e in planned_effects if e.name not in unusable and e.guard(current)]
        effect = next((e for e in usable if e.name in waiting or not waiting), None)
        if effect is None:
            effect = next(iter(usable), None)
        if effect is None:
            return False
        current = effect.apply(current)
        simulated.happened(effect.name)
    return goal(current)


def enabled_in(tick: Tick, state: State) -> Callable[[str], bool]:
    """Whether a transition's guard holds in `state` (which early effects still count)."""
    return lambda name: tick.index.transition(name).guard(state)
