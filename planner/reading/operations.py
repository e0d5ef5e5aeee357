"""A station's operations and intentions read from YAML (seed 000 Definitions 5 and 6).

Both come after everything they may name: the variables, the abilities' predicates, and, for
intentions, the operations' own (`OPERATION.precondition`, `OPERATION.goal`, the goal with
the effects).  An operation with a parameter is made once per value, its name from the
`{parameter}` in it or with `_VALUE` appended.
"""

from __future__ import annotations

import yaml

from planner.model.expression_syntax import is_name, substitute
from planner.model.expression_text import Scope
from planner.model.expressions import TRUE, Assign, Expr, SameValue, conjunction
from planner.model.flat import TransitionKind, Variable
from planner.model.station import Intention, Operation, value_is
from planner.reading.display import fill_checked, parameter_words
from planner.reading.flat import read_actions, read_description, read_display
from planner.reading.parameters import Parameter, filled, read_parameter
from planner.reading.yaml_reader import Fields, Reader, key_node, name_node

_OPERATION_KEYS = (
    "name",
    "description",
    "display",
    "parameter",
    "precondition",
    "effects",
    "goal",
    "actions",
    "duration",
)
_INTENTION_KEYS = (
    "name",
    "description",
    "display",
    "precondition",
    "goal",
    "always",
    "actions",
    "product",
)


def read_operations(
    reader: Reader,
    nodes: list[yaml.Node],
    scope: Scope,
    variables: dict[str, Variable],
    predicates: dict[str, Expr],
) -> list[Operation]:
    """The operations, each one's precondition and goal (with its effects) added to
    `predicates` as it is read."""
    operations: list[Operation] = []
    named: list[tuple[str, yaml.Node]] = []
    for node in nodes:
        for operation in _read_operation(reader, node, scope, variables):
            operations.append(operation)
            named.append((operation.name, name_node(node)))
            predicates[f"{operation.name}.precondition"] = operation.precondition
            predicates[f"{operation.name}.goal"] = conjunction(
                [operation.goal, *(_effect_predicate(a) for a in operation.effects)]
            )
    reader.unique(named, "operation")
    return operations


def read_intentions(
    reader: Reader,
    nodes: list[yaml.Node],
    scope: Scope,
    variables: dict[str, Variable],
    predicates: dict[str, Expr],
) -> list[Intention]:
    """The intentions, each one's precondition, goal and `always` added to `predicates`."""
    intentions: list[Intention] = []
    for node in nodes:
        intention = _read_intention(reader, node, scope, variables)
        if intention is not None:
            intentions.append(intention)
            predicates[f"{intention.name}.precondition"] = intention.precondition
            predicates[f"{intention.name}.goal"] = intention.goal
            if intention.always is not None:
                predicates[f"{intention.name}.always"] = intention.always
    return intentions


def _effect_predicate(action: Assign) -> Expr:
    if action.source is not None:
        return SameValue(action.target, action.source)
    assert action.value is not None
    return value_is(action.target, action.value)


def _names_and_values(
    reader: Reader, fields: Fields, what: str
) -> tuple[list[tuple[str, dict[str, str]]], Parameter | None] | None:
    """Instance names and placeholder values for a possibly parameterised operation."""
    text = reader.scalar(fields["name"][1], f"{what} name")
    if text is None:
        return None
    parameter = read_parameter(reader, fields, f"{what} '{text}'")
    if parameter is None:
        return ([(text, {})], None) if reader.name(fields["name"][1], f"{what} name") else None
    key = parameter.name
    result = []
    for value in parameter.values:
        name = substitute(text, {key: value})[0] if "{" + key + "}" in text else f"{text}_{value}"
        if not is_name(name):
            reader.error(fields["name"][1], f"{what} name '{name}' is not a name")
            return None
        result.append((name, {key: value}))
    return result, parameter


