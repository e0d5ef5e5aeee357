"""Hypothesis strategies for models with the structure the bdd engine's reductions exploit.

`tests/strategies.py` draws flat models of a few variables, which almost never split into
independent components.  These strategies build them on purpose, from the same building
blocks, so that the reductions of `planner.relevance` are exercised against the oracle:

- `component_models`: 2-3 *parts* over disjoint variables, each a small random model with
  every kind of transition and its own specifications, optionally joined by *bridges*
  (an automatic whose guard reads two parts, an effect, a controlled or maintenance step
  that touches two);
- queries for each, touching one, two or all parts, with extras (`forbidden`, `always`,
  `disabled`) per part, and starts chosen to have automatic transitions enabled.

Models are plain dicts shaped like the YAML; the extra knowledge (which part owns which
variable, which transitions join two parts) travels beside them so the tests can say what
the reductions must do.  Every model has at most `MAX_STATES` states, so that the oracle
can enumerate them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from hypothesis import strategies as st

if TYPE_CHECKING:
    from tests import oracle as O
    from tests import strategies as S
else:
    try:
        from tests import oracle as O
        from tests import strategies as S
    except ImportError:  # no tests/__init__.py: pytest put tests/ itself on sys.path
        import oracle as O
        import strategies as S

MAX_STATES = 2000
PART_NAMES = ("p0", "p1", "p2")
PART_VARIABLES = ("a", "b", "c")
KIND_WEIGHTS = (("controlled", 8), ("automatic", 4), ("effect", 3), ("maintenance", 3))

Var = dict[str, Any]
Model = dict[str, Any]

# --------------------------------------------------------------------------- helpers


def _values(var: Var) -> list[Any]:
    return S.domain_values(var)


def _text(value: Any) -> str:
    return "true" if value is True else "false" if value is False else str(value)


def states_of(model: Model) -> int:
    """How many states a model has (the product of its domain sizes)."""
    n = 1
    for var in model["variables"]:
        n *= len(_values(var))
    return n


def written(transition: dict[str, Any]) -> set[str]:
    return {a.split(":=")[0].strip() for a in transition.get("actions", [])}


def _estimated_where_assigned(model: Model) -> None:
    """The planner rejects controlled and automatic transitions that assign measured
    variables; such variables become estimated (as in `tests/strategies.flat_models`)."""
    targets = set()
    for t in model["transitions"]:
        if t.get("kind", "controlled") in ("controlled", "automatic"):
            targets |= written(t)
    for var in model["variables"]:
        if var.get("kind") == "measured" and var["name"] in targets:
            var["kind"] = "estimated"


@st.composite
def _guard_and_actions(draw: st.DrawFn, variables: list[Var], kind: str) -> tuple[str, list[str]]:
    """One transition's body, shaped as `tests/strategies.flat_models` shapes them."""
    # automatics mostly progress (they alone then never cycle): hypothesis favours the
    # ends of a range, so the rare case is a value in the middle
    if kind == "automatic" and draw(st.integers(0, 19)) != 11:
        return draw(S._progressing_automatic(variables))
    if kind == "effect":
        return draw(S._effect(variables))
    if kind != "automatic" and draw(st.integers(0, 2)) < 2:
        return draw(S._structured(variables))
    return draw(S.random_expression(variables, 2)), draw(S._actions(variables))


def _kinds() -> list[str]:
    return [k for k, w in KIND_WEIGHTS for _ in range(w)]


# --------------------------------------------------------------------------- components


@dataclass(frozen=True)
class Structured:
    """A model made of parts over disjoint variables, and how it was made.

    `parts` are the parts as standalone models (before bridges): the queries walk in them.
    `bridges` are the transitions that touch two parts; whether they join the parts for a
    query depends on their kind and on what the query allows (see `tests/test_reductions`).
    """

    model: Model
    parts: tuple[Model, ...]
    bridges: tuple[str, ...]


