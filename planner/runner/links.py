"""Causal links of the operation plan, kept by the transition planner (DESIGN.md section 3.4).

With operations in parallel, the transition plan of the executing operations can undo
what a later operation needs: a robot that makes way for the other makes its camera forget
the tool it found, and the operation that was to take that tool can no longer start.  The
operation planner cannot see this (its model holds only the operations' preconditions and
effects); the transition planner can, once it is told what to keep.

A *link* is a part of the precondition of an operation that comes next in the partial order
(not started, every operation it comes after started or finished) that holds now and that
the operation plan leaves as it is until then (no operation it waits for changes it).  The
transition planner's query keeps every link (`PlanQuery.kept`): no state of the plan breaks
one or lets the world break one by itself, as the monotonic abstraction keeps other
operations' goals out (section 3.5) and the supervisor the specifications.

When no plan exists under the links but one does without them, an executing operation is
breaking one.  It is deferred (back to initial, and it waits for the operations whose links
it would break) rather than the operation that needs the link, and a `blocked` event says
so; an operation that a link's consumer itself waits for cannot be deferred (the consumer
would wait for ever), and when none can be, the plan is made without the links.  One
operation at a time (`sequential`) there are no links: the one executing is the plan.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from planner.model.expressions import Expr, conjuncts, format_expr, variables_of
from planner.runner.state import OperationPlan
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind, OperationState


@dataclass(frozen=True)
class Link:
    """`consumer` needs `condition`, which holds now and which the plan leaves standing."""

    consumer: str
    condition: Expr

    def __str__(self) -> str:
        return f"{format_expr(self.condition)} for {self.consumer}"


def protected_links(tick: Tick) -> tuple[Link, ...]:
    """The links the executing operations' transition plan must keep (module docstring)."""
    state = tick.state
    plan = state.operation_plan
    if plan is None or tick.config.sequential or not state.executing():
        return ()
    index = tick.index
    links = []
    for k, name in enumerate(plan.steps):
        if k in plan.started or not plan.after[k] <= plan.started:
            continue
        changed = set().union(*(_writes(tick, n) for n in waited_for(tick, plan, k)))
        for part in conjuncts(index.operations[name].precondition):
            if not variables_of(part) & changed and index.holds(part, state.values):
                links.append(Link(name, part))
    return tuple(dict.fromkeys(links))


def conditions(links: Iterable[Link]) -> tuple[Expr, ...]:
    """What a plan keeps for the links (`PlanQuery.kept`)."""
    return tuple(dict.fromkeys(link.condition for link in links))


def waited_for(tick: Tick, plan: OperationPlan, k: int) -> set[str]:
    """The operations step k of the plan waits for, at any remove: those it comes after in
    the plan (and what they wait for), and the executing operations any of them shares a
    variable with (`operations.start_operations` holds them back for those)."""
    index = tick.index
    executing = tick.state.executing()
    seen: set[int] = set()
    todo = [k]
    while todo:
        j = todo.pop()
        for i in plan.after[j]:
            if i not in seen and i not in plan.finished:
                seen.add(i)
                todo.append(i)
    names = {plan.steps[i] for i in seen}
    for name in [plan.steps[k], *names]:
        mine = index.operation_variables[name]
        names |= {e for e in executing if e != name and index.operation_variables[e] & mine}
    return names - {plan.steps[k]}


def deferrable(tick: Tick, links: tuple[Link, ...]) -> list[str]:
    """The executing operations that may be deferred for the links: in the operation plan
    (so that it starts them again), and waited for by no link's consumer.  The last started
    first: what began last has done least."""
    plan = tick.state.operation_plan
    if plan is None:
        return []
    position = {name: k for k, name in enumerate(plan.steps)}
    needed: set[str] = set()
    for link in links:
        needed |= waited_for(tick, plan, position[link.consumer])
    return [
        name
        for name in reversed(tick.state.executing())
        if name in position and position[name] in plan.started and name not in needed
    ]


def defer(tick: Tick, name: str, links: tuple[Link, ...]) -> None:
    """`name` goes back to initial and waits, in the operation plan, for the operations
    whose links its transitions would break."""
    state = tick.state
    plan = state.operation_plan
    assert plan is not None
    position = {step: k for k, step in enumerate(plan.steps)}
    k = next(j for j in sorted(plan.started - plan.finished) if plan.steps[j] == name)
    consumers = sorted({position[link.consumer] for link in links})
    plan.after = tuple(a | frozenset(consumers) if j == k else a for j, a in enumerate(plan.after))
    plan.started.discard(k)
    state.operation_goals.pop(name, None)
    kept = "; ".join(str(link) for link in links)
    why = f"it would undo what the next operations need ({kept}): it waits for them"
    tick.set_operation(name, OperationState.INITIAL, why)
    tick.emit(EventKind.BLOCKED, name, why=why, waits_for=[plan.steps[j] for j in consumers])


def _writes(tick: Tick, name: str) -> set[str]:
    return {a.target for a in tick.index.operations[name].effects}
