"""What the bdd engine's reductions must do for a query, read independently of `planner/`.

`tests/support/oracle.py` says what a plan must be (section 8); this module says how the exact
reductions must get there, from the docstrings of `planner.planning.relevance` and
`planner.planning.symmetry` alone, by brute force where it matters:

- `expected_structure`: the independent components of a query by union-find over what
  ties variables together, which of them must move (*active*), and, with each active one
  planned by the oracle on its own sub-model, how many parts the engine reports and how
  many bits it searches (the concatenation in order, or the joint fallback);
- `explicit_swap`: whether swapping two numbered tokens is an automorphism of the model,
  checked on every state.

It reads the model through `planner.model.flat` and `planner.model.expressions` (parsing is tested
elsewhere) and nothing of the reductions themselves.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from planner.model.expressions import Expr, conjuncts, format_expr, variables_of
from planner.model.flat import Model, Transition, TransitionKind
from planner.model.semantics import compile_expr
from planner.planning.query import PlanQuery
from tests.support import oracle as O

UNCONTROLLABLE = (TransitionKind.AUTOMATIC, TransitionKind.EFFECT)

# --------------------------------------------------------------------------- components


def touches(t: Transition) -> frozenset[str]:
    """The variables a transition reads or writes."""
    sources = {a.source for a in t.actions if a.source is not None}
    return variables_of(t.guard) | t.written | sources


def bits_of(model: Model, variables: Iterable[str]) -> int:
    """BDD bits of the variables: each is log-encoded, one bit at least."""
    return sum(max(1, (len(model.variable(v).domain) - 1).bit_length()) for v in variables)


@dataclass(frozen=True)
class Expected:
    """What the reductions must do for one query."""

    components: tuple[frozenset[str], ...]  # model order of their first variable
    active: tuple[frozenset[str], ...]  # those that must move
    busy: tuple[frozenset[str], ...]  # active ones with an automatic enabled at the start
    unsettled: tuple[frozenset[str], ...]  # no minimal plan of theirs ends calm
    lengths: tuple[int | None, ...]  # each active part's own minimal length, in order
    searches: bool  # whether the engine searches at all (not answered at the start)
    fallback: bool  # no order concatenates the parts: they are planned jointly
    parts: int  # `statistics["parts"]` with the parts reduction
    bits: int  # `statistics["searched_bits"]` with the parts reduction, without the cone


def expected_structure(model: Model, oracle: O.OracleModel, query: PlanQuery) -> Expected:
    """Components by union-find over what ties variables together for this query, the
    active ones planned alone by the oracle on their own sub-models.

    Tied together are the variables of a usable transition, of any uncontrollable one
    (the bad states are closed over them all), of a specification, and of a conjunct of
    the goal, of `always` or of a forbidden predicate's negation (the strategies'
    forbidden predicates are conjunctions: their negation is one conjunct).
    """
    usable = [
        t
        for t in model.transitions
        if t.name not in query.disabled
        and (query.maintenance or t.kind is not TransitionKind.MAINTENANCE)
    ]
    goal_parts = conjuncts(query.goal)
    always_parts = conjuncts(query.always) if query.always is not None else ()
    edges = [touches(t) for t in model.transitions if t.kind in UNCONTROLLABLE or t in usable]
    edges += [variables_of(s.invariant) for s in model.specifications]
    edges += [variables_of(p) for p in (*goal_parts, *always_parts, *query.forbidden)]
    components = _union_find([v.name for v in model.variables], edges)
    index = model.variable_index

    def holds(expr: Expr) -> bool:
        return compile_expr(expr, index)(query.start)

    def busy(component: frozenset[str]) -> bool:
        return any(
            t.kind is TransitionKind.AUTOMATIC
            and t.written & component
            and compile_expr(t.guard, index)(query.start)
            for t in usable
        )

    def unmet(component: frozenset[str]) -> bool:
        return any(variables_of(p) <= component and not holds(p) for p in goal_parts)

    bad = O.bad_states(oracle)

    def bad_part(component: frozenset[str]) -> bool:
        """Bad whatever the other components' values (recovery plans such parts)."""
        fixed = [index[v] for v in component]
        return all(
            s in bad for s in O.all_states(oracle) if all(s[i] == query.start[i] for i in fixed)
        )

    recovery = bool(query.relaxed)
    weighted = query.maintenance and query.maintenance_cost > 1
    active = tuple(c for c in components if unmet(c) or busy(c) or (recovery and bad_part(c)))
    whole = O.plan(oracle, query.start, format_expr(query.goal), **_options(query))
    searches = whole.status != "bad_start" and whole.length != 0 and all(map(holds, always_parts))
    lengths: list[int | None] = []
    unsettled: list[frozenset[str]] = []
    if searches and not recovery and len(active) > 1:
        for component in active:
            alone, calm = _alone(model, query, component)
            lengths.append(None if alone is None else alone[0])
            if alone is None:
                break
            if calm != alone:  # as short and as cheap (weighted), or the part goes last
                unsettled.append(component)
    first = [c for c in active if busy(c)]
    fallback = False
    if not searches:
        parts, bits = 0, 0
    elif recovery or len(active) == 1:  # recovery plans every active part jointly
        parts, bits = 1, bits_of(model, set().union(*active))
    elif lengths[-1] is None:  # the engine stops at the first part with no plan
        parts, bits = len(lengths), sum(bits_of(model, c) for c in active[: len(lengths)])
    elif len(first) > 1 or len(unsettled) > 1 or (first and first[0] in unsettled):
        fallback = True
        parts, bits = 1, bits_of(model, set().union(*active))
    elif weighted and sum(n for n in lengths if n is not None) > query.max_steps:
        # each part's cheapest plan need not be its shortest: when they do not fit
        # together, the parts are planned jointly
        fallback = True
        parts, bits = 1, bits_of(model, set().union(*active))
    else:
        parts, bits = len(active), sum(bits_of(model, c) for c in active)
    return Expected(
        components,
        active,
        tuple(first),
        tuple(unsettled),
        tuple(lengths),
        searches,
        fallback,
        parts,
        bits,
    )


