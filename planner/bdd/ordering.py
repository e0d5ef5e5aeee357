"""The static BDD variable order a model's BDDs start with (sifted once more after synthesis).

Variables are arranged by FORCE (Aloul, Markov, Sakallah 2003): each transition and each
specification is a hyperedge over the variables it reads or writes, and every variable
moves repeatedly to the centre of gravity of its hyperedges, so that variables used
together end up close together.  Then the bits of variables compared or copied
(`x == y`, `x := y`) are interleaved: their relation is linear in the width that way,
and exponential with the variables apart.
"""

from __future__ import annotations

from collections.abc import Mapping

from planner.model.expressions import And, Expr, Implies, Not, Or, SameValue, variables_of
from planner.model.flat import Model, Transition

FORCE_ROUNDS = 20


def variable_order(model: Model, bits: Mapping[str, tuple[str, ...]]) -> list[str]:
    """Every bit of `bits` (each variable's, most significant first), in the order to declare."""
    edges = _hyperedges(model)
    ordered = _hubs_on_top(_force([v.name for v in model.variables], edges), edges)
    order: list[str] = []
    for members in _compared_groups(model, ordered):
        width = max(len(bits[m]) for m in members)
        for j in range(width):
            order.extend(bits[m][j] for m in members if j < len(bits[m]))
    return order


def _hyperedges(model: Model) -> list[list[str]]:
    """The variables of each transition and specification that ties two or more together."""
    edges = [
        sorted(variables_of(t.guard) | {a.target for a in t.actions} | _sources(t))
        for t in model.transitions
    ] + [sorted(variables_of(s.invariant)) for s in model.specifications]
    return [e for e in edges if len(e) > 1]


def _force(names: list[str], edges: list[list[str]]) -> list[str]:
    """`names` rearranged by FORCE: each to the mean centre of its hyperedges, until stable."""
    position = {name: float(i) for i, name in enumerate(names)}
    for _ in range(FORCE_ROUNDS):
        centre = [sum(position[v] for v in e) / len(e) for e in edges]
        total = {name: 0.0 for name in names}
        count = {name: 0 for name in names}
        for e, c in zip(edges, centre, strict=True):
            for v in e:
                total[v] += c
                count[v] += 1
        target = {n: total[n] / count[n] if count[n] else position[n] for n in names}
        ranked = sorted(names, key=lambda n: (target[n], position[n]))
        new = {name: float(i) for i, name in enumerate(ranked)}
        if new == position:
            break
        position = new
    return sorted(names, key=lambda n: position[n])


def _hubs_on_top(ordered: list[str], edges: list[list[str]]) -> list[str]:
    """FORCE fixes neighbourhoods, not direction: the order turned so that the hubs
    (variables in many hyperedges, such as who holds a shared tool) are on top, where they
    split the BDD early."""
    degree = dict.fromkeys(ordered, 0)
    for e in edges:
        for v in e:
            degree[v] += 1
    last = len(ordered) - 1
    if sum(degree[n] * i for i, n in enumerate(ordered)) > sum(
        degree[n] * (last - i) for i, n in enumerate(ordered)
    ):
        ordered.reverse()
    return ordered


def _compared_groups(model: Model, ordered: list[str]) -> list[list[str]]:
    """The variables compared or copied with each other (`x == y`, `x := y`), joined into
    groups; a group sits where its first member is in `ordered`."""
    parent = {name: name for name in ordered}

    def find(name: str) -> str:
        while parent[name] != name:
            parent[name] = parent[parent[name]]
            name = parent[name]
        return name

    def visit(expr: Expr) -> None:
        match expr:
            case SameValue(left, right):
                parent[find(right)] = find(left)
            case Not(arg):
                visit(arg)
            case And(args) | Or(args):
                for arg in args:
                    visit(arg)
            case Implies(left, right):
                visit(left)
                visit(right)

    for t in model.transitions:
        visit(t.guard)
        for action in t.actions:
            if action.source is not None:
                parent[find(action.source)] = find(action.target)
    for spec in model.specifications:
        visit(spec.invariant)
    groups: dict[str, list[str]] = {}
    for name in ordered:
        groups.setdefault(find(name), []).append(name)
    return list(groups.values())


def _sources(t: Transition) -> set[str]:
    return {a.source for a in t.actions if a.source is not None}