def _read_operation(
    reader: Reader, node: yaml.Node, scope: Scope, variables: dict[str, Variable]
) -> list[Operation]:
    fields = reader.mapping(node, "an operation", _OPERATION_KEYS, required=("name",))
    if fields is None or "name" not in fields:
        return []
    named = _names_and_values(reader, fields, "operation")
    if named is None:
        return []
    instances, parameter = named
    description = read_description(reader, fields)
    template = reader.scalar(fields["name"][1], "operation name")
    what = f"operation '{template}'"
    display = read_display(reader, fields, what, [parameter.name] if parameter else [])
    words = parameter.words if parameter else {}
    duration = _duration(reader, fields, what)
    result = []
    for name, values in instances:
        where = f"operation '{name}'"
        pre = _optional_expr(reader, fields, "precondition", scope, where, values)
        goal = _optional_expr(reader, fields, "goal", scope, where, values)
        effects = read_actions(
            reader, fields.get("effects"), scope, where, TransitionKind.EFFECT, variables, values
        )
        actions = read_actions(
            reader, fields.get("actions"), scope, where, TransitionKind.EFFECT, variables, values
        )
        if pre is None or goal is None or effects is None or actions is None:
            continue
        shown = fill_checked(
            reader,
            key_node(node, "display"),
            f"the display of {what}",
            display,
            parameter_words(words, values),
        )
        described = filled(description, values)
        result.append(Operation(name, pre, effects, goal, actions, described, shown, duration))
    return result


def _duration(reader: Reader, fields: Fields, what: str) -> float | None:
    """`duration`: the model's estimate in seconds, a number above 0."""
    if "duration" not in fields:
        return None
    node = fields["duration"][1]
    text = reader.scalar(node, f"the duration of {what}")
    try:
        seconds = float(text) if text is not None else None
    except ValueError:
        seconds = None
    if seconds is None or not 0 < seconds < float("inf"):
        reader.error(node, f"the duration of {what} is seconds, a number above 0, not {text!r}")
        return None
    return seconds


def _read_intention(
    reader: Reader, node: yaml.Node, scope: Scope, variables: dict[str, Variable]
) -> Intention | None:
    fields = reader.mapping(node, "an intention", _INTENTION_KEYS, required=("name", "goal"))
    if fields is None or "name" not in fields or "goal" not in fields:
        return None
    name = reader.name(fields["name"][1], "intention name")
    where = f"intention '{name}'"
    pre = _optional_expr(reader, fields, "precondition", scope, where, {})
    goal = _optional_expr(reader, fields, "goal", scope, where, {})
    always = (
        _optional_expr(reader, fields, "always", scope, where, {}) if "always" in fields else None
    )
    actions = read_actions(
        reader, fields.get("actions"), scope, where, TransitionKind.EFFECT, variables
    )
    if name is None or pre is None or goal is None or actions is None:
        return None
    if "always" in fields and always is None:
        return None
    display = read_display(reader, fields, where)
    product = _read_product(reader, fields, where)
    about = read_description(reader, fields)
    return Intention(name, pre, goal, always, actions, about, display, product)


def _read_product(reader: Reader, fields: Fields, where: str) -> bool:
    """`product: true` marks the intention whose finished runs are the station's products;
    anything but true or false is an error at the value."""
    if "product" not in fields:
        return False
    node = fields["product"][1]
    if not (isinstance(node, yaml.ScalarNode) and node.tag.endswith(":bool")):
        shown = node.value if isinstance(node, yaml.ScalarNode) else "a list or mapping"
        reader.error(node, f"the product of {where} is true or false, not {shown!r}")
        return False
    return str(node.value).lower() in ("true", "yes", "on")


def _optional_expr(
    reader: Reader, fields: Fields, key: str, scope: Scope, where: str, values: dict[str, str]
) -> Expr | None:
    if key not in fields:
        return TRUE
    return reader.expression(fields[key][1], scope, f"the {key} of {where}", values)
