"""Hypothesis strategies for random small flat models, start states and goal expressions.

Models are plain dicts shaped like the YAML (``variables``/``transitions``/``specifications``)
so the same example can be fed to the real planner and to ``tests/support/oracle.py``.
Generation is biased towards useful examples: automatic transitions mostly make
progress (no automatic cycles), and queries use the oracle to pick good starts and goals
reached by short random walks, so that many plans are non-trivial.
"""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from tests.support import oracle as O

VAR_NAMES = ("a", "b", "c", "b.c", "x1", "r1.pos", "r2.ref", "nr.running", "d.e_f", "y")
VAR_KINDS = ("measured", "estimated", "command")
TRANSITION_KIND_WEIGHTS = (
    ("controlled", 10),
    ("automatic", 3),
    ("effect", 3),
    ("maintenance", 2),
)
MAX_STATES = 2000

Var = dict[str, Any]


def domain_values(var: Var) -> list[Any]:
    """Concrete values of a generated variable: bools, or the listed values."""
    if var["domain"] == "bool":
        return [False, True]
    return list(var["domain"])


def _initial(var: Var) -> Any:
    return var.get("initial", domain_values(var)[0])


def _text(value: Any) -> str:
    """How a value is written in an expression or action."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _same_domain(u: Var, v: Var) -> bool:
    return u is not v and domain_values(u) == domain_values(v)


@st.composite
def _spacing(draw: st.DrawFn, op: str) -> str:
    """Operators sometimes written without surrounding blanks, to exercise tokenizers."""
    return op if draw(st.integers(0, 3)) == 3 else f" {op} "


@st.composite
def random_atom(draw: st.DrawFn, variables: list[Var]) -> str:
    """A literal, a bool variable, ``x == v``/``x != v`` or ``x == y`` for same domains."""
    var = draw(st.sampled_from(variables))
    op = draw(_spacing(draw(st.sampled_from(["==", "!="]))))
    partners = [w for w in variables if _same_domain(var, w)]
    choice = draw(st.integers(0, 9))  # Hypothesis favours 0: make it the common case
    if choice == 9:
        return draw(st.sampled_from(["true", "false"]))
    if choice == 8 and var["domain"] == "bool":
        return str(var["name"])
    if choice >= 6 and partners:
        return f"{var['name']}{op}{draw(st.sampled_from(partners))['name']}"
    return f"{var['name']}{op}{_text(draw(st.sampled_from(domain_values(var))))}"


@st.composite
def random_expression(draw: st.DrawFn, variables: list[Var], max_depth: int = 3) -> str:
    """A random expression over ``variables`` using every operator of the grammar.

    Binary operands are parenthesised only sometimes, so precedence and the
    right-associativity of ``->`` are exercised; ``!`` always gets an atom or parentheses.
    """
    if max_depth <= 0 or draw(st.integers(0, 2)) == 0:
        return draw(random_atom(variables))
    op = draw(st.sampled_from(["&&", "!", "||", "->", "()"]))
    if op == "()":
        return f"({draw(random_expression(variables, max_depth - 1))})"
    if op == "!":
        inner = draw(random_expression(variables, max_depth - 1))
        simple = inner.replace(".", "").replace("_", "").isalnum()
        return f"!{inner}" if simple else f"!({inner})"
    parts = []
    for _ in range(2):
        sub = draw(random_expression(variables, max_depth - 1))
        parts.append(f"({sub})" if draw(st.booleans()) else sub)
    return parts[0] + draw(_spacing(op)) + parts[1]


@st.composite
def _variable(draw: st.DrawFn, name: str) -> Var:
    var: Var = {"name": name}
    size = draw(st.sampled_from([0, 0, 2, 3, 4]))
    var["domain"] = "bool" if size == 0 else [f"v{i}" for i in range(size)]
    if draw(st.booleans()):
        var["initial"] = draw(st.sampled_from(domain_values(var)))
    if draw(st.booleans()):
        var["kind"] = draw(st.sampled_from(VAR_KINDS))
    return var


@st.composite
def _actions(draw: st.DrawFn, variables: list[Var]) -> list[str]:
    """1-2 assignments with distinct targets; sources are values or same-domain variables."""
    targets = draw(
        st.lists(st.sampled_from(variables), min_size=1, max_size=2, unique_by=lambda v: v["name"])
    )
    actions = []
    for var in targets:
        partners = [w for w in variables if _same_domain(var, w)]
        if partners and draw(st.integers(0, 3)) == 3:
            source = draw(st.sampled_from(partners))["name"]
        else:
            source = _text(draw(st.sampled_from(domain_values(var))))
        actions.append(f"{var['name']} := {source}")
    return actions


@st.composite
def _progressing_automatic(draw: st.DrawFn, variables: list[Var]) -> tuple[str, list[str]]:
    """Guard ``x == v_i && ...``, action ``x := v_j`` with j > i.

    Each such step raises the sum of value indices, so these alone never form a cycle.
    """
    candidates = [v for v in variables if len(domain_values(v)) >= 2]
    var = draw(st.sampled_from(candidates))
    values = domain_values(var)
    i = draw(st.integers(0, len(values) - 2))
    j = draw(st.integers(i + 1, len(values) - 1))
    guard = f"{var['name']} == {_text(values[i])}"
    if draw(st.booleans()):
        guard += f" && ({draw(random_expression(variables, 1))})"
    return guard, [f"{var['name']} := {_text(values[j])}"]


@st.composite
def _structured(draw: st.DrawFn, variables: list[Var]) -> tuple[str, list[str]]:
    """Station-like shapes that keep the state graph connected so plans are non-trivial:
    a chain step ``x == v_i -> x := v_i+1`` or a goto ``x != v_j -> x := v_j``, sometimes
    with a precondition on another variable and a second action."""
    var = draw(st.sampled_from(variables))
    values = domain_values(var)
    i = draw(st.integers(0, len(values) - 1))
    j = (i + 1) % len(values)
    if draw(st.integers(0, 2)) < 2:
        guard = f"{var['name']} == {_text(values[i])}"
    else:
        guard = f"{var['name']} != {_text(values[j])}"
    others = [v for v in variables if v is not var]
    if draw(st.integers(0, 2)) == 2:  # precondition on another variable: longer plans
        other = draw(st.sampled_from(others))
        guard += f" && {other['name']} == {_text(draw(st.sampled_from(domain_values(other))))}"
    elif draw(st.integers(0, 3)) == 3:
        guard += f" && {draw(random_atom(variables))}"
    actions = [f"{var['name']} := {_text(values[j])}"]
    if draw(st.integers(0, 3)) == 3:
        actions += draw(_actions(others))[:1]
    return guard, actions


@st.composite
def _effect(draw: st.DrawFn, variables: list[Var]) -> tuple[str, list[str]]:
    """Mostly the ``ref != pos -> pos := ref`` pattern when a same-domain pair exists."""
    pairs = [(u, w) for u in variables for w in variables if _same_domain(u, w)]
    if pairs and draw(st.integers(0, 2)) < 2:
        pos, ref = draw(st.sampled_from(pairs))
        return f"{ref['name']} != {pos['name']}", [f"{pos['name']} := {ref['name']}"]
    return draw(random_expression(variables, 2)), draw(_actions(variables))


@st.composite
def _specification(draw: st.DrawFn, variables: list[Var], index: int) -> dict[str, str]:
    """Mostly ``!(atom && atom [&& atom])``: specs forbid a small part of the state space."""
    if draw(st.integers(0, 3)) < 3:
        left, right = draw(random_atom(variables)), draw(random_atom(variables))
        extra = f" && {draw(random_atom(variables))}" if draw(st.booleans()) else ""
        invariant = f"!({left} && {right}{extra})"
    else:
        invariant = draw(random_expression(variables, 2))
    return {"name": f"spec{index}", "invariant": invariant}


@st.composite
def flat_models(draw: st.DrawFn, max_vars: int = 5, max_transitions: int = 8) -> dict[str, Any]:
    """A random flat model dict with at most ``MAX_STATES`` states."""
    n_vars = draw(st.integers(2, max(2, max_vars)))
    names = draw(
        st.lists(st.sampled_from(VAR_NAMES), min_size=n_vars, max_size=n_vars, unique=True)
    )
    variables: list[Var] = []
    n_states = 1
    for name in names:
        var = draw(_variable(name))
        if n_states * len(domain_values(var)) > MAX_STATES:
            var = {"name": name, "domain": "bool"}
        n_states *= len(domain_values(var))
        variables.append(var)

    kinds = [k for k, w in TRANSITION_KIND_WEIGHTS for _ in range(w)]
    transitions: list[dict[str, Any]] = []
    top = max(1, max_transitions)
    low = 1 if draw(st.integers(0, 3)) == 3 else (top + 1) // 2  # mostly the upper half
    for i in range(draw(st.integers(low, top))):
        kind = draw(st.sampled_from(kinds))
        if kind == "automatic" and draw(st.integers(0, 4)) < 4:
            guard, actions = draw(_progressing_automatic(variables))
        elif kind == "effect":
            guard, actions = draw(_effect(variables))
        elif kind != "automatic" and draw(st.integers(0, 2)) < 2:
            guard, actions = draw(_structured(variables))
        else:
            guard, actions = draw(random_expression(variables)), draw(_actions(variables))
        entry: dict[str, Any] = {"name": f"t{i}.{kind[:4]}"}
        if kind != "controlled" or draw(st.booleans()):
            entry["kind"] = kind
        if guard != "true" or draw(st.booleans()):
            entry["guard"] = guard
        entry["actions"] = actions
        transitions.append(entry)

    specs = [draw(_specification(variables, i)) for i in range(draw(st.integers(0, 2)))]
    # The planner rejects controlled and automatic transitions that assign measured variables
    # (only the world and operators change those); such variables become estimated instead.
    controlled_targets = {
        action.split(":=")[0].strip()
        for t in transitions
        if t.get("kind", "controlled") in ("controlled", "automatic")
        for action in t["actions"]
    }
    for var in variables:
        if var.get("kind") == "measured" and var["name"] in controlled_targets:
            var["kind"] = "estimated"
    return {"variables": variables, "transitions": transitions, "specifications": specs}


def _assigned(model: dict[str, Any]) -> list[tuple[str, str]]:
    """(variable, value text) pairs that some action assigns as a constant."""
    names = {v["name"] for v in model["variables"]}
    pairs = []
    for t in model["transitions"]:
        for action in t.get("actions", []):
            target, source = (part.strip() for part in action.split(":="))
            if source not in names:
                pairs.append((target, source))
    return sorted(set(pairs))


@st.composite
def _goal(draw: st.DrawFn, model: dict[str, Any], start: dict[str, Any]) -> str:
    """Mostly 1-2 atoms ``x == v`` false at the start, preferring values some action sets,
    so that many queries need a non-trivial plan."""
    variables: list[Var] = model["variables"]
    if draw(st.integers(0, 4)) == 4:
        return draw(random_expression(variables))
    by_name = {v["name"]: v for v in variables}
    reachable = [(n, v) for n, v in _assigned(model) if v != _text(start[n])]
    atoms: dict[str, str] = {}
    for _ in range(1 + draw(st.booleans())):
        if reachable and draw(st.integers(0, 3)) < 3:
            name, value = draw(st.sampled_from(reachable))
        else:
            var = draw(st.sampled_from(variables))
            name = var["name"]
            others = [v for v in domain_values(by_name[name]) if v != start[name]]
            value = _text(draw(st.sampled_from(others)))
        atoms.setdefault(name, value)
    return " && ".join(f"{n} == {v}" for n, v in atoms.items())


@st.composite
def _walk_goal(draw: st.DrawFn, m: O.OracleModel, start: O.State, maintenance: bool) -> str | None:
    """Atoms describing where a short random walk of legal steps ends (None if nowhere new).

    The oracle is used only to propose the example; the minimal plan may still be
    shorter than the walk, or absent if other constraints get in the way.
    """
    bad = O.bad_states(m)
    s = start
    seen = {start}
    for _ in range(7 - draw(st.integers(1, 6))):  # Hypothesis favours small draws
        succs = [t for _, t in O.steps(m, s, maintenance=maintenance)]
        options = [t for t in succs if t not in bad and t not in seen]
        if not options:
            break
        s = draw(st.sampled_from(options))
        seen.add(s)
    changed = [i for i, v in enumerate(m.variables) if s[i] != start[i]]
    if not changed:
        return None
    if draw(st.booleans()):
        changed = list(range(len(m.variables)))  # the whole end state: longer plans
    else:
        changed = draw(st.lists(st.sampled_from(changed), min_size=1, max_size=2, unique=True))
    return " && ".join(f"{m.variables[i].name} == {_text(s[i])}" for i in sorted(changed))


@st.composite
def queries(draw: st.DrawFn, model: dict[str, Any]) -> dict[str, Any]:
    """``{"start": name->value, "goal": expression, "maintenance": bool}`` for ``model``.

    Starts are mostly the initial state or a random good state (some are bad, to cover
    ``bad_start``); goals are mostly the end of a random walk, else blind atoms/expressions.
    """
    variables: list[Var] = model["variables"]
    m = O.parse_model(model)
    good = sorted(set(O.all_states(m)) - O.bad_states(m), key=repr)
    mode = draw(st.integers(0, 9))
    if mode < 6 and good:
        start = draw(st.sampled_from(good))
    elif mode < 9:
        start = O.initial_state(m)
    else:
        start = tuple(draw(st.sampled_from(domain_values(v))) for v in variables)
    maintenance = draw(st.booleans())
    start_dict = O.state_to_dict(m, start)
    goal = draw(_walk_goal(m, start, maintenance)) if draw(st.integers(0, 3)) < 3 else None
    if goal is None:
        goal = draw(_goal(model, start_dict))
    return {"start": start_dict, "goal": goal, "maintenance": maintenance}


@st.composite
def query_extensions(
    draw: st.DrawFn, model: dict[str, Any], start: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Optional extras: ``forbidden`` (0-2 predicates), ``phi``, ``disabled``, ``max_steps``.

    Given ``start``, forbidden atoms mostly avoid it, so few queries end as ``bad_start``.
    """
    variables: list[Var] = model["variables"]
    names = [t["name"] for t in model["transitions"]]
    forbidden = []
    for _ in range(draw(st.integers(0, 2))):
        var = draw(st.sampled_from(variables))
        values = [v for v in domain_values(var) if start is None or v != start[var["name"]]]
        if draw(st.integers(0, 3)) == 3:
            forbidden.append(draw(random_atom(variables)))
        else:
            forbidden.append(f"{var['name']} == {_text(draw(st.sampled_from(values)))}")
    return {
        "forbidden": forbidden,
        "phi": draw(st.one_of(st.none(), random_expression(variables, 2))),
        "disabled": draw(st.lists(st.sampled_from(names), max_size=2, unique=True)),
        "max_steps": 8 - draw(st.integers(0, 8)),
    }


