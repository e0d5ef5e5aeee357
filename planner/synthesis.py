"""Supervisor synthesis by guard extraction (seed 000 sec. 3, seed 001 VI-B).

The forbidden states of the specifications are extended backwards over uncontrollable steps
(automatic, and effect where no automatic is enabled) into the *bad* states; every controlled
and maintenance transition then gets the extra guard "does not lead into a bad state".
Following those guards keeps the runner out of bad states whatever the world does; planning
excludes bad states directly, which is equivalent for plans.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from planner.expressions import (
    FALSE,
    TRUE,
    BoolVar,
    Equals,
    Expr,
    Not,
    conjunction,
    disjunction,
    format_expr,
    negation,
)
from planner.model import Specification, TransitionKind
from planner.symbolic import Function, SymbolicModel, SymbolicTransition, cudd


def automatic_guard(sym: SymbolicModel, disabled: frozenset[str] = frozenset()) -> Function:
    """States where some (not disabled) automatic transition is enabled."""
    result = sym.false
    for t in sym.transitions:
        if t.kind is TransitionKind.AUTOMATIC and t.name not in disabled:
            result |= t.guard
    return result


def uncontrollable_preimage(sym: SymbolicModel, states: Function, automatic: Function) -> Function:
    """Valid states with an automatic or effect step into `states` (section 8 step rule)."""
    by_automatic = sym.false
    by_effect = sym.false
    for t in sym.transitions:
        if t.kind is TransitionKind.AUTOMATIC:
            by_automatic |= sym.preimage(t, states)
        elif t.kind is TransitionKind.EFFECT:
            by_effect |= sym.preimage(t, states)
    return (by_automatic | (by_effect & ~automatic)) & sym.valid


def backward_closure(sym: SymbolicModel, states: Function) -> Function:
    """`states` and every valid state that uncontrollable steps can carry into them."""
    automatic = automatic_guard(sym)
    closure = states & sym.valid
    frontier = closure
    while frontier != sym.false:
        frontier = uncontrollable_preimage(sym, frontier, automatic) & ~closure
        closure |= frontier
    return closure


def violations(sym: SymbolicModel, specifications: Iterable[Specification]) -> Function:
    result = sym.false
    for spec in specifications:
        result |= ~sym.expr(spec.invariant)
    return result & sym.valid


def bad_states(sym: SymbolicModel) -> Function:
    return backward_closure(sym, violations(sym, sym.model.specifications))


def violated_by(sym: SymbolicModel, state: Function) -> list[str]:
    """Specifications the state is bad for, each on its own (the bad set is their union)."""
    return [
        spec.name
        for spec in sym.model.specifications
        if backward_closure(sym, violations(sym, [spec])) & state != sym.false
    ]


@dataclass(frozen=True)
class SupervisorGuard:
    """The extra guard of one transition, and the states it forbids that transition in."""

    transition: str
    guard: Expr
    forbidden_states: int

    def describe(self) -> str:
        return format_expr(self.guard)


def supervisor_guards(sym: SymbolicModel, bad: Function) -> list[SupervisorGuard]:
    """For each controlled or maintenance transition that could step into `bad`, its guard.

    The guard is simplified under the states where the transition can actually be taken
    (its own guard holds, no automatic transition is enabled, the state is not bad), so it
    says only what the specifications add.
    """
    automatic = automatic_guard(sym)
    result: list[SupervisorGuard] = []
    for t in sym.transitions:
        if t.kind not in (TransitionKind.CONTROLLED, TransitionKind.MAINTENANCE):
            continue
        care = t.guard & ~automatic & ~bad & sym.valid
        forbidden = sym.preimage(t, bad) & care
        if forbidden == sym.false:
            continue
        allowed = cudd.restrict(~forbidden, care)
        positive = to_expr(sym, allowed)
        negative = negation(to_expr(sym, cudd.restrict(forbidden, care)))
        guard = min(positive, negative, key=lambda e: len(format_expr(e)))
        result.append(SupervisorGuard(t.name, guard, sym.count(forbidden)))
    return result


def automatic_cycle(sym: SymbolicModel) -> tuple[list[str], Function] | None:
    """A cycle of automatic transitions, as transition names and the states on it, or None.

    The greatest set of states from which automatic steps can go on forever is computed as a
    fixpoint; one concrete cycle is then walked from a state in it.
    """
    autos = [t for t in sym.transitions if t.kind is TransitionKind.AUTOMATIC]
    if not autos:
        return None
    looping = automatic_guard(sym) & sym.valid
    while True:
        keep = sym.false
        for t in autos:
            keep |= sym.preimage(t, looping)
        keep &= looping
        if keep == looping:
            break
        looping = keep
    if looping == sym.false:
        return None
    state = sym.pick(looping)
    seen: list[tuple[object, str]] = []
    while True:
        current = sym.state(state)
        step = _next_looping_step(sym, autos, current, looping)
        key = (state, step.name)
        if key in seen:
            cycle = [name for _, name in seen[seen.index(key) :]]
            return cycle, looping
        seen.append(key)
        state = sym.pick(sym.image(step, current))


def _next_looping_step(
    sym: SymbolicModel, autos: list[SymbolicTransition], current: Function, looping: Function
) -> SymbolicTransition:
    for t in autos:
        if sym.image(t, current) & looping != sym.false:
            return t
    raise AssertionError("a state in the looping set has no looping step")


# ---- readable predicates from BDDs -----------------------------------------------------------


def to_expr(sym: SymbolicModel, u: Function) -> Expr:
    """An expression over the model's variables equivalent to `u` on valid states.

    Walks the variables in order; at each, values that lead to the same sub-function are
    grouped into one literal (`x == a`, `x != b`, `!flag`), so guards read as the engineer
    would write them rather than as bits.
    """
    involved = {bit for bit in sym.bdd.support(u)}
    variables = [v for v in sym.model.variables if involved.intersection(sym.bits[v.name])]
    memo: dict[tuple[int, int], Expr] = {}

    def walk(node: Function, depth: int) -> Expr:
        if node == sym.true:
            return TRUE
        if node == sym.false:
            return FALSE
        key = (int(node), depth)
        if key in memo:
            return memo[key]
        variable = variables[depth]
        groups: dict[Function, list[object]] = {}
        for value in variable.domain:
            cofactor = sym.bdd.let(sym.code(variable.name, value), node)
            groups.setdefault(cofactor, []).append(value)
        if len(groups) == 1:
            result = walk(next(iter(groups)), depth + 1)
        else:
            terms = []
            for sub, values in groups.items():
                if sub == sym.false:
                    continue
                literal = _literal(variable.name, variable.domain, values)
                terms.append(conjunction([literal, walk(sub, depth + 1)]))
            result = disjunction(terms)
        memo[key] = result
        return result

    return walk(u, 0)


def _literal(name: str, domain: tuple[object, ...], values: list[object]) -> Expr:
    if domain == (False, True):
        return BoolVar(name) if values == [True] else Not(BoolVar(name))
    if len(values) == 1:
        return Equals(name, values[0])  # type: ignore[arg-type]
    others = [v for v in domain if v not in values]
    if len(others) < len(values):
        return conjunction([Not(Equals(name, v)) for v in others])  # type: ignore[arg-type]
    return disjunction([Equals(name, v) for v in values])  # type: ignore[arg-type]
