"""Readable predicates from BDDs: irredundant sums of products over the model's variables.

Used for the supervisor guards that `sp check` prints (`planner.bdd.guards`).
"""

from __future__ import annotations

from collections.abc import Sequence

from planner.bdd.symbolic import Function, SymbolicModel
from planner.model.expressions import BoolVar, Equals, Expr, Not, Value, conjunction, disjunction

Cube = tuple[tuple[str, bool], ...]
"""Literals over BDD bits, outermost bit first."""


class Cover:
    """Covers of intervals of BDDs as expressions, sharing their work between calls.

    An irredundant sum of products between the two bounds (Minato-Morreale ISOP), whose
    cubes over bits are read back as literals over the model's variables.  The guards of
    similar transitions meet the same sub-intervals, so one `Cover` for all of them saves
    most of the recursion.
    """

    def __init__(self, sym: SymbolicModel) -> None:
        self.sym = sym
        self.reader = _Reader(sym)
        self.memo: dict[tuple[Function, Function], tuple[list[Cube], Function]] = {}
        self.limit: int | None = None

    def expr(self, lower: Function, upper: Function, limit: int | None = None) -> Expr | None:
        """A short expression true on all of `lower` and nowhere outside `upper`; None if
        it takes more than `limit` products."""
        try:
            cubes = self.isop(lower, upper, limit)
        except _TooMany:
            return None
        terms = [self.reader.literals(cube) for cube in cubes]
        if len(terms) < 2:
            return disjunction([conjunction(t) for t in terms])
        common = [lit for lit in terms[0] if all(lit in t for t in terms[1:])]
        rest = [conjunction([lit for lit in t if lit not in common]) for t in terms]
        return conjunction([*common, disjunction(rest)])

    def isop(self, lower: Function, upper: Function, limit: int | None = None) -> list[Cube]:
        """Irredundant cubes covering `lower` within `upper` (requires lower <= upper).

        Every cube of a part is a cube of the whole, so a part over `limit` cubes stops the
        recursion (`_TooMany`); the parts finished until then stay memoised.
        """
        self.limit = limit
        return self._isop(lower, upper)[0]

    # methods, not a nested recursive function: that would be a reference cycle holding
    # BDD nodes, which Python may free after the manager (CUDD then reports leaked nodes)

    def _isop(self, low: Function, up: Function) -> tuple[list[Cube], Function]:
        sym = self.sym
        if low == sym.false:
            return [], sym.false
        if up == sym.true:
            return [()], sym.true
        key = (low, up)
        known = self.memo.get(key)
        if known is not None:
            return known
        level = min(low.level, up.level)
        l0, l1 = _cofactors(low, level)
        u0, u1 = _cofactors(up, level)
        c0, f0 = self._isop(l0 & ~u1, u0)
        c1, f1 = self._isop(l1 & ~u0, u1)
        cd, fd = self._isop((l0 & ~f0) | (l1 & ~f1), u0 & u1)
        var = sym.bdd.var_at_level(level)
        cubes = [((var, False), *c) for c in c0] + [((var, True), *c) for c in c1] + cd
        if self.limit is not None and len(cubes) > self.limit:
            raise _TooMany
        result = (cubes, sym.bdd.ite(sym.bdd.var(var), f1, f0) | fd)
        self.memo[key] = result
        return result


def _cofactors(u: Function, level: int) -> tuple[Function, Function]:
    """The cofactors of `u` by the bit at `level`, read off the node (not substituted, which
    costs a pass over every declared bit in `dd`)."""
    if u.level != level:  # below that bit, or a constant (which sits below every level)
        return u, u
    if u.negated:
        return ~u.low, ~u.high
    return u.low, u.high


class _TooMany(Exception):
    """A cover needs more cubes than allowed."""


class _Reader:
    """Reads cubes over bits back as literals over variables, in the model's order."""

    def __init__(self, sym: SymbolicModel) -> None:
        self.owner = {bit: v.name for v in sym.model.variables for bit in sym.bits[v.name]}
        self.index = sym.model.variable_index
        self.domains = {v.name: v.domain for v in sym.model.variables}
        self.codes = {
            v.name: [(value, tuple(sym.code(v.name, value).items())) for value in v.domain]
            for v in sym.model.variables
        }

    def literals(self, cube: Cube) -> list[Expr]:
        """A cube over bits as literals, one per variable it constrains."""
        fixed = dict(cube)
        literals: list[Expr] = []
        for name in sorted({self.owner[b] for b in fixed}, key=self.index.__getitem__):
            domain = self.domains[name]
            values = [
                value
                for value, code in self.codes[name]
                if all(fixed.get(b, bit) == bit for b, bit in code)
            ]
            if len(values) < len(domain):
                literals.append(_literal(name, domain, values))
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