@st.composite
def _part(draw: st.DrawFn, prefix: str, budget: int) -> Model:
    """A small random model over `prefix.a`, `prefix.b` (and maybe `prefix.c`)."""
    variables: list[Var] = []
    states = 1
    for i, name in enumerate(PART_VARIABLES[: draw(st.integers(2, 3))]):
        var = draw(S._variable(f"{prefix}.{name}"))
        room = budget // (2 if i == 0 else 1)  # the second variable must fit too
        if states * len(_values(var)) > room:
            var = {"name": var["name"], "domain": "bool"}
            if states * 2 > room:
                break
        states *= len(_values(var))
        variables.append(var)
    kinds = _kinds()
    transitions: list[dict[str, Any]] = []
    for i in range(draw(st.integers(2, 5))):
        kind = draw(st.sampled_from(kinds))
        guard, actions = draw(_guard_and_actions(variables, kind))
        transitions.append(
            {"name": f"{prefix}.t{i}.{kind[:4]}", "kind": kind, "guard": guard, "actions": actions}
        )
    specs = []
    for i in range(draw(st.integers(0, 2))):
        spec = draw(S._specification(variables, i))
        specs.append({"name": f"{prefix}.{spec['name']}", "invariant": spec["invariant"]})
    return {"variables": variables, "transitions": transitions, "specifications": specs}


@st.composite
def _bridge(draw: st.DrawFn, parts: list[Model], index: int) -> dict[str, Any]:
    """A transition touching two parts: mostly an automatic in one part that a step of
    another enables (its guard reads both), else an effect, controlled or maintenance step
    from one part into the other."""
    i, j = draw(st.permutations(range(len(parts))))[:2]
    source = draw(st.sampled_from(parts[i]["variables"]))
    target = draw(st.sampled_from(parts[j]["variables"]))
    when = f"{source['name']} == {_text(draw(st.sampled_from(_values(source))))}"
    kind = draw(st.sampled_from(["automatic", "automatic", "effect", "controlled", "maintenance"]))
    values = _values(target)
    if kind == "automatic":  # progressing on the target: bridges alone never cycle
        k = draw(st.integers(0, len(values) - 2))
        m = draw(st.integers(k + 1, len(values) - 1))
        guard = f"{when} && {target['name']} == {_text(values[k])}"
        actions = [f"{target['name']} := {_text(values[m])}"]
    else:
        guard = when
        if draw(st.booleans()):
            guard += f" && {draw(S.random_atom(parts[j]['variables']))}"
        actions = [f"{target['name']} := {_text(draw(st.sampled_from(values)))}"]
    return {"name": f"bridge{index}.{kind[:4]}", "kind": kind, "guard": guard, "actions": actions}


