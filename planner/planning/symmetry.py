"""Symmetries of a station: interchangeable objects found in the model and used by the search.

A station built from parameterised abilities is full of interchangeable objects: bolt pairs
`bp1 ... bp4`, robots `r1`, `r2`.  Swapping two of them everywhere (variables such as
`bp1.state` <-> `bp2.state`, values such as `r1.pos == bp1` <-> `r1.pos == bp2`, transitions
such as `r1.goto_bp1` <-> `r1.goto_bp2`) maps the model onto itself.  If the query is
unchanged by the swap too (goal, `always`, forbidden predicates, disabled transitions), the
distance from the start to the goal is the same from every state of an orbit, so the search
may keep one representative per orbit and still find the minimal length: any plan of the
quotient lifts back to a real plan of the same length (seed-independent; see Pochter,
Zohar and Rosenschein, "Exploiting problem symmetries in state-based planners", 2011).

Candidates come from names: tokens with a common prefix and different numbers (`bp1`,
`bp2`; `r1`, `r2`) are swapped wherever they occur as a whole token of a name or value.
Each candidate is then *verified* on the model's semantics: every variable, value and
transition must have an image, the image of every guard must equal the image transition's
guard as a BDD, actions must map onto actions, and the specifications' conjunction onto
itself.  A candidate that fails on an automatic or effect transition or on the
specifications is discarded; one that fails only on controlled or maintenance transitions
(the operator can move r2 home by hand, not r1) is kept for the queries where those are not
usable.  Names that follow no such pattern simply yield no symmetries.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from planner.bdd.symbolic import Function, SymbolicModel
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
    conjunction,
)
from planner.model.flat import UNCONTROLLABLE, Model

_NUMBERED = re.compile(r"^(.*?)(\d+)$")
_SEPARATORS = re.compile(r"([._])")


@dataclass(frozen=True)
class Symmetry:
    """An automorphism of the model that swaps two objects (an involution)."""

    first: str  # the two tokens swapped, e.g. "bp1" and "bp2"
    second: str
    variables: Mapping[str, str]  # each moved variable -> its image
    values: Mapping[str, Mapping[Value, Value]]  # per variable: value -> value of the image
    transitions: Mapping[str, str]  # every transition with an image -> that image
    broken: frozenset[str]  # controlled or maintenance transitions with no image
    specifications: Mapping[str, str] | None  # spec -> spec, when they map one by one

    @property
    def name(self) -> str:
        return f"{self.first}<->{self.second}"

    @property
    def moved(self) -> frozenset[str]:
        """The variables whose values a state changes under the swap."""
        return frozenset(self.variables) | frozenset(self.values)

    def variable(self, name: str) -> str:
        return self.variables.get(name, name)

    def value(self, name: str, value: Value) -> Value:
        return self.values.get(name, {}).get(value, value)

    def expr(self, expr: Expr) -> Expr:
        """The image of an expression (its truth in `s` is the image's truth in swap(s))."""
        match expr:
            case Const():
                return expr
            case BoolVar(name):
                return BoolVar(self.variable(name))
            case Equals(name, value):
                return Equals(self.variable(name), self.value(name, value))
            case SameValue(left, right):
                return SameValue(self.variable(left), self.variable(right))
            case Not(arg):
                return Not(self.expr(arg))
            case And(args):
                return And(tuple(self.expr(a) for a in args))
            case Or(args):
                return Or(tuple(self.expr(a) for a in args))
            case Implies(left, right):
                return Implies(self.expr(left), self.expr(right))
        raise TypeError(expr)

    def assign(self, action: Assign) -> Assign:
        target = self.variable(action.target)
        if action.source is not None:
            return Assign(target, source=self.variable(action.source))
        assert action.value is not None
        return Assign(target, value=self.value(action.target, action.value))

    def state(self, model: Model, values: Sequence[Value]) -> tuple[Value, ...]:
        """The image of a concrete state."""
        index = model.variable_index
        image = list(values)
        for variable in model.variables:
            name = variable.name
            image[index[self.variable(name)]] = self.value(name, values[index[name]])
        return tuple(image)


def find_symmetries(sym: SymbolicModel) -> tuple[Symmetry, ...]:
    """Every verified swap of two numbered objects of the model (see the module docstring)."""
    model = sym.model
    names = [v.name for v in model.variables] + [t.name for t in model.transitions]
    names += [str(value) for v in model.variables for value in v.domain if isinstance(value, str)]
    families: dict[str, set[str]] = {}
    for name in names:
        for token in _SEPARATORS.split(name):
            found = _NUMBERED.match(token)
            if found and found.group(1):
                families.setdefault(found.group(1), set()).add(token)
    result: list[Symmetry] = []
    for members in families.values():
        ordered = sorted(members, key=_number_order)
        for i, first in enumerate(ordered):
            for second in ordered[i + 1 :]:
                candidate = _candidate(sym, first, second)
                if candidate is not None:
                    result.append(candidate)
    return tuple(result)


def _number_order(token: str) -> tuple[str, int]:
    found = _NUMBERED.match(token)
    assert found is not None
    return found.group(1), int(found.group(2))


def _rename(name: str, first: str, second: str) -> str:
    parts = _SEPARATORS.split(name)
    swapped = {first: second, second: first}
    return "".join(swapped.get(part, part) for part in parts)


def _candidate(sym: SymbolicModel, first: str, second: str) -> Symmetry | None:
    """The swap of two tokens, if it is an automorphism of the model's semantics."""
    model = sym.model
    variables: dict[str, str] = {}
    values: dict[str, dict[Value, Value]] = {}
    for variable in model.variables:
        image = _rename(variable.name, first, second)
        if image not in model.variable_index:
            return None
        target = model.variable(image)
        if target.kind is not variable.kind:
            return None
        if image != variable.name:
            variables[variable.name] = image
        mapping = {
            value: _rename(value, first, second) if isinstance(value, str) else value
            for value in variable.domain
        }
        if sorted(map(str, mapping.values())) != sorted(map(str, target.domain)):
            return None
        if any(value not in target.domain for value in mapping.values()):
            return None
        changed = {v: w for v, w in mapping.items() if v != w}
        if changed:
            values[variable.name] = changed
    if not variables and not values:
        return None
    swap = Symmetry(first, second, variables, values, {}, frozenset(), None)
    transitions: dict[str, str] = {}
    broken: set[str] = set()
    for t in model.transitions:
        image_name = _rename(t.name, first, second)
        fits = image_name in model.transition_index
        if fits:
            other = model.transition(image_name)
            fits = (
                other.kind is t.kind
                and set(map(swap.assign, t.actions)) == set(other.actions)
                and sym.expr(swap.expr(t.guard)) == sym.by_name[image_name].guard
            )
        if fits:
            transitions[t.name] = image_name
        elif t.kind in UNCONTROLLABLE:
            return None
        else:
            broken.add(t.name)
    every = conjunction([s.invariant for s in model.specifications])
    if sym.expr(swap.expr(every)) != sym.expr(every):
        return None
    specifications = _specifications(sym, swap, first, second)
    return Symmetry(
        first, second, variables, values, transitions, frozenset(broken), specifications
    )


def _specifications(
    sym: SymbolicModel, swap: Symmetry, first: str, second: str
) -> dict[str, str] | None:
    """Each specification's image, if they map one by one (needed when a forbidden-state
    recovery drops some of them)."""
    by_name = {s.name: s for s in sym.model.specifications}
    result: dict[str, str] = {}
    for spec in sym.model.specifications:
        other = by_name.get(_rename(spec.name, first, second))
        if other is None or sym.expr(swap.expr(spec.invariant)) != sym.expr(other.invariant):
            return None
        result[spec.name] = other.name
    return result


COMPARED_VARIABLES = 8


def neighbours(symmetries: Iterable[Symmetry]) -> list[Symmetry]:
    """Swaps of neighbouring objects only: per group of interchangeable objects (tokens
    connected by the given swaps), the swaps of consecutive members.  They generate the
    same group, and are what an odd-even transposition sort needs."""
    chosen = list(symmetries)
    by_pair = {(s.first, s.second): s for s in chosen}
    parent: dict[str, str] = {}

    def find(token: str) -> str:
        parent.setdefault(token, token)
        while parent[token] != token:
            parent[token] = parent[parent[token]]
            token = parent[token]
        return token

    for s in chosen:
        parent[find(s.first)] = find(s.second)
    groups: dict[str, list[str]] = {}
    for token in list(parent):
        groups.setdefault(find(token), []).append(token)
    result: list[Symmetry] = []
    for members in groups.values():
        ordered = sorted(members, key=_number_order)
        for a, b in itertools.pairwise(ordered):
            swap = by_pair.get((a, b))
            if swap is not None:
                result.append(swap)
    return sorted(result, key=lambda s: (_number_order(s.first), _number_order(s.second)))


class Swapper:
    """A symmetry acting on BDD sets over some kept variables: images of sets, and the
    predicate "the swapped state is smaller" that canonicalisation sorts by."""

    def __init__(self, sym: SymbolicModel, symmetry: Symmetry, kept: Iterable[str]) -> None:
        self.sym = sym
        self.symmetry = symmetry
        keep = set(kept)
        model = sym.model
        bdd = sym.bdd
        # sigma(S)(s) = S(sigma(s)) for an involution: each bit of x takes the value the same
        # bit of x has in sigma(s), a function of the image variable's bits
        substitution: dict[str, Function] = {}
        ordered = [v.name for v in model.variables if v.name in keep]
        self.affected = tuple(v for v in ordered if v in symmetry.moved)
        for name in self.affected:
            image = symmetry.variable(name)
            domain = model.variable(name).domain
            bits = sym.bits[name]
            for j, bit in enumerate(bits):
                f = sym.false
                for value in model.variable(image).domain:
                    # sigma(s)[name] = value of sigma applied to s[image]
                    mine = symmetry.value(image, value)
                    if sym.code(name, mine)[bit]:
                        f |= sym.equals(image, value)
                if len(domain) < 1 << len(bits):  # invalid codes keep their bit
                    f |= ~_valid(sym, image) & bdd.var(sym.bits[image][j])
                substitution[bit] = f
        self._substitution = substitution
        # compare by the first few moved variables only: a lexicographic comparison over
        # many variables is a large BDD whatever the variable order, and a canonical form
        # need not be unique to be sound (ties are simply not swapped)
        pairs = [v for v in self.affected if symmetry.variable(v) != v]
        recoded = [v for v in self.affected if symmetry.variable(v) == v]
        self.compared = tuple((pairs + recoded)[:COMPARED_VARIABLES])
        self.smaller = self._smaller()

    def image(self, states: Function) -> Function:
        if not self._substitution:
            return states
        return self.sym.bdd.let(self._substitution, states)

    def _smaller(self) -> Function:
        """States s with sigma(s) lexicographically smaller than s (variables in model
        order, values in domain order)."""
        sym = self.sym
        symmetry = self.symmetry
        result = sym.false
        for name in reversed(self.compared):
            image = symmetry.variable(name)
            domain = sym.model.variable(name).domain
            less = sym.false
            equal = sym.false
            for value in sym.model.variable(image).domain:
                mine = symmetry.value(image, value)  # sigma(s)[name] when s[image] == value
                for own in domain:
                    both = sym.equals(image, value) & sym.equals(name, own)
                    if domain.index(mine) < domain.index(own):
                        less |= both
                    elif mine == own:
                        equal |= both
            result = less | (equal & result)
        return result


def _valid(sym: SymbolicModel, name: str) -> Function:
    result = sym.false
    for value in sym.model.variable(name).domain:
        result |= sym.equals(name, value)
    return result


def canonical(swappers: Sequence[Swapper], states: Function, rounds: int) -> Function:
    """Each state replaced by a smaller one of its orbit where one swap makes it smaller,
    over `rounds` rounds of every swap (an odd-even transposition sort when the swaps are
    of neighbouring objects).  Every state stays in its orbit, so the result has at least
    one state of every orbit the input meets, and no state of any other."""
    sym = swappers[0].sym if swappers else None
    for _ in range(rounds):
        changed = False
        for swapper in swappers:
            assert sym is not None
            moving = states & swapper.smaller
            if moving != sym.false:
                states = (states & ~swapper.smaller) | swapper.image(moving)
                changed = True
        if not changed:
            break
    return states


def orbit(swappers: Sequence[Swapper], states: Function) -> Function:
    """Every state of every orbit the set meets (closure under the swaps)."""
    while True:
        before = states
        for swapper in swappers:
            states |= swapper.image(states)
        if states == before:
            return states
