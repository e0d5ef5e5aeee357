"""Hypothesis strategies for models with the structure the bdd engine's reductions exploit.

`tests/support/strategies.py` draws flat models of a few variables, which almost never split into
independent components or hold interchangeable objects.  These strategies build them on
purpose, from the same building blocks, so that every reduction of `planner.planning.relevance`
and `planner.planning.symmetry` is exercised against the oracle:

- `component_models`: 2-3 *parts* over disjoint variables, each a small random model with
  every kind of transition and its own specifications, optionally joined by *bridges*
  (an automatic whose guard reads two parts, an effect, a controlled or maintenance step
  that touches two);
- `symmetric_models`: 2-3 copies of a random template object named with numbered tokens
  (`bp1.state`, `r.goto_bp1`, the value `bp1` of the shared `r.pos`) around a shared robot,
  optionally with one copy's guard altered so that the swaps are not automorphisms;
- queries for each, touching one, two or all parts, with extras (`forbidden`, `always`,
  `disabled`) per part, and starts chosen to have automatic transitions enabled;
- `relaxations`: such a query turned into a forbidden-state recovery.

Models are plain dicts shaped like the YAML; the extra knowledge (which transitions join
two parts, which copy's transition was altered) travels beside them so the tests can say
what the reductions must do.  Every model has at most `MAX_STATES` states, so that the oracle
can enumerate them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from hypothesis import strategies as st

from tests.support import oracle as O
from tests.support import strategies as S

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
    targets: tuple[str | None, ...] = ()  # per part, where its maintenance shortcut leads


@st.composite
def _shortcut(draw: st.DrawFn, variables: list[Var], prefix: str) -> list[dict[str, Any]]:
    """A controlled chain `x == v_i -> x := v_i+1` through a variable's values and a
    maintenance step straight to its last value: fewer steps, or no maintenance."""
    var = max(variables, key=lambda v: len(_values(v)))
    values = [_text(v) for v in _values(var)]
    name = var["name"]
    chain = [
        {
            "name": f"{prefix}.chain{i}",
            "kind": "controlled",
            "guard": f"{name} == {values[i]}",
            "actions": [f"{name} := {values[i + 1]}"],
        }
        for i in range(len(values) - 1)
    ]
    jump = {
        "name": f"{prefix}.jump.main",
        "kind": "maintenance",
        "guard": f"{name} != {values[-1]}",
        "actions": [f"{name} := {values[-1]}"],
    }
    if draw(st.booleans()):  # the jump leaves an automatic of the part to finish
        other = draw(st.sampled_from([v for v in variables if v is not var]))
        flag = _values(other)
        jump["actions"].append(f"{other['name']} := {_text(flag[0])}")
        chain.append(
            {
                "name": f"{prefix}.settle.auto",
                "kind": "automatic",
                "guard": f"{name} == {values[-1]} && {other['name']} == {_text(flag[0])}",
                "actions": [f"{other['name']} := {_text(flag[-1])}"],
            }
        )
    return [*chain, jump]


@st.composite
def _part(
    draw: st.DrawFn, prefix: str, budget: int, shortcuts: bool = False, specified: bool = False
) -> Model:
    """A small random model over `prefix.a`, `prefix.b` (and maybe `prefix.c`); with
    `shortcuts`, a chain of controlled steps that one maintenance step can skip; with
    `specified`, at least one specification."""
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
    if shortcuts:
        transitions += draw(_shortcut(variables, prefix))
    specs = []
    for i in range(draw(st.integers(int(specified), 2))):
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
    shortcuts: bool = False,
    specified: bool = False,
) -> Structured:
    """2-3 parts over disjoint variables, at most `MAX_STATES` states in all; with
    `bridges` (drawn when None) 1-2 transitions that touch two parts; with `shortcuts`
    each part has a chain of controlled steps that a maintenance step skips; with
    `specified` the first part has a specification."""
    n = draw(st.integers(2, 3))
    parts: list[Model] = []
    left = MAX_STATES
    for k in range(n):
        reserve = 4 ** (n - k - 1)  # two bools for each part still to come
        part = draw(_part(PART_NAMES[k], left // reserve, shortcuts, specified and k == 0))
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
    targets = tuple(_target(part) for part in parts)
    return Structured(model, tuple(parts), tuple(t["name"] for t in extra), targets)


def _target(part: Model) -> str | None:
    """`x == v` for the part's maintenance shortcut `x := v`, if it has one."""
    for t in part["transitions"]:
        if t["name"].endswith(".jump.main"):
            target, value = (side.strip() for side in t["actions"][0].split(":="))
            return f"{target} == {value}"
    return None


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
        target = structured.targets[k] if structured.targets else None
        if target is not None and draw(st.booleans()):
            goal.append(target)  # a shortcut's end: fewer steps with maintenance
        else:
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


