"""The supervisor's extra guards as readable expressions: what `sp check` prints.

Planning and the runner exclude the bad states of `planner.bdd.synthesis` directly; for
people, each controlled or maintenance transition that could step into one gets its extra
guard "does not lead into a bad state" written out over the model's variables, as an
irredundant sum of products (`planner.bdd.cover`).
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.bdd.cover import Cover
from planner.bdd.symbolic import Function, SymbolicModel
from planner.bdd.synthesis import COUNTABLE_BITS, automatic_guard, components
from planner.model.expressions import Expr, format_expr, negation
from planner.model.flat import TransitionKind


@dataclass(frozen=True)
class SupervisorGuard:
    """The extra guard of one transition, and the states it forbids that transition in."""

    transition: str
    guard: Expr
    forbidden_states: int | None  # None when too many to count

    def describe(self) -> str:
        return format_expr(self.guard)


def supervisor_guards(sym: SymbolicModel, bad: Function) -> list[SupervisorGuard]:
    """For each controlled or maintenance transition that could step into `bad`, its guard.

    The guard is simplified under the states where the transition can actually be taken
    (its own guard holds, no automatic transition is enabled, the state is not bad), so it
    says only what the specifications add.  There, whether the step leads into `bad`
    depends only on the components the transition writes and the variables it copies from
    (in the others the next state is the current, good one), so the guard is read over
    those variables alone: fewer variables, a shorter expression, a faster cover.
    """
    parts = [p for p in components(sym.model) if p.specifications]
    component_of = {name: k for k, p in enumerate(parts) for name in p.variables}
    automatic = automatic_guard(sym)
    good = ~automatic & ~bad & sym.valid
    cover = Cover(sym)
    result: list[SupervisorGuard] = []
    for t in sym.transitions:
        if t.kind not in (TransitionKind.CONTROLLED, TransitionKind.MAINTENANCE):
            continue
        care = t.guard & good
        forbidden = sym.preimage(t, bad) & care
        if forbidden == sym.false:
            continue
        relevant: set[str] = set()
        for action in t.transition.actions:
            if action.target in component_of:
                relevant.update(parts[component_of[action.target]].variables)
                if action.source is not None:
                    relevant.add(action.source)
        hidden = [
            b for v in sym.model.variables if v.name not in relevant for b in sym.bits[v.name]
        ]
        care_here = sym.bdd.exist(hidden, care) if hidden else care
        forbidden_here = sym.bdd.exist(hidden, forbidden) if hidden else forbidden
        guard = _readable(cover, care_here, forbidden_here)
        # all valid; CUDD counts in doubles, which overflow beyond 2^1024
        bits = len(sym.state_bits)
        states = int(sym.bdd.count(forbidden, nvars=bits)) if bits <= COUNTABLE_BITS else None
        result.append(SupervisorGuard(t.name, guard, states))
    return result


def _readable(cover: Cover, care: Function, forbidden: Function) -> Expr:
    """The shorter of: what is allowed, or "not" what is forbidden, each an irredundant sum
    of products that may use the states outside `care` (where the transition is not taken).

    Both covers are grown together, their number of products limited, so that one that
    needs many more products than the other is not finished (on the demo station those
    took a third of the time, for expressions of up to 290,000 characters).
    """
    allowed = (care & ~forbidden, ~forbidden)
    denied = (forbidden, forbidden | ~care)
    limit = 8
    while True:
        found: list[Expr] = []
        positive = cover.expr(*allowed, limit)
        if positive is not None:
            found.append(positive)
        negative = cover.expr(*denied, limit)
        if negative is not None:
            found.append(negation(negative))
        if found:
            return min(found, key=lambda e: len(format_expr(e)))
        limit *= 4
