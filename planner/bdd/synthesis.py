"""Supervisor synthesis by guard extraction (seed 000 sec. 3, seed 001 VI-B).

The forbidden states of the specifications are extended backwards over uncontrollable steps
(automatic, and effect where no automatic is enabled) into the *bad* states; every controlled
and maintenance transition then gets the extra guard "does not lead into a bad state".
Following those guards keeps the runner out of bad states whatever the world does; planning
excludes bad states directly, which is equivalent for plans (`planner.bdd.guards` writes the
guards out for people).

Synthesis works one *component* at a time: the variables tied together by the automatic and
effect transitions (what each reads or writes) and by the specifications.  A station of
independent cells has one component per cell, and each closure stays within a few bits
instead of walking the product of all cells (see `bad_states` for why this is exact).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from planner.bdd.symbolic import Function, SymbolicModel, SymbolicTransition
from planner.model.coupling import Groups, touched
from planner.model.expressions import Equals, Expr, variables_of
from planner.model.flat import UNCONTROLLABLE, Model, Specification, TransitionKind

# states are counted over at most this many bits: CUDD counts in doubles, which overflow
# beyond 2^1024 (the supervisor's guards, the planners' statistics, `sp check`)
COUNTABLE_BITS = 1000


def automatic_guard(sym: SymbolicModel, disabled: frozenset[str] = frozenset()) -> Function:
    """States where some (not disabled) automatic transition is enabled."""
    result = sym.false
    for t in sym.transitions:
        if t.kind is TransitionKind.AUTOMATIC and t.name not in disabled:
            result |= t.guard
    return result


@dataclass(frozen=True, slots=True)
class Component:
    """Variables that uncontrollable transitions and specifications tie together."""

    variables: tuple[str, ...]
    transitions: tuple[str, ...]  # its automatic and effect transitions, in model order
    specifications: tuple[Specification, ...]


def components(model: Model) -> tuple[Component, ...]:
    """The model's components, in the order of their first variables.

    A transition or specification over no variable belongs to none: such a transition has
    no actions and a constant guard, a self-loop that adds no bad state (or, if automatic
    and enabled, a cycle that loading rejects); a constant specification is collected in a
    last component without variables.
    """
    groups = Groups(v.name for v in model.variables)
    uncontrollable = [
        t for t in model.transitions if t.kind in (TransitionKind.AUTOMATIC, TransitionKind.EFFECT)
    ]
    for t in uncontrollable:
        groups.join(touched(t))
    for spec in model.specifications:
        groups.join(variables_of(spec.invariant))
    members = groups.members()
    find = groups.find
    steps: dict[str, list[str]] = {root: [] for root in members}
    for t in uncontrollable:
        read_or_written = touched(t)
        if read_or_written:
            steps[find(min(read_or_written))].append(t.name)
    specs: dict[str, list[Specification]] = {root: [] for root in members}
    constant: list[Specification] = []
    for spec in model.specifications:
        read = variables_of(spec.invariant)
        (specs[find(min(read))] if read else constant).append(spec)
    result = [
        Component(tuple(names), tuple(steps[root]), tuple(specs[root]))
        for root, names in members.items()
    ]
    if constant:
        result.append(Component((), (), tuple(constant)))
    return tuple(result)


@dataclass(frozen=True, slots=True)
class _Step:
    """An uncontrollable transition prepared for preimages.

    `substitution` (bit -> constant or bit it copies) is applied one bit at a time, which
    is exact when no copied bit is also written; `dd`'s multi-bit substitution and cube
    building cost a pass over every declared bit, which dominates on large models.
    """

    transition: SymbolicTransition
    guard: Function
    substitution: tuple[tuple[str, Function], ...] | None  # None: use sym.preimage

    def preimage(self, sym: SymbolicModel, states: Function) -> Function:
        if self.substitution is None:
            return sym.preimage(self.transition, states)
        for bit, value in self.substitution:
            states = sym.bdd.let({bit: value}, states)
        return states & self.guard


def _step(sym: SymbolicModel, t: SymbolicTransition) -> _Step:
    written = t.transition.written
    substitution: list[tuple[str, Function]] = []
    for action in t.transition.actions:
        bits = sym.bits[action.target]
        if action.source is None:
            assert action.value is not None
            code = sym.code(action.target, action.value)
            substitution += [(b, sym.true if code[b] else sym.false) for b in bits]
        elif action.source in written:  # a swap: needs the simultaneous substitution
            return _Step(t, t.guard, None)
        else:
            substitution += [
                (b, sym.bdd.var(s)) for b, s in zip(bits, sym.bits[action.source], strict=True)
            ]
    return _Step(t, t.guard, tuple(substitution))


class _Closure:
    """Backward closure over a set of automatic and effect transitions (section 8 steps).

    Chained: each transition's preimage joins the closure at once, and rounds repeat until
    nothing changes.  The fixpoint is the same as the breadth-first one, in far fewer
    rounds: a breadth-first frontier advances one distance layer per round, and with
    independent parts whose automatics can all be enabled together that is one layer per part.
    """

    def __init__(self, sym: SymbolicModel, transitions: Iterable[str], valid: Function) -> None:
        self.sym = sym
        chosen = [sym.by_name[name] for name in transitions]
        self.automatic = [_step(sym, t) for t in chosen if t.kind is TransitionKind.AUTOMATIC]
        self.effects = [_step(sym, t) for t in chosen if t.kind is TransitionKind.EFFECT]
        enabled = sym.false
        for step in self.automatic:
            enabled |= step.guard
        self.valid = valid
        self.free = valid & ~enabled  # effects happen only where no automatic is enabled

    def __call__(self, states: Function) -> Function:
        sym = self.sym
        closure = states & self.valid
        while True:
            before = closure
            for step in self.automatic:
                closure |= step.preimage(sym, closure) & self.valid
            for step in self.effects:
                closure |= step.preimage(sym, closure) & self.free
            if closure == before:
                return closure


def breaking(sym: SymbolicModel, predicate: Expr) -> Function:
    """The states where `predicate` is false, or from which a chain of automatic and effect
    steps leads to one: what a plan must avoid to keep `predicate` whatever the world does
    (a causal link, `PlanQuery.kept`), as the bad states are for the specifications.

    Closed over the uncontrollable transitions that can change what it reads, and what
    their guards read, to a fixpoint; the closure over fewer automatics than the whole
    model's lets effects happen in a few states where an automatic would go first, which
    only widens the set (the plan stays safe)."""
    uncontrollable = [t for t in sym.model.transitions if t.kind in UNCONTROLLABLE]
    cone = set(variables_of(predicate))
    chosen: dict[str, None] = {}
    changed = True
    while changed:
        changed = False
        for t in uncontrollable:
            if t.name not in chosen and t.written & cone:
                chosen[t.name] = None
                reads = variables_of(t.guard) | {a.source for a in t.actions if a.source}
                cone |= reads | t.written
                changed = True
    close = _Closure(sym, chosen, valid_codes(sym, cone))
    return close(~sym.expr(predicate))


def valid_codes(sym: SymbolicModel, variables: Iterable[str]) -> Function:
    """States whose bits encode values of these variables' domains (the others are free)."""
    result = sym.true
    for name in variables:
        domain = sym.model.variable(name).domain
        if len(domain) < 1 << len(sym.bits[name]):
            codes = sym.false
            for value in domain:
                codes |= sym.expr(Equals(name, value))
            result &= codes
    return result