# --------------------------------------------------------------------------- symmetric objects

TOKEN = "bpX"  # the template object's token, replaced by bp1, bp2, ...
_TOKEN = re.compile(r"(?<![A-Za-z0-9])bpX(?![A-Za-z0-9])")
OBJECT_VALUES = ("empty", "half", "full")  # no numbered tokens: they would be candidates too


@dataclass(frozen=True)
class Symmetric:
    """Copies of one template object around a shared robot.

    `altered` names the transition of the last copy whose guard was made different from
    its siblings' images (None: the copies are exact images of each other, so every swap
    of two copies is an automorphism of the model).
    """

    model: Model
    copies: tuple[str, ...]  # bp1, bp2, ...
    altered: str | None
    template_goals: tuple[str, ...]  # atoms over the template object, `bpX` in them


def instantiate(text: str, token: str) -> str:
    return _TOKEN.sub(token, text)


@st.composite
def _object_variables(draw: st.DrawFn, budget: int) -> list[Var]:
    """The template object's variables: `bpX.state` and maybe a flag `bpX.ok`."""
    size = draw(st.sampled_from([2, 3, 3, 0]))
    state: Var = {"name": "bpX.state", "domain": list(OBJECT_VALUES[:size]) if size else "bool"}
    if len(_values(state)) > budget:
        state = {"name": "bpX.state", "domain": "bool"}
    variables = [state]
    if len(_values(state)) * 2 <= budget and draw(st.booleans()):
        variables.append({"name": "bpX.ok", "domain": "bool"})
    return variables


