"""What a resource that stopped where it is keeps the others out of.

A resource that stops answering stays where it was last seen, and the specifications that
relate its variables to another resource's now forbid that resource some values whatever else
holds: robot 2 silent above the engine keeps robot 1 out of the space above it (seed 000 6.1,
E6; the demo's `one_robot_in_shared_zone`).  This is what a person is told next to the cause
("robot 1 cannot go there").  A value counts only when the stopped resource's values are why:
one the specifications forbid anyway is not a consequence of the stop.

Each specification is judged by trying every assignment of its other variables, up to
`LIMIT` of them; one with more is not judged (it says nothing rather than something slow).
"""

from __future__ import annotations

import itertools
from collections.abc import Collection, Mapping

from planner.model.expressions import Value, variables_of
from planner.model.flat import Model
from planner.model.semantics import Predicate, compile_expr

LIMIT = 4096  # assignments of a specification's free variables tried, per value judged


def kept_out(
    model: Model, fixed: Mapping[str, Value], candidates: Collection[str]
) -> dict[str, tuple[Value, ...]]:
    """For each variable in `candidates` (not in `fixed`): the values of its domain that the
    specifications forbid, whatever the other variables hold, given `fixed`, and that they do
    not forbid with `fixed`'s variables free.  Variables with no such value are left out."""
    domains = {v.name: v.domain for v in model.variables}
    found: dict[str, set[Value]] = {}
    for spec in model.specifications:
        names = sorted(variables_of(spec.invariant))
        pinned = {n: fixed[n] for n in names if n in fixed}
        if not pinned:
            continue
        holds = compile_expr(spec.invariant, {n: k for k, n in enumerate(names)})
        for variable in sorted(set(names) & set(candidates) - fixed.keys()):
            for value in domains[variable]:
                now = _never(holds, names, {**pinned, variable: value}, domains)
                anyway = _never(holds, names, {variable: value}, domains)
                if now is True and anyway is False:
                    found.setdefault(variable, set()).add(value)
    return {name: tuple(v for v in domains[name] if v in values) for name, values in found.items()}


def _never(
    holds: Predicate,
    names: list[str],
    given: Mapping[str, Value],
    domains: Mapping[str, tuple[Value, ...]],
) -> bool | None:
    """Whether `holds` (over `names`, in order) is false for every value of the names not
    `given`; None when there are more than LIMIT assignments (not judged)."""
    choices = [(given[n],) if n in given else domains[n] for n in names]
    count = 1
    for values in choices:
        count *= len(values)
        if count > LIMIT:
            return None
    return not any(holds(state) for state in itertools.product(*choices))