def _options(query: PlanQuery) -> dict[str, Any]:
    return {
        "max_steps": query.max_steps,
        "maintenance": query.maintenance,
        "forbidden": tuple(format_expr(f) for f in query.forbidden),
        "phi": format_expr(query.always) if query.always is not None else None,
        "disabled": query.disabled,
        "relaxed": query.relaxed,
    }


def _union_find(names: list[str], edges: Iterable[Iterable[str]]) -> tuple[frozenset[str], ...]:
    parent = {n: n for n in names}

    def find(n: str) -> str:
        while parent[n] != n:
            n = parent[n]
        return n

    for edge in edges:
        members = sorted(edge)
        for other in members[1:]:
            parent[find(other)] = find(members[0])
    groups: dict[str, list[str]] = {}
    for n in names:
        groups.setdefault(find(n), []).append(n)
    return tuple(frozenset(g) for g in groups.values())


def _alone(
    model: Model, query: PlanQuery, component: frozenset[str]
) -> tuple[tuple[int, int, int] | None, tuple[int, int, int] | None]:
    """The oracle's best plan for the component on its own sub-model (its goal, `always`
    and forbidden parts), and its best plan to a *calm* end: there its goal and `always`
    hold and none of its automatic transitions is enabled.  Each as (length, cost,
    maintenance steps): with `maintenance_cost` the cheapest plans, else the shortest
    (cost = length, maintenance steps 0)."""
    # built from the parsed model: a guard's text may name variables its value ignores
    inside = [t for t in model.transitions if touches(t) <= component]
    names = {t.name for t in inside}
    sub = {
        "variables": [
            {
                "name": v.name,
                "domain": "bool" if v.is_bool else list(v.domain),
                "initial": v.initial,
            }
            for v in model.variables
            if v.name in component
        ],
        "transitions": [
            {
                "name": t.name,
                "kind": t.kind.value,
                "guard": format_expr(t.guard),
                "actions": [str(a) for a in t.actions],
            }
            for t in inside
        ],
        "specifications": [
            {"name": s.name, "invariant": format_expr(s.invariant)}
            for s in model.specifications
            if variables_of(s.invariant) <= component
        ],
    }
    m = O.parse_model(sub)
    start = tuple(query.start[model.variable_index[v.name]] for v in m.variables)

    def within(parts: Iterable[Expr]) -> list[str]:
        return [f"({format_expr(p)})" for p in parts if variables_of(p) <= component]

    goal = within(conjuncts(query.goal))
    phi = within(conjuncts(query.always)) if query.always is not None else []
    options: dict[str, Any] = {
        "max_steps": query.max_steps,
        "maintenance": query.maintenance,
        "forbidden": tuple(within(query.forbidden)),
        "phi": " && ".join(phi) or None,
        "disabled": query.disabled & names,
        "maintenance_cost": query.maintenance_cost,
    }
    extra = query.maintenance_cost - 1

    def key(result: O.OracleResult) -> tuple[int, int, int] | None:
        if result.status != "found" or result.length is None:
            return None
        steps = result.maintenance_steps or 0
        return result.length, result.length + extra * steps, steps

    alone = O.plan(m, start, " && ".join(goal) or "true", **options)
    if alone.status != "found":
        return None, None
    automatic = [
        f"!({format_expr(t.guard)})"
        for t in inside
        if t.kind is TransitionKind.AUTOMATIC and t.name not in query.disabled
    ]
    calm = O.plan(m, start, " && ".join([*goal, *phi, *automatic]) or "true", **options)
    return key(alone), key(calm)