@st.composite
def symmetric_models(
    draw: st.DrawFn, altered: bool | None = None, specified: bool = False
) -> Symmetric:
    """2-3 copies of a random template object that the shared robot `r` visits.

    The robot's `r.goto_bpX` (controlled) sets `r.ref`, the effect `r.arrive` moves
    `r.pos` there, `r.go_home` brings it back; each copy has 2-4 random transitions over its
    own variables, the shared `tool.busy` and `r.pos == bpX`, and 0-2 specifications.  With
    `altered` (drawn when None), one of the last copy's transitions gets an extra guard
    conjunct that its siblings lack.  With `specified`, the template has a specification.
    """
    k = draw(st.integers(2, 3))
    copies = tuple(f"bp{i}" for i in range(1, k + 1))
    robot = ["home", *copies]
    shared: list[Var] = [
        {"name": "r.pos", "domain": robot},
        {"name": "r.ref", "domain": robot},
        {"name": "tool.busy", "domain": "bool"},
    ]
    shared_states = len(robot) ** 2 * 2
    per_object = int((MAX_STATES // shared_states) ** (1 / k))
    own = draw(_object_variables(per_object))
    # the template sees r.pos with the values it may name: home and its own token
    view = [*own, {"name": "r.pos", "domain": ["home", TOKEN]}, shared[2]]
    template: list[dict[str, Any]] = [
        {
            "name": "r.goto_bpX",
            "kind": "controlled",
            "guard": "r.ref == home && r.pos == home",
            "actions": ["r.ref := bpX"],
        }
    ]
    if draw(st.booleans()):
        template[0]["guard"] += f" && {draw(S.random_atom(own))}"
    # the work on an object: steps through its state's values while the robot is there,
    # the last one sometimes automatic (an ability's finish)
    stages = [_text(v) for v in _values(own[0])]
    for i in range(len(stages) - 1):
        finish = i == len(stages) - 2 and len(stages) > 2 and draw(st.booleans())
        template.append(
            {
                "name": f"bpX.work{i}",
                "kind": "automatic" if finish else "controlled",
                "guard": f"r.pos == bpX && bpX.state == {stages[i]}",
                "actions": [f"bpX.state := {stages[i + 1]}"],
            }
        )
    kinds = _kinds()
    for i in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(kinds))
        if kind != "automatic" and draw(st.integers(0, 3)) == 3:
            guard, actions = draw(S.random_expression(view, 1)), draw(S._actions(own))
        else:
            guard, actions = draw(_guard_and_actions([*own, shared[2]], kind))
        if draw(st.integers(0, 2)) < 2:
            guard = f"r.pos == bpX && ({guard})"
        template.append(
            {"name": f"bpX.t{i}.{kind[:4]}", "kind": kind, "guard": guard, "actions": actions}
        )
    specs = []
    for i in range(draw(st.integers(int(specified), 2))):
        spec = draw(S._specification(view, i))
        specs.append({"name": f"bpX.{spec['name']}", "invariant": spec["invariant"]})
    shared_transitions: list[dict[str, Any]] = [
        {
            "name": "r.arrive",
            "kind": "effect",
            "guard": "r.ref != r.pos",
            "actions": ["r.pos := r.ref"],
        },
        {
            "name": "r.go_home",
            "kind": "controlled",
            "guard": "r.ref != home && r.pos == r.ref",
            "actions": ["r.ref := home"],
        },
        {
            "name": "tool.reset",
            "kind": draw(st.sampled_from(["controlled", "maintenance"])),
            "guard": "tool.busy",
            "actions": ["tool.busy := false"],
        },
    ]
    variables = [*shared] + [{**v, "name": instantiate(v["name"], c)} for c in copies for v in own]
    transitions = list(shared_transitions)
    for c in copies:
        for t in template:
            transitions.append(
                {
                    "name": instantiate(t["name"], c),
                    "kind": t["kind"],
                    "guard": instantiate(t["guard"], c),
                    "actions": [instantiate(a, c) for a in t["actions"]],
                }
            )
    specifications = [
        {"name": instantiate(s["name"], c), "invariant": instantiate(s["invariant"], c)}
        for c in copies
        for s in specs
    ]
    state = own[0]
    if len(_values(state)) > 2 and draw(st.booleans()):  # the copies exclude each other
        top = _text(_values(state)[-1])
        pairs = [
            f"!({a}.state == {top} && {b}.state == {top})"
            for n, a in enumerate(copies)
            for b in copies[n + 1 :]
        ]
        specifications.append({"name": "objects.apart", "invariant": " && ".join(pairs)})
    changed = draw(st.booleans()) if altered is None else altered
    altered_name = None
    if changed:
        last = copies[-1]
        mine = [t for t in transitions if last in re.split(r"[._]", t["name"])]
        uncontrollable = [t for t in mine if t["kind"] in ("automatic", "effect")]
        if uncontrollable and draw(st.booleans()):  # then no swap with this copy holds
            mine = uncontrollable
        target = draw(st.sampled_from(mine))
        last_view = [{**v, "name": instantiate(v["name"], last)} for v in own] + [shared[2]]
        target["guard"] = f"({target['guard']}) && {draw(S.random_atom(last_view))}"
        altered_name = target["name"]
    values = [v for v in _values(state) if v != _values(state)[0]]
    goals = tuple(f"bpX.state == {_text(v)}" for v in values)
    if len(own) > 1:
        goals += ("bpX.ok",)
    return Symmetric(
        {"variables": variables, "transitions": transitions, "specifications": specifications},
        copies,
        altered_name,
        goals,
    )


@st.composite
def symmetric_queries(draw: st.DrawFn, symmetric: Symmetric) -> dict[str, Any]:
    """A query on a `symmetric_models` model that keeps the symmetry (the goal over every
    copy, or the shared part only) or breaks it (the goal, a forbidden predicate or a
    disabled transition on one copy); `symmetric` says which was drawn."""
    model = symmetric.model
    copies = symmetric.copies
    m = O.parse_model(model)
    good = sorted(set(O.all_states(m)) - O.bad_states(m), key=repr)
    maintenance = draw(st.booleans())
    mode = draw(st.integers(0, 9))
    start = O.initial_state(m) if mode < 5 or not good else draw(st.sampled_from(good))
    template = draw(st.sampled_from(symmetric.template_goals))
    keeps = draw(st.booleans())
    forbidden: list[str] = []
    disabled: list[str] = []
    if keeps:
        shape = draw(st.sampled_from(["all", "all", "any", "shared"]))
        if shape == "shared":
            goal = draw(st.sampled_from(["tool.busy", "r.pos != home && !tool.busy"]))
        else:
            glue = " && " if shape == "all" else " || "
            goal = glue.join(f"({instantiate(template, c)})" for c in copies)
        if draw(st.integers(0, 3)) == 3:
            forbidden.append("tool.busy && r.pos != home")
        if symmetric.altered is not None and draw(st.booleans()):
            # without the altered transition and its images the swaps hold again
            disabled += [_on(symmetric.altered, copies[-1], c) for c in copies]
    else:
        one = draw(st.sampled_from(copies))
        breaking = draw(st.sampled_from(["goal", "goal", "forbidden", "disabled"]))
        goal = instantiate(template, one)
        if breaking != "goal":
            goal = " && ".join(f"({instantiate(template, c)})" for c in copies)
        if breaking == "forbidden":
            forbidden.append(f"r.pos == {one} && tool.busy")
        elif breaking == "disabled":
            mine = [n for n in _names(model) if one in re.split(r"[._]", n)]
            disabled.append(draw(st.sampled_from(mine)))
    return {
        "start": O.state_to_dict(m, start),
        "goal": goal,
        "maintenance": maintenance,
        "forbidden": forbidden,
        "phi": None,
        "disabled": disabled,
        "max_steps": 12,
        "symmetric": keeps,
    }


def _names(model: Model) -> list[str]:
    return [t["name"] for t in model["transitions"]]


def _on(name: str, token: str, other: str) -> str:
    """The same transition on another copy: `r.goto_bp3` -> `r.goto_bp1`."""
    return "".join(other if part == token else part for part in re.split(r"([._])", name))


# --------------------------------------------------------------------------- recovery queries


@st.composite
def relaxations(draw: st.DrawFn, model: Model, query: dict[str, Any]) -> dict[str, Any]:
    """The query turned into a forbidden-state recovery: mostly from a bad state, with the
    specifications it is bad for relaxed (where recovery starts), else 1-2 specifications
    relaxed for the query's own start; the goal mostly "true" (any good state).  `relaxed`
    is empty when the model has no specification."""
    names = [s["name"] for s in model["specifications"]]
    if not names:
        return {**query, "relaxed": []}
    m = O.parse_model(model)
    bad = sorted(O.bad_states(m), key=repr)
    start = query["start"]
    if bad and draw(st.integers(0, 3)) < 3:
        state = draw(st.sampled_from(bad))
        relaxed = O.violated(m, state)
        start = O.state_to_dict(m, state)
    else:
        relaxed = draw(st.lists(st.sampled_from(names), min_size=1, max_size=2, unique=True))
    forbidden = query["forbidden"] if draw(st.integers(0, 3)) == 3 else []
    goal = query["goal"] if draw(st.integers(0, 2)) == 2 else "true"
    return {**query, "start": start, "goal": goal, "forbidden": forbidden, "relaxed": relaxed}


# the smallest model of `component_models(shortcuts=True)`, written out: two chains of three
# steps, each with a maintenance step that jumps to its end
SHORTCUTS = """
variables:
  - {name: x, domain: [v0, v1, v2, v3]}
  - {name: y, domain: [v0, v1, v2, v3]}
transitions:
  - {name: x.c0, guard: "x == v0", actions: ["x := v1"]}
  - {name: x.c1, guard: "x == v1", actions: ["x := v2"]}
  - {name: x.c2, guard: "x == v2", actions: ["x := v3"]}
  - {name: x.jump, kind: maintenance, guard: "x != v3", actions: ["x := v3"]}
  - {name: y.c0, guard: "y == v0", actions: ["y := v1"]}
  - {name: y.c1, guard: "y == v1", actions: ["y := v2"]}
  - {name: y.c2, guard: "y == v2", actions: ["y := v3"]}
  - {name: y.jump, kind: maintenance, guard: "y != v3", actions: ["y := v3"]}
"""
