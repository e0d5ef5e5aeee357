"""What a planning query can matter to: independent components and the cone of influence.

A station is often several loosely coupled parts.  Two sets of variables are *independent*
for a query when no usable transition, no specification, no uncontrollable transition and
no part of the query (a conjunct of the goal, of `always`, or of what `forbidden` leaves
allowed) reads or writes both.  Under the section 8 semantics such components can be
planned apart, exactly:

- The bad states split: `bad(a, b) = bad_A(a) or bad_B(b)`.  From `(a, b)` the product can
  first fire B's automatic transitions until none is enabled (they terminate: automatic
  cycles are rejected when the planner is built), then follow A's own uncontrollable chain
  into a violation; conversely a product chain projects onto a valid chain of each part.
- A plan of the product projects onto a plan of each component for its part of the goal
  (a controlled or effect step of A in the product needs no automatic enabled anywhere, so
  in particular none in A), so the product's minimal length is at least the sum of the
  parts' minimal lengths.  Concatenating the parts' minimal plans reaches that sum as long
  as every part but the last ends where none of its automatic transitions is enabled (and
  `always` holds), and every part but the first starts where none is enabled:
  `transition_planner` orders the parts that way, and plans the offending parts jointly
  when no such order exists.
- A component whose part of the goal already holds at the start and where no automatic is
  enabled needs no step at all: it is *frozen* at its start values, and the query's sets
  are cofactored on them.

Within a component, the *cone of influence* drops variables that nothing the search reads
depends on (a robot's `last` pose, read only by a restart ability outside restart mode):
each transition writing only such variables is a self-loop of the projection, and the
others keep just their actions on kept variables.  The projection is exact, so plans keep
their minimal length; the full states are recovered by replaying the plan.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from planner.model.coupling import Groups, touched
from planner.model.expressions import Expr, Implies, Not, Or, conjuncts, variables_of
from planner.model.flat import UNCONTROLLABLE, Model, Transition


def allowed_conjuncts(forbidden: Expr) -> tuple[Expr, ...]:
    """The top-level conjuncts of `!forbidden`, without building the negation's normal form."""
    match forbidden:
        case Not(arg):
            return conjuncts(arg)
        case Or(args):
            return tuple(part for arg in args for part in allowed_conjuncts(arg))
        case Implies(left, right):
            return (*conjuncts(left), *allowed_conjuncts(right))
    return (Not(forbidden),)


@dataclass(frozen=True, slots=True)
class Component:
    """Variables a query can plan apart from the rest (model order)."""

    variables: tuple[str, ...]


class Structure:
    """A model's coupling: what each transition touches and what the bad states tie together.

    Built once per model; the groups for a set of usable transitions are cached, as a
    running station asks about the same few sets again and again, and each query only adds
    its own predicates.
    """

    def __init__(self, model: Model) -> None:
        self.model = model
        # the bad states are closed over every uncontrollable transition (disabled or not)
        # and derived from every specification: those tie their variables together
        self._coupling = Groups(v.name for v in model.variables)
        for t in model.transitions:
            if t.kind in UNCONTROLLABLE:
                self._coupling.join(touched(t))
        for spec in model.specifications:
            self._coupling.join(variables_of(spec.invariant))
        self._cache: dict[frozenset[str], Groups] = {}

    def _base(self, usable: frozenset[str]) -> Groups:
        cached = self._cache.get(usable)
        if cached is None:
            cached = self._coupling.copy()
            for name in sorted(usable):
                cached.join(touched(self.model.transition(name)))
            if len(self._cache) > 64:  # a station asks a handful of shapes; bound it anyway
                self._cache.clear()
            self._cache[usable] = cached
        return cached

    def components(
        self, usable: frozenset[str], predicates: Iterable[Expr]
    ) -> tuple[Component, ...]:
        """The independent components, given the query's predicates (each one ties its
        variables together), in model order of their first variable."""
        groups = self._base(usable).copy()
        for predicate in predicates:
            groups.join(variables_of(predicate))
        return tuple(Component(tuple(names)) for names in groups.members().values())


def cone_of_influence(
    seeds: Iterable[str], transitions: Iterable[Transition], variables: Iterable[str]
) -> frozenset[str]:
    """The variables among `variables` that can matter: the `seeds` (what the goal, the
    allowed states and the automatic guard read), and what the guards and sources of every
    transition writing a kept variable read, to a fixpoint."""
    within = frozenset(variables)
    keep = set(seeds) & within
    writers: dict[str, list[Transition]] = {}
    for t in transitions:
        for name in t.written:
            writers.setdefault(name, []).append(t)
    todo = list(keep)
    while todo:
        name = todo.pop()
        for t in writers.get(name, ()):
            for read in (variables_of(t.guard) | _sources_into(t, keep)) & within:
                if read not in keep:
                    keep.add(read)
                    todo.append(read)
    return frozenset(keep)


def _sources_into(t: Transition, keep: set[str]) -> set[str]:
    return {a.source for a in t.actions if a.source is not None and a.target in keep}
