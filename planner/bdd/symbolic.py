"""The model on BDDs (CUDD through `dd`): sets of states, and images over transitions.

Each variable is log-encoded (bit 0 is the most significant bit of the value's index in its
domain).  Images are computed per transition, never with a monolithic relation: a transition
only writes a few variables, so `img_t(S) = (exists W. S & g_t) & post_t` for constant
assignments, and `pre_t(Z) = g_t & Z[W := actions]` by (vector) composition.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from planner.bdd.ordering import variable_order
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


def _import_cudd() -> Any:
    """Import `dd.cudd` without networkx, which `dd` loads (~140 ms) only for graph export."""
    if "networkx" in sys.modules:
        import dd.cudd

        return dd.cudd
    sys.modules["networkx"] = None  # type: ignore[assignment]  # makes `import networkx` fail
    try:
        import dd.cudd
    finally:
        del sys.modules["networkx"]
    return dd.cudd


cudd = _import_cudd()

Function = Any  # dd.cudd.Function: a BDD node
MEMORY_TARGET = 192 * 2**20  # bytes
CACHE_ENTRIES = 2**21  # CUDD's computed table, at most
State = tuple[Value, ...]


@dataclass(frozen=True, slots=True)
class SymbolicTransition:
    transition: Transition
    guard: Function
    written_bits: tuple[str, ...]
    post: Function | None  # constraint on the written bits after the step; None: use `relation`
    relation: Function | None  # general case: guard-free relation over primed written bits
    primes: Mapping[str, str]  # primed bit -> bit, for `relation`
    substitution: Mapping[str, Any]  # bit -> bool or node, for preimages

    @property
    def name(self) -> str:
        return self.transition.name

    @property
    def kind(self) -> TransitionKind:
        return self.transition.kind


class SymbolicModel:
    """A model's variables as BDD bits, its predicates as BDDs, its transitions as images."""

    def __init__(self, model: Model, order: Sequence[str] | None = None) -> None:
        """`order`: the bits' order to declare (a saved, tuned one; ValueError when it is not
        this model's), instead of the static FORCE order computed from the model."""
        self.model = model
        # CUDD grows its tables up to the memory it is told of (dd's default: 1 GB) before it
        # collects garbage instead; a target keeps a long search near it at a small cost in
        # time (the demo's 95-step goal: 201 MB instead of 587 MB, as fast), and is no limit
        # (a search that needs more live nodes gets them)
        self.bdd = cudd.BDD(memory_estimate=MEMORY_TARGET)
        self.bdd.configure(max_cache_hard=CACHE_ENTRIES)
        # Dynamic reordering fires on node-count thresholds that depend on the order `dd`
        # builds cubes in (hash-seed dependent), which would make plans vary between runs;
        # `sift` reorders at fixed points instead.
        self.bdd.configure(reordering=False)
        self.bits: dict[str, tuple[str, ...]] = {}
        for i, variable in enumerate(model.variables):
            width = max(1, (len(variable.domain) - 1).bit_length())
            names = tuple(f"v{i}_{j}" for j in range(width))
            self.bits[variable.name] = names
        self.state_bits: tuple[str, ...] = tuple(b for bits in self.bits.values() for b in bits)
        if order is not None and sorted(order) != sorted(self.state_bits):
            raise ValueError("the saved variable order does not match this model's bits")
        self.bdd.declare(*(variable_order(model, self.bits) if order is None else order))
        self.true: Function = self.bdd.true
        self.false: Function = self.bdd.false
        self._value_cache: dict[tuple[str, Value], Function] = {}
        # each value's cube from its literals: `bdd.cube` costs a pass over every declared
        # bit, which dominated building a model of thousands of variables
        for variable in model.variables:
            for value in variable.domain:
                cube = self.true
                for bit, on in self.code(variable.name, value).items():
                    cube &= self.bdd.var(bit) if on else ~self.bdd.var(bit)
                self._value_cache[(variable.name, value)] = cube
        self._expr_cache: dict[Expr, Function] = {}
        codes = [self._valid_codes(v.name) for v in model.variables]
        while len(codes) > 1:  # pairwise: one long chain of conjunctions costs quadratic time
            pairs = zip(codes[::2], codes[1::2], strict=False)
            codes = [a & b for a, b in pairs] + ([codes[-1]] if len(codes) % 2 else [])
        self.valid = codes[0] if codes else self.true
        self.transitions: tuple[SymbolicTransition, ...] = tuple(
            self._transition(t) for t in model.transitions
        )
        self.by_name = {t.name: t for t in self.transitions}
        # the order the variables were declared in (FORCE unless given), before any sifting
        self.initial_order: list[str] = sorted(self.bdd.vars, key=self.bdd.level_of_var)
        self._restricted: dict[tuple[str, frozenset[str]], SymbolicTransition] = {}
        self._bit_owner = {bit: name for name, bits in self.bits.items() for bit in bits}

    def sift(self) -> None:
        """Reorder the BDD variables once by sifting (deterministic: called at fixed points)."""
        cudd.reorder(self.bdd)

    def reorder(self, order: list[str]) -> None:
        """Put the BDD variables in the given order (a saved one); unknown names are an error."""
        if sorted(order) != sorted(self.bdd.vars):
            raise ValueError("the saved variable order does not match this model's bits")
        cudd.reorder(self.bdd, {name: level for level, name in enumerate(order)})

    def code(self, variable: str, value: Value) -> dict[str, bool]:
        """The bit assignment that encodes `variable == value`."""
        domain = self.model.variable(variable).domain
        index = domain.index(value)
        bits = self.bits[variable]
        width = len(bits)
        return {bit: bool((index >> (width - 1 - j)) & 1) for j, bit in enumerate(bits)}

    def equals(self, variable: str, value: Value) -> Function:
        key = (variable, value)
        cached = self._value_cache.get(key)
        if cached is None:
            cached = self.bdd.cube(self.code(variable, value))
            self._value_cache[key] = cached
        return cached

    def same_value(self, left: str, right: str) -> Function:
        """`left == right` for two variables of the same domain: bitwise equivalence."""
        result = self.true
        for a, b in zip(self.bits[left], self.bits[right], strict=True):
            result &= self.bdd.apply("<=>", self.bdd.var(a), self.bdd.var(b))
        return result

    def _valid_codes(self, variable: str) -> Function:
        domain = self.model.variable(variable).domain
        if len(domain) == 1 << len(self.bits[variable]):
            return self.true
        return self._disjoin(self.equals(variable, v) for v in domain)

    def _conjoin(self, parts: Iterable[Function]) -> Function:
        result = self.true
        for part in parts:
            result &= part
        return result

    def _disjoin(self, parts: Iterable[Function]) -> Function:
        result = self.false
        for part in parts:
            result |= part
        return result

    def expr(self, expr: Expr) -> Function:
        """The set of (valid or not) states where `expr` holds."""
        cached = self._expr_cache.get(expr)
        if cached is not None:
            return cached
        match expr:
            case Const(value):
                result = self.true if value else self.false
            case BoolVar(name):
                result = self.bdd.var(self.bits[name][0])
            case Equals(name, value):
                result = self.equals(name, value)
            case SameValue(left, right):
                result = self.same_value(left, right)
            case Not(arg):
                result = ~self.expr(arg)
            case And(args):
                result = self._conjoin(self.expr(a) for a in args)
            case Or(args):
                result = self._disjoin(self.expr(a) for a in args)
            case Implies(left, right):
                result = ~self.expr(left) | self.expr(right)
            case _:
                raise TypeError(expr)
        self._expr_cache[expr] = result
        return result

    def _transition(self, t: Transition) -> SymbolicTransition:
        guard = self.expr(t.guard)
        written = t.written
        written_bits = tuple(b for a in t.actions for b in self.bits[a.target])
        substitution: dict[str, Any] = {}
        general = any(a.source is not None and a.source in written for a in t.actions)
        for action in t.actions:
            substitution.update(self._substitution(action))
        if any(a.source is not None for a in t.actions):  # `let` needs one kind of value
            substitution = {
                bit: (self.true if v else self.false) if isinstance(v, bool) else v
                for bit, v in substitution.items()
            }
        if not general:
            post = self._conjoin(self._post(a) for a in t.actions)
            return SymbolicTransition(t, guard, written_bits, post, None, {}, substitution)
        # an action copies a variable the same transition writes: relate primed bits instead
        primes: dict[str, str] = {}
        for bit in written_bits:
            primed = bit + "p"
            if primed not in self.bdd.vars:
                self.bdd.declare(primed)
            primes[primed] = bit
        relation = self.true
        for action in t.actions:
            targets = self.bits[action.target]
            if action.source is None:
                assert action.value is not None
                code = self.code(action.target, action.value)
                relation &= self.bdd.cube({b + "p": code[b] for b in targets})
            else:
                for a, b in zip(targets, self.bits[action.source], strict=True):
                    relation &= self.bdd.apply("<=>", self.bdd.var(a + "p"), self.bdd.var(b))
        return SymbolicTransition(t, guard, written_bits, None, relation, primes, substitution)

    def restricted(self, t: SymbolicTransition, targets: frozenset[str]) -> SymbolicTransition:
        """`t` with only its actions on `targets` (the others' variables are dropped from a
        search, see `planner.planning.relevance`); `t` itself when it writes nothing else."""
        if t.transition.written <= targets:
            return t
        key = (t.name, targets & t.transition.written)
        cached = self._restricted.get(key)
        if cached is None:
            actions = tuple(a for a in t.transition.actions if a.target in targets)
            cached = self._transition(replace(t.transition, actions=actions))
            self._restricted[key] = cached
        return cached

    def _post(self, action: Assign) -> Function:
        if action.source is None:
            assert action.value is not None
            return self.equals(action.target, action.value)
        return self.same_value(action.target, action.source)

    def _substitution(self, action: Assign) -> dict[str, Any]:
        if action.source is None:
            assert action.value is not None
            return dict(self.code(action.target, action.value))
        return {
            a: self.bdd.var(b)
            for a, b in zip(self.bits[action.target], self.bits[action.source], strict=True)
        }

    def image(self, t: SymbolicTransition, states: Function) -> Function:
        """States reached by taking `t` from those of `states` where its guard holds."""
        if t.post is not None:
            if not t.written_bits:
                return states & t.guard
            return cudd.and_exists(states, t.guard, t.written_bits) & t.post
        assert t.relation is not None
        stepped = cudd.and_exists(states & t.guard, t.relation, t.written_bits)
        return self.bdd.let(dict(t.primes), stepped)

    def preimage(self, t: SymbolicTransition, states: Function) -> Function:
        """States where `t` is enabled and leads into `states` (validity not implied)."""
        if not t.substitution:
            return states & t.guard
        return self.bdd.let(dict(t.substitution), states) & t.guard

    def state(self, values: State) -> Function:
        """The single-state set of a concrete state tuple."""
        assignment: dict[str, bool] = {}
        for variable, value in zip(self.model.variables, values, strict=True):
            assignment.update(self.code(variable.name, value))
        return self.bdd.cube(assignment)

    def pick(self, states: Function) -> State:
        """One concrete state of a non-empty set (deterministic for the same BDD)."""
        assignment = self.bdd.pick(states & self.valid, care_vars=set(self.state_bits))
        if assignment is None:
            raise ValueError("pick from an empty set of states")
        return self.decode(assignment)

    def cube(self, values: Mapping[str, Value]) -> Function:
        """The states where each given variable has its given value (the rest free)."""
        assignment: dict[str, bool] = {}
        for name, value in values.items():
            assignment.update(self.code(name, value))
        return self.bdd.cube(assignment)

    def variables_of(self, states: Function) -> frozenset[str]:
        """The model variables whose bits the set depends on."""
        owner = self._bit_owner
        return frozenset(owner[bit] for bit in self.bdd.support(states) if bit in owner)

    def decode(self, assignment: Mapping[str, bool]) -> State:
        values: list[Value] = []
        for variable in self.model.variables:
            bits = self.bits[variable.name]
            index = 0
            for bit in bits:
                index = (index << 1) | int(assignment[bit])
            values.append(variable.domain[index])
        return tuple(values)

    def count(self, states: Function) -> int:
        """How many valid states the set holds."""
        return int(self.bdd.count(states & self.valid, nvars=len(self.state_bits)))

    def contains(self, states: Function, values: State) -> bool:
        return bool((states & self.state(values)) != self.false)
