"""Supervisor synthesis by guard extraction (seed 000 sec. 3, seed 001 VI-B).

The forbidden states of the specifications are extended backwards over uncontrollable steps
(automatic, and effect where no automatic is enabled) into the *bad* states; every controlled
and maintenance transition then gets the extra guard "does not lead into a bad state".
Following those guards keeps the runner out of bad states whatever the world does; planning
excludes bad states directly, which is equivalent for plans.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from planner.expressions import (
    BoolVar,
    Equals,
    Expr,
    Not,
    Value,
    conjunction,
    disjunction,
    format_expr,
    negation,
)
from planner.model import Specification, TransitionKind
from planner.symbolic import Function, SymbolicModel, SymbolicTransition


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
        dont_care = ~care
        # the shortest of: what is allowed, or "not" what is forbidden, each as an
        # irredundant sum of products that may use the states where t cannot be taken
        positive = cover_expr(sym, ~forbidden & care, ~forbidden | dont_care)
        negative = negation(cover_expr(sym, forbidden, forbidden | dont_care))
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


def cover_expr(sym: SymbolicModel, lower: Function, upper: Function) -> Expr:
    """A short expression true on all of `lower` and nowhere outside `upper`.

    An irredundant sum of products between the two bounds (Minato-Morreale ISOP), whose
    cubes over bits are read back as literals over the model's variables.
    """
    terms = [_cube_literals(sym, cube) for cube in isop(sym, lower, upper)]
    if len(terms) < 2:
        return disjunction([conjunction(t) for t in terms])
    common = [lit for lit in terms[0] if all(lit in t for t in terms[1:])]
    rest = [conjunction([lit for lit in t if lit not in common]) for t in terms]
    return conjunction([*common, disjunction(rest)])


def isop(sym: SymbolicModel, lower: Function, upper: Function) -> list[dict[str, bool]]:
    """Irredundant cubes covering `lower` within `upper` (requires lower <= upper)."""
    bdd = sym.bdd
    memo: dict[tuple[Function, Function], tuple[list[dict[str, bool]], Function]] = {}

    def level(u: Function) -> int:
        return 1 << 30 if u in (sym.true, sym.false) else int(bdd.level_of_var(u.var))

    def go(low: Function, up: Function) -> tuple[list[dict[str, bool]], Function]:
        if low == sym.false:
            return [], sym.false
        if up == sym.true:
            return [{}], sym.true
        key = (low, up)
        if key in memo:
            return memo[key]
        var = bdd.var_at_level(min(level(low), level(up)))
        l0, l1 = bdd.let({var: False}, low), bdd.let({var: True}, low)
        u0, u1 = bdd.let({var: False}, up), bdd.let({var: True}, up)
        c0, f0 = go(l0 & ~u1, u0)
        c1, f1 = go(l1 & ~u0, u1)
        cd, fd = go((l0 & ~f0) | (l1 & ~f1), u0 & u1)
        x = bdd.var(var)
        cubes = [{**c, var: False} for c in c0] + [{**c, var: True} for c in c1] + cd
        result = (cubes, (~x & f0) | (x & f1) | fd)
        memo[key] = result
        return result

    return go(lower, upper)[0]


def _cube_literals(sym: SymbolicModel, cube: dict[str, bool]) -> list[Expr]:
    """A cube over bits as literals, one per variable it constrains."""
    literals: list[Expr] = []
    for variable in sym.model.variables:
        bits = sym.bits[variable.name]
        if not any(b in cube for b in bits):
            continue
        values = [
            value
            for value in variable.domain
            if all(cube.get(b, bit) == bit for b, bit in sym.code(variable.name, value).items())
        ]
        if len(values) < len(variable.domain):
            literals.append(_literal(variable.name, variable.domain, values))
    return literals


def _literal(name: str, domain: tuple[Value, ...], values: Sequence[Value]) -> Expr:
    """`x == v`, `x != v`, `flag`, `!flag`, or a short disjunction, for a set of values."""
    if domain == (False, True):
        return BoolVar(name) if list(values) == [True] else Not(BoolVar(name))
    if len(values) == 1:
        return Equals(name, values[0])
    others = [v for v in domain if v not in values]
    if len(others) < len(values):
        return conjunction([Not(Equals(name, v)) for v in others])
    return disjunction([Equals(name, v) for v in values])