# --------------------------------------------------------------------------- independent parts

PART_NAMES = ("a", "b", "r.pos", "r.ref", "flag")


@st.composite
def _part(draw: st.DrawFn, prefix: str, max_states: int) -> tuple[list[Var], list[dict[str, Any]]]:
    """One part's variables (names under ``prefix``) and its automatic, effect and
    controlled transitions, each reading and writing only the part's own variables."""
    n_vars = draw(st.integers(2, 3))  # the shapes below need two variables
    names = draw(
        st.lists(st.sampled_from(PART_NAMES), min_size=n_vars, max_size=n_vars, unique=True)
    )
    variables: list[Var] = []
    states = 1
    for name in names:
        var = draw(_variable(f"{prefix}.{name}"))
        if states * len(domain_values(var)) > max_states:
            var = {"name": f"{prefix}.{name}", "domain": "bool"}
            if states * 2 > max_states:
                break
        states *= len(domain_values(var))
        variables.append(var)
    # at least one automatic and one effect per part, so that automatics of several parts
    # can be enabled together and effects wait for all of them (the global priority)
    more = draw(st.lists(st.sampled_from(["automatic", "effect", "controlled"]), max_size=4))
    kinds = ["automatic", "effect", *more]
    transitions = []
    for i, kind in enumerate(kinds):
        if kind == "automatic" and draw(st.integers(0, 9)) < 9:  # else often a cycle
            guard, actions = draw(_progressing_automatic(variables))
        elif kind == "effect":
            guard, actions = draw(_effect(variables))
        elif kind == "controlled":
            guard, actions = draw(_structured(variables))
        else:
            guard, actions = draw(random_expression(variables)), draw(_actions(variables))
        transitions.append(
            {"name": f"{prefix}.t{i}", "kind": kind, "guard": guard, "actions": actions}
        )
    return variables, transitions