# --------------------------------------------------------------------------- swaps


def rename(name: str, first: str, second: str) -> str:
    """Swap two tokens wherever they are a whole part of a dotted/underscored name."""
    swapped = {first: second, second: first}
    return "".join(swapped.get(part, part) for part in re.split(r"([._])", name))


def explicit_swap(m: O.OracleModel, first: str, second: str) -> set[str] | None:
    """Checks the swap of two tokens on every state, explicitly: None if it is not an
    automorphism (no image for a variable or value, an uncontrollable transition or the
    specifications not preserved), else the controlled and maintenance transitions that
    it does not map onto their images (the ones a query must not use)."""
    index = m.index
    image_of: list[int] = []
    for v in m.variables:
        image = rename(v.name, first, second)
        if image not in index:
            return None
        target = m.variables[index[image]]
        mapped = {rename(x, first, second) if isinstance(x, str) else x for x in v.domain}
        if mapped != set(target.domain):
            return None
        image_of.append(index[image])

    def sigma(s: O.State) -> O.State:
        out: list[object] = list(s)
        for i, value in enumerate(s):
            out[image_of[i]] = rename(value, first, second) if isinstance(value, str) else value
        return tuple(out)

    by_name = {t.name: t for t in m.transitions}
    failed: set[str] = set()
    for t in m.transitions:
        other = by_name.get(rename(t.name, first, second))
        if other is None or other.kind != t.kind:
            failed.add(t.name)
    for s in O.all_states(m):
        image = sigma(s)
        if all(sp.holds(s) for sp in m.specs) != all(sp.holds(image) for sp in m.specs):
            return None
        for t in m.transitions:
            if t.name in failed:
                continue
            other = by_name[rename(t.name, first, second)]
            if t.enabled(s) != other.enabled(image) or (
                t.enabled(s) and sigma(t.update(s)) != other.update(image)
            ):
                failed.add(t.name)
    if any(by_name[n].kind in ("automatic", "effect") for n in failed):
        return None
    return failed
