"""The step semantics on concrete states (DESIGN.md sections 3 and 8), compiled for speed.

This is the one definition of "which steps are possible" for concrete states: the runner, the
simulated world and plan replay all use it, and property tests check the symbolic planners
against it.  A `State` is a tuple of values in the model's variable order.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

from planner.model.expressions import (
    And,
    Assign,
    BoolVar,
    Const,
    Equals,
    Expr,
    Implies,
    Not,
    Or,
    SameValue,
    Value,
)
from planner.model.flat import Model, Transition, TransitionKind

State = tuple[Value, ...]
Predicate = Callable[[State], bool]


def compile_expr(expr: Expr, index: Mapping[str, int]) -> Predicate:
    """A closure that evaluates `expr` on a state tuple."""
    match expr:
        case Const(value):
            return (lambda s: True) if value else (lambda s: False)
        case BoolVar(name):
            i = index[name]
            return lambda s: s[i] is True
        case Equals(name, value):
            i = index[name]
            return lambda s: s[i] == value
        case SameValue(left, right):
            i, j = index[left], index[right]
            return lambda s: s[i] == s[j]
        case Not(arg):
            inner = compile_expr(arg, index)
            return lambda s: not inner(s)
        case And(args):
            parts = tuple(compile_expr(a, index) for a in args)
            return lambda s: all(p(s) for p in parts)
        case Or(args):
            parts = tuple(compile_expr(a, index) for a in args)
            return lambda s: any(p(s) for p in parts)
        case Implies(left, right):
            lhs, rhs = compile_expr(left, index), compile_expr(right, index)
            return lambda s: (not lhs(s)) or rhs(s)
    raise TypeError(expr)


def compile_actions(
    actions: Iterable[Assign], index: Mapping[str, int]
) -> Callable[[State], State]:
    """A closure applying all actions, each reading the state before the transition."""
    writes: list[tuple[int, int | None, Value | None]] = []
    for action in actions:
        source = index[action.source] if action.source is not None else None
        writes.append((index[action.target], source, action.value))

    def apply(state: State) -> State:
        values = list(state)
        for target, source, value in writes:
            values[target] = state[source] if source is not None else value  # type: ignore[assignment]
        return tuple(values)

    return apply


def _lazy_guard(t: Transition, extra: Expr | None, index: Mapping[str, int]) -> Predicate:
    compiled: list[Predicate] = []

    def guard(state: State) -> bool:
        if not compiled:
            compiled.append(Semantics._guard(t, extra, index))
        return compiled[0](state)

    return guard


@dataclass(frozen=True, slots=True)
class CompiledTransition:
    transition: Transition
    guard: Predicate
    apply: Callable[[State], State]

    @property
    def name(self) -> str:
        return self.transition.name

    @property
    def kind(self) -> TransitionKind:
        return self.transition.kind


class Semantics:
    """Possible steps of a model on concrete states.

    `extra_guards` (e.g. the supervisor's) are conjoined with the model's guards; they are
    what the runner enforces, while planning instead excludes bad states (equivalent for
    plans).
    """

    def __init__(
        self, model: Model, extra_guards: Mapping[str, Expr] | None = None, lazy: bool = False
    ) -> None:
        """`lazy`: compile each guard when it is first asked (a planner of a model of
        thousands of transitions asks few of them; the runner asks them all every tick)."""
        self.model = model
        index = model.variable_index
        extra = extra_guards or {}
        guard = _lazy_guard if lazy else self._guard
        self.transitions: tuple[CompiledTransition, ...] = tuple(
            CompiledTransition(
                t, guard(t, extra.get(t.name), index), compile_actions(t.actions, index)
            )
            for t in model.transitions
        )
        self.by_name = {c.name: c for c in self.transitions}
        self.automatic = tuple(c for c in self.transitions if c.kind is TransitionKind.AUTOMATIC)
        self.invariants = tuple(
            (s.name, compile_expr(s.invariant, index)) for s in model.specifications
        )

    @staticmethod
    def _guard(t: Transition, extra: Expr | None, index: Mapping[str, int]) -> Predicate:
        guard = compile_expr(t.guard, index)
        if extra is None:
            return guard
        more = compile_expr(extra, index)
        return lambda s: guard(s) and more(s)

    def state(self, values: Mapping[str, Value]) -> State:
        return tuple(values[v.name] for v in self.model.variables)

    def values(self, state: State) -> dict[str, Value]:
        return {v.name: state[i] for i, v in enumerate(self.model.variables)}

    def initial_state(self) -> State:
        return tuple(v.initial for v in self.model.variables)

    def automatic_enabled(self, state: State) -> bool:
        return any(a.guard(state) for a in self.automatic)

    def steps(
        self,
        state: State,
        *,
        maintenance: bool = False,
        disabled: frozenset[str] = frozenset(),
    ) -> list[tuple[CompiledTransition, State]]:
        """Every possible step from `state`: automatic ones first and alone if any is enabled."""
        autos = [a for a in self.automatic if a.name not in disabled and a.guard(state)]
        if autos:
            return [(a, a.apply(state)) for a in autos]
        result = []
        for c in self.transitions:
            if c.name in disabled or c.kind is TransitionKind.AUTOMATIC:
                continue
            if c.kind is TransitionKind.MAINTENANCE and not maintenance:
                continue
            if c.guard(state):
                result.append((c, c.apply(state)))
        return result

    def violated(self, state: State) -> list[str]:
        """Names of the specifications `state` violates directly."""
        return [name for name, holds in self.invariants if not holds(state)]

    def step_allowed(
        self,
        state: State,
        name: str,
        *,
        maintenance: bool = False,
        disabled: frozenset[str] = frozenset(),
        enabled_automatic: Sequence[str] | None = None,
    ) -> str | None:
        """None if transition `name` is a possible step from `state`, else the reason why not.

        `enabled_automatic`: the usable automatic transitions enabled in `state`, when the
        caller keeps track of them (replaying a plan over a large model); else computed."""
        chosen = self.by_name.get(name)
        if chosen is None:
            return f"there is no transition '{name}'"
        if name in disabled:
            return f"'{name}' is disabled"
        if chosen.kind is TransitionKind.MAINTENANCE and not maintenance:
            return f"'{name}' is a maintenance transition and maintenance is not allowed"
        if not chosen.guard(state):
            return f"the guard of '{name}' does not hold"
        if chosen.kind is not TransitionKind.AUTOMATIC:
            blocking = (
                list(enabled_automatic)
                if enabled_automatic is not None
                else [a.name for a in self.automatic if a.name not in disabled and a.guard(state)]
            )
            if blocking:
                return f"automatic transition '{blocking[0]}' is enabled and goes first"
        return None
