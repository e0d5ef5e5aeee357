"""The flat model of DESIGN.md section 8 read from YAML: variables, transitions, specifications.

Every reader records its problems at their line and column (`planner.reading.yaml_reader`)
and goes on, so that an engineer sees every mistake at once; the station form
(`planner.reading.station`) reads its resources' variables and transitions with these.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping

import yaml

from planner.model.expression_syntax import is_name
from planner.model.expression_text import Scope
from planner.model.expressions import TRUE, Assign, Expr, Value
from planner.model.flat import (
    BOOL,
    Model,
    SourceLocation,
    Specification,
    Transition,
    TransitionKind,
    Variable,
    VariableKind,
)
from planner.reading.display import fill_checked, read_value_words, read_words
from planner.reading.yaml_reader import Diagnostic, ModelError, Reader, closest, each, scope_for

FLAT_KEYS = ("variables", "transitions", "specifications")
_VARIABLE_KEYS = ("name", "domain", "initial", "kind", "description", "display", "display_values")
_TRANSITION_KEYS = ("name", "kind", "guard", "actions", "description", "display", "safety")
MAX_SAFETY_CHARS = 200  # a note read before Done on a watch: two or three short lines
_SPECIFICATION_KEYS = ("name", "invariant", "description", "display")


def read_variable(reader: Reader, node: yaml.Node, prefix: str = "") -> Variable | None:
    fields = reader.mapping(node, "a variable", _VARIABLE_KEYS, required=("name", "domain"))
    if fields is None or "name" not in fields or "domain" not in fields:
        return None
    name = reader.name(fields["name"][1], "variable name")
    domain = read_domain(reader, fields["domain"][1])
    # A variable with a bad kind or initial value is still returned (its error recorded), so
    # that expressions using it do not add "unknown variable" errors of their own.
    kind = VariableKind.ESTIMATED
    if "kind" in fields:
        kind_text = reader.scalar(fields["kind"][1], "variable kind")
        options = [k.value for k in VariableKind]
        if kind_text is not None and kind_text not in options:
            hint = closest(kind_text, options)
            extra = f" (did you mean '{hint}'?)" if hint else ""
            reader.error(
                fields["kind"][1],
                f"unknown variable kind '{kind_text}'{extra}; use one of {', '.join(options)}",
            )
        elif kind_text is not None:
            kind = VariableKind(kind_text)
    if name is None or domain is None:
        return None
    initial: Value = domain[0]
    if "initial" in fields:
        initial_node = fields["initial"][1]
        text = reader.scalar(initial_node, "initial value")
        value = _domain_value(text, initial_node, domain == BOOL) if text is not None else None
        if text is not None and value not in domain:
            reader.error(
                initial_node,
                f"initial value '{text}' of '{prefix}{name}' is outside its domain "
                f"{_show_domain(domain)}",
            )
        elif value is not None:
            initial = value
    what = f"variable '{prefix}{name}'"
    return Variable(
        prefix + name,
        domain,
        initial,
        kind,
        reader.at(node),
        read_description(reader, fields),
        read_display(reader, fields, what),
        read_value_words(reader, fields["display_values"][1], what, domain)
        if "display_values" in fields
        else (),
    )


def read_description(reader: Reader, fields: Mapping[str, tuple[yaml.Node, yaml.Node]]) -> str:
    if "description" not in fields:
        return ""
    return reader.scalar(fields["description"][1], "description") or ""


def read_display(
    reader: Reader,
    fields: Mapping[str, tuple[yaml.Node, yaml.Node]],
    what: str,
    parameters: Collection[str] = (),
) -> str:
    """The `display` of `what` as written (placeholders unfilled); "" if none or bad."""
    if "display" not in fields:
        return ""
    return read_words(reader, fields["display"][1], f"the display of {what}", parameters) or ""


def _domain_value(text: str, node: yaml.Node, is_bool: bool) -> Value:
    if is_bool and isinstance(node, yaml.ScalarNode) and text.lower() in ("true", "false"):
        return text.lower() == "true"
    return text


def _show_domain(domain: tuple[Value, ...]) -> str:
    if domain == BOOL:
        return "bool"
    return "[" + ", ".join(str(v) for v in domain) + "]"


def read_domain(reader: Reader, node: yaml.Node) -> tuple[Value, ...] | None:
    if isinstance(node, yaml.ScalarNode):
        if node.value == "bool":
            return BOOL
        reader.error(node, f"domain must be 'bool' or a list of values, not '{node.value}'")
        return None
    values = reader.sequence(node, "domain")
    if not values:
        if isinstance(node, yaml.SequenceNode):
            reader.error(node, "domain must have at least one value")
        return None
    result: list[str] = []
    for value_node in values:
        text = reader.scalar(value_node, "domain value")
        if text is None:
            return None
        if value_node.tag.endswith(":bool") or text in ("true", "false"):
            reader.error(
                value_node,
                "use 'domain: bool' for booleans; true/false cannot be enumeration values",
            )
            return None
        if not (is_name(text) and "." not in text) and not text.lstrip("-").isdigit():
            reader.error(value_node, f"domain value '{text}' must be a plain name or an integer")
            return None
        if text in result:
            reader.error(value_node, f"duplicate domain value '{text}'")
            return None
        result.append(text)
    return tuple(result)


def read_transition(
    reader: Reader,
    node: yaml.Node,
    scope: Scope,
    kinds: Mapping[str, Variable],
    values: Mapping[str, str] | None = None,
    label: str = "",
    words: Mapping[str, str] | None = None,
) -> Transition | None:
    """A transition as written; `values` fill `{param}` placeholders (ability instances),
    and `words` (the values' words for people) fill those of its `display`.

    `label` prefixes the name in messages (`r1.goto.` for an ability's transitions).
    """
    fields = reader.mapping(node, "a transition", _TRANSITION_KEYS, required=("name",))
    if fields is None or "name" not in fields:
        return None
    name = reader.name(fields["name"][1], "transition name")
    about = read_description(reader, fields)
    display = read_display(reader, fields, f"transition '{label}{name}'", (values or {}).keys())
    if display and words:
        what = f"the display of transition '{label}{name}'"
        display = fill_checked(reader, fields["display"][1], what, display, words)
    kind = TransitionKind.CONTROLLED
    if "kind" in fields:
        text = reader.scalar(fields["kind"][1], "transition kind")
        options = [k.value for k in TransitionKind]
        if text is not None and text not in options:
            hint = closest(text, options)
            extra = f" (did you mean '{hint}'?)" if hint else ""
            reader.error(
                fields["kind"][1],
                f"unknown transition kind '{text}'{extra}; use one of {', '.join(options)}",
            )
            return None
        if text is not None:
            kind = TransitionKind(text)
    where = f"transition '{label}{name}'"
    guard: Expr | None = None
    if "guard" in fields:
        guard = reader.expression(fields["guard"][1], scope, f"the guard of {where}", values)
        if guard is None:
            return None
    actions = read_actions(reader, fields.get("actions"), scope, where, kind, kinds, values)
    if name is None or actions is None:
        return None
    if guard is None:
        guard = TRUE
    safety = read_safety(reader, fields, where, kind)
    return Transition(name, kind, guard, actions, reader.at(node), about, display, safety)


def read_safety(
    reader: Reader,
    fields: Mapping[str, tuple[yaml.Node, yaml.Node]],
    where: str,
    kind: TransitionKind,
) -> str:
    """A maintenance transition's `safety` note (plain words, one line); "" if none or bad
    (an error recorded at the key or the value)."""
    if "safety" not in fields:
        return ""
    key, node = fields["safety"]
    if kind is not TransitionKind.MAINTENANCE:
        reader.error(key, f"safety of {where}: only a maintenance transition has a safety note")
        return ""
    what = f"the safety note of {where}"
    return read_words(reader, node, what, limit=MAX_SAFETY_CHARS) or ""


def read_actions(
    reader: Reader,
    entry: tuple[yaml.Node, yaml.Node] | None,
    scope: Scope,
    where: str,
    kind: TransitionKind,
    variables: Mapping[str, Variable],
    values: Mapping[str, str] | None = None,
) -> tuple[Assign, ...] | None:
    if entry is None:
        return ()
    nodes = reader.sequence(entry[1], f"the actions of {where}")
    actions: list[Assign] = []
    ok = True
    for action_node in nodes:
        action = reader.action(action_node, scope, f"an action of {where}", values)
        if action is None:
            ok = False
            continue
        if any(a.target == action.target for a in actions):
            reader.error(action_node, f"'{action.target}' is assigned twice in {where}")
            ok = False
            continue
        target = variables[action.target]
        if target.kind is VariableKind.MEASURED and kind in (
            TransitionKind.CONTROLLED,
            TransitionKind.AUTOMATIC,
        ):
            reader.error(
                action_node,
                f"{kind.value} {where} assigns measured variable '{action.target}'; measured "
                "variables change only through effect or maintenance transitions",
            )
            ok = False
            continue
        actions.append(action)
    return tuple(actions) if ok else None


def read_specification(reader: Reader, node: yaml.Node, scope: Scope) -> Specification | None:
    fields = reader.mapping(
        node, "a specification", _SPECIFICATION_KEYS, required=("name", "invariant")
    )
    if fields is None or "name" not in fields or "invariant" not in fields:
        return None
    name = reader.name(fields["name"][1], "specification name")
    invariant = reader.expression(
        fields["invariant"][1], scope, f"the invariant of specification '{name}'"
    )
    if name is None or invariant is None:
        return None
    what = f"specification '{name}'"
    return Specification(
        name,
        invariant,
        reader.at(node),
        read_description(reader, fields),
        read_display(reader, fields, what),
    )


def read_flat(reader: Reader, top: dict[str, tuple[yaml.Node, yaml.Node]]) -> Model:
    """Read the three section 8 lists into a checked `Model`."""
    variable_nodes = reader.sequence(top["variables"][1], "variables") if "variables" in top else []
    variables = list(each(reader, variable_nodes, lambda n: read_variable(reader, n)))
    at = name_nodes(variable_nodes)
    reader.unique([(v.name, at(v.source)) for v in variables], "variable")
    by_name = {v.name: v for v in variables}
    scope = scope_for({v.name: v.domain for v in variables}, sizes=reader.sizes)

    transition_nodes = (
        reader.sequence(top["transitions"][1], "transitions") if "transitions" in top else []
    )
    transitions = list(
        each(reader, transition_nodes, lambda n: read_transition(reader, n, scope, by_name))
    )
    at = name_nodes(transition_nodes)
    reader.unique([(t.name, at(t.source)) for t in transitions], "transition")

    spec_nodes = (
        reader.sequence(top["specifications"][1], "specifications")
        if "specifications" in top
        else []
    )
    specifications = list(each(reader, spec_nodes, lambda n: read_specification(reader, n, scope)))
    at = name_nodes(spec_nodes)
    reader.unique([(s.name, at(s.source)) for s in specifications], "specification")
    reader.raise_if_errors()
    return Model(tuple(variables), tuple(transitions), tuple(specifications), reader.file)


def name_nodes(nodes: list[yaml.Node]) -> Callable[[SourceLocation | None], yaml.Node]:
    """The node a located item was read from (for duplicate-name messages): its `name`
    value, else the item's node, else the first node.  Indexed once by location, so that a
    model of 10,000 items is not scanned 10,000 times."""
    index: dict[tuple[int, int], yaml.Node] = {}
    for node in nodes:
        fields = node.value if isinstance(node, yaml.MappingNode) else []
        named = next((value for key, value in fields if key.value == "name"), node)
        index.setdefault((node.start_mark.line + 1, node.start_mark.column + 1), named)

    def at(location: SourceLocation | None) -> yaml.Node:
        if location is not None and (location.line, location.column) in index:
            return index[(location.line, location.column)]
        return nodes[0]

    return at


def read_top(
    text: str, file: str, station_keys: tuple[str, ...]
) -> tuple[Reader, dict[str, tuple[yaml.Node, yaml.Node]]]:
    """The composed top-level mapping of a model file, its keys checked."""
    reader = Reader(text, file)
    root = reader.compose()
    if root is None:
        raise ModelError([Diagnostic(SourceLocation(file, 1, 1), "the model file is empty")])
    top = reader.mapping(root, "the model", FLAT_KEYS + station_keys)
    reader.raise_if_errors()
    assert top is not None
    return reader, top