def backward_closure(sym: SymbolicModel, states: Function) -> Function:
    """`states` and every valid state that uncontrollable steps can carry into them.

    Over the whole model at once: the reference that componentwise synthesis must equal.
    """
    uncontrollable = (TransitionKind.AUTOMATIC, TransitionKind.EFFECT)
    names = [t.name for t in sym.transitions if t.kind in uncontrollable]
    return _Closure(sym, names, sym.valid)(states)


def violations(sym: SymbolicModel, specifications: Iterable[Specification]) -> Function:
    result = sym.false
    for spec in specifications:
        result |= ~sym.expr(spec.invariant)
    return result & sym.valid


@dataclass(frozen=True, slots=True)
class BadPart:
    """The bad states of one component (a set over its bits only)."""

    component: Component
    states: Function


def bad_parts(
    sym: SymbolicModel, by_specification: Mapping[str, Function] | None = None
) -> list[BadPart]:
    """Each component's bad states, each specification closed on its own (see `bad_states`);
    `by_specification` when `bad_by_specification` was already computed."""
    if by_specification is None:
        by_specification = bad_by_specification(sym)
    result: list[BadPart] = []
    for part in components(sym.model):
        if part.specifications:
            closed = [by_specification[spec.name] for spec in part.specifications]
            result.append(BadPart(part, _disjoin(sym, closed)))
    return result