@st.composite
def independent_models(draw: st.DrawFn) -> dict[str, Any]:
    """A flat model of 2-3 parts over disjoint variables (at most ``MAX_STATES`` states in
    all), each with automatic, effect and controlled transitions and up to two
    specifications (the first part at least one); a few controlled transitions may read
    and write across parts (they do not tie parts together for synthesis, as bad states
    do not depend on them)."""
    parts = draw(st.integers(2, 3))
    budget = int(MAX_STATES ** (1 / parts))
    variables: list[Var] = []
    transitions: list[dict[str, Any]] = []
    specs: list[dict[str, str]] = []
    for k in range(parts):
        part_vars, part_transitions = draw(_part(f"p{k}", budget))
        variables += part_vars
        transitions += part_transitions
        # parts without a specification too: their automatics still take priority
        for _ in range(draw(st.integers(0 if k else 1, 2))):
            specs.append(draw(_specification(part_vars, len(specs))))
    prefix = {v["name"]: v["name"].split(".")[0] for v in variables}
    copies = [
        f"{u['name']} := {w['name']}"
        for u in variables
        for w in variables
        if _same_domain(u, w) and prefix[u["name"]] != prefix[w["name"]]
    ]
    for i in range(draw(st.integers(0, 2))):
        guard = draw(random_expression(variables, 2))
        if copies and draw(st.booleans()):  # the next state's part depends on another part
            actions = [draw(st.sampled_from(copies))]
        else:
            actions = draw(_actions(variables))
        transitions.append({"name": f"across.t{i}", "guard": guard, "actions": actions})
    targets = {
        action.split(":=")[0].strip()
        for t in transitions
        if t.get("kind", "controlled") in ("controlled", "automatic")
        for action in t["actions"]
    }
    for var in variables:  # as in flat_models: only the world changes measured variables
        if var.get("kind") == "measured" and var["name"] in targets:
            var["kind"] = "estimated"
    return {"variables": variables, "transitions": transitions, "specifications": specs}