@st.composite
def component_models(
    draw: st.DrawFn,
    bridges: bool | None = None,
) -> Structured:
    """2-3 parts over disjoint variables, at most `MAX_STATES` states in all; with
    `bridges` (drawn when None) 1-2 transitions that touch two parts;"""
    n = draw(st.integers(2, 3))
    parts: list[Model] = []
    left = MAX_STATES
    for k in range(n):
        reserve = 4 ** (n - k - 1)  # two bools for each part still to come
        part = draw(_part(PART_NAMES[k], left // reserve))
        parts.append(part)
        left //= states_of(part)
    with_bridges = draw(st.booleans()) if bridges is None else bridges
    extra = (
        [draw(_bridge(parts, i)) for i in range(draw(st.integers(1, 2)))] if with_bridges else []
    )
    variables = [v for p in parts for v in p["variables"]]
    transitions = [t for p in parts for t in p["transitions"]] + extra
    order = draw(st.permutations(range(len(variables))))
    shuffle = draw(st.permutations(range(len(transitions))))
    model: Model = {
        "variables": [dict(variables[i]) for i in order],
        "transitions": [transitions[i] for i in shuffle],
        "specifications": [s for p in parts for s in p["specifications"]],
    }
    _estimated_where_assigned(model)
    for part in parts:
        _estimated_where_assigned(part)
    return Structured(model, tuple(parts), tuple(t["name"] for t in extra))


def _automatic_enabled(m: O.OracleModel, s: O.State) -> bool:
    return any(t.kind == "automatic" and t.enabled(s) for t in m.transitions)


@st.composite
def _part_start(draw: st.DrawFn, part: Model) -> O.State:
    """Mostly a good state; often one where an automatic transition of the part is enabled
    (it must move first, or the part must be planned first); sometimes anything."""
    m = O.parse_model(part)
    every = sorted(O.all_states(m), key=repr)
    good = [s for s in every if s not in O.bad_states(m)]
    busy = [s for s in good if _automatic_enabled(m, s)]
    mode = draw(st.integers(0, 9))
    if mode < 4 and good:
        return draw(st.sampled_from(good))
    if mode < 7 and busy:
        return draw(st.sampled_from(busy))
    if mode < 9:
        return O.initial_state(m)
    return draw(st.sampled_from(every))


@st.composite
def _part_goal(draw: st.DrawFn, part: Model, start: O.State, maintenance: bool) -> list[str]:
    """Atoms `x == v` where a random walk in the part ends (that state may have an
    automatic enabled), else a blind atom false at the start."""
    m = O.parse_model(part)
    walked = draw(S._walk_goal(m, start, maintenance))
    if walked is not None:
        return walked.split(" && ")
    var = draw(st.sampled_from(part["variables"]))
    i = [v["name"] for v in part["variables"]].index(var["name"])
    others = [v for v in _values(var) if v != start[i]] or _values(var)
    return [f"{var['name']} == {_text(draw(st.sampled_from(others)))}"]


@st.composite
def _unmet_atom(draw: st.DrawFn, variables: list[Var], start: dict[str, Any]) -> str:
    """`x == v` with v not x's start value (when x has another value)."""
    var = draw(st.sampled_from(variables))
    values = [v for v in _values(var) if v != start[var["name"]]] or _values(var)
    return f"{var['name']} == {_text(draw(st.sampled_from(values)))}"


@st.composite
def component_queries(draw: st.DrawFn, structured: Structured) -> dict[str, Any]:
    """A query on a `component_models` model.

    Keys as `tests/strategies.queries` and `query_extensions` give them (`start`, `goal`,
    `maintenance`, `forbidden`, `phi`, `disabled`, `max_steps`).  The goal's conjuncts are
    each within one part (atoms), except sometimes one disjunction tying two parts; it
    touches one, two or all parts.  `forbidden` and `phi` are per part too.
    """
    parts = structured.parts
    maintenance = draw(st.booleans())
    starts = [draw(_part_start(p)) for p in parts]
    start: dict[str, Any] = {}
    for part, s in zip(parts, starts, strict=True):
        start.update(O.state_to_dict(O.parse_model(part), s))
    touched = draw(
        st.sampled_from([1, 1, 2, len(parts)]).flatmap(
            lambda k: st.lists(
                st.sampled_from(range(len(parts))), min_size=k, max_size=k, unique=True
            )
        )
    )
    goal: list[str] = []
    for k in sorted(touched):
        goal += draw(_part_goal(parts[k], starts[k], maintenance))
    if len(parts) > 1 and draw(st.integers(0, 4)) == 4:  # a conjunct that ties two parts
        i, j = draw(st.permutations(range(len(parts))))[:2]
        left = draw(_unmet_atom(parts[i]["variables"], start))
        right = draw(_unmet_atom(parts[j]["variables"], start))
        goal.append(f"({left} || {right})")
    forbidden: list[str] = []
    for _ in range(draw(st.integers(0, 2))):
        part = draw(st.sampled_from(parts))
        atom = draw(_unmet_atom(part["variables"], start))
        if draw(st.integers(0, 3)) == 3:
            atom += f" && {draw(S.random_atom(part['variables']))}"
        forbidden.append(atom)
    phi = None
    if draw(st.integers(0, 2)) == 2:
        conjuncts = []
        for _ in range(draw(st.integers(1, 2))):
            part = draw(st.sampled_from(parts))
            atom = draw(_unmet_atom(part["variables"], start))
            conjuncts.append("!(" + atom + ")" if draw(st.integers(0, 4)) else atom)
        phi = " && ".join(conjuncts)
    names = [t["name"] for t in structured.model["transitions"]]
    disabled = []
    if draw(st.integers(0, 3)) == 3:
        disabled = draw(st.lists(st.sampled_from(names), min_size=1, max_size=2, unique=True))
    elif structured.bridges and draw(st.booleans()):
        disabled = [draw(st.sampled_from(structured.bridges))]
    return {
        "start": start,
        "goal": " && ".join(goal),
        "maintenance": maintenance,
        "forbidden": forbidden,
        "phi": phi,
        "disabled": disabled,
        "max_steps": draw(st.sampled_from([12, 12, 12, 6, 4, 3])),
    }