def bad_by_specification(sym: SymbolicModel) -> dict[str, Function]:
    """For each specification, the states bad for it alone: its violations closed over the
    uncontrollable transitions of its component (the bad states are the union of these)."""
    result: dict[str, Function] = {}
    for part in components(sym.model):
        if part.specifications:
            close = _Closure(sym, part.transitions, valid_codes(sym, part.variables))
            for spec in part.specifications:
                result[spec.name] = close(~sym.expr(spec.invariant))
    return result


def bad_states(sym: SymbolicModel, parts: Sequence[BadPart] | None = None) -> Function:
    """The bad states: the union of each component's own (`parts`, if already computed).

    Exact under the section 8 step rule although automatic priority is global, provided no
    automatic cycle exists (loading rejects them, `check_dynamics`).  Split the state into
    a component's part c and the rest r:

    - if c's own steps (its automatics; its effects where none of its automatics is
      enabled) carry c into a violation of one of its specifications, steps of the whole
      model carry (c, r) there too: before each effect of c's chain, take the rest's
      enabled automatics until none is enabled (finitely many, as they cannot cycle; they
      leave c as it is), and the effect is then a step of the whole model;
    - conversely, a chain of the whole model into such a violation, restricted to c's
      transitions, is a chain of c alone: the other steps leave c as it is, and an effect
      taken where no automatic is enabled anywhere is taken where none of c's is.

    Controlled and maintenance transitions play no part.  Within a component each
    specification is closed on its own (the closure of a union is the union of the
    closures), which keeps the BDDs small: on the demo station the closures of single
    specifications have a few hundred nodes, their union tens of thousands.
    """
    if parts is None:
        parts = bad_parts(sym)
    return _disjoin(sym, [part.states for part in parts]) & sym.valid


def _disjoin(sym: SymbolicModel, parts: Sequence[Function]) -> Function:
    """The union, joined pairwise: on many independent parts, each join stays small."""
    if not parts:
        return sym.false
    layer = list(parts)
    while len(layer) > 1:
        layer = [a | b for a, b in zip(layer[::2], layer[1::2], strict=False)] + (
            [layer[-1]] if len(layer) % 2 else []
        )
    return layer[0]


def violated_by(sym: SymbolicModel, state: Function) -> list[str]:
    """Specifications the state is bad for, each on its own (the bad set is their union)."""
    bad = bad_by_specification(sym)
    return [
        spec.name
        for spec in sym.model.specifications
        if spec.name in bad and bad[spec.name] & state & sym.valid != sym.false
    ]


def automatic_cycle(sym: SymbolicModel) -> tuple[list[str], Function] | None:
    """A cycle of automatic transitions, as transition names and the states on it, or None.

    Per component: an endless run of automatic steps makes endlessly many steps in some
    component, and those alone are an endless run of that component (the other steps leave
    it as it is); an endless run of one component is one of the whole model, as automatic
    steps are always possible when enabled.  In each, the greatest set of states from which
    automatic steps can go on forever is a fixpoint; one concrete cycle is then walked from
    a state in it.
    """
    for part in components(sym.model):
        autos = [
            sym.by_name[name]
            for name in part.transitions
            if sym.by_name[name].kind is TransitionKind.AUTOMATIC
        ]
        if not autos:
            continue
        steps = [_step(sym, t) for t in autos]
        enabled = sym.false
        for step in steps:
            enabled |= step.guard
        looping = enabled & valid_codes(sym, part.variables)
        while True:
            keep = sym.false
            for step in steps:
                keep |= step.preimage(sym, looping)
            keep &= looping
            if keep == looping:
                break
            looping = keep
        if looping != sym.false:
            return _walk_cycle(sym, autos, looping), looping
    return None


def _walk_cycle(
    sym: SymbolicModel, autos: list[SymbolicTransition], looping: Function
) -> list[str]:
    state = sym.pick(looping)
    seen: list[tuple[object, str]] = []
    while True:
        current = sym.state(state)
        step = _next_looping_step(sym, autos, current, looping)
        key = (state, step.name)
        if key in seen:
            return [name for _, name in seen[seen.index(key) :]]
        seen.append(key)
        state = sym.pick(sym.image(step, current))


def _next_looping_step(
    sym: SymbolicModel, autos: list[SymbolicTransition], current: Function, looping: Function
) -> SymbolicTransition:
    for t in autos:
        if sym.image(t, current) & looping != sym.false:
            return t
    raise AssertionError("a state in the looping set has no looping step")
