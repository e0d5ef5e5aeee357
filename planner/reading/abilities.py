"""A resource's abilities read from YAML (seed 003 sec. II-C): one ability per parameter
value, each with its named predicates and its transitions, named after the resource.

An ability with a parameter is a template: its predicates and transitions are read once per
value with `{parameter}` filled in, and messages name the template, so that one mistake is
reported once, not per value.  A transition that comes out the same for every value (an
effect that does not depend on it) is made once, named after the template; `instances`
adds an extra guard and actions to one value's `start` (seed 003 Table V).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import yaml

from planner.model.expression_text import Scope
from planner.model.expressions import TRUE, Expr, Value, conjunction
from planner.model.flat import Transition, Variable
from planner.model.station import Ability
from planner.reading.display import fill_checked, parameter_words
from planner.reading.flat import read_actions, read_description, read_display, read_transition
from planner.reading.parameters import Parameter, filled, read_parameter
from planner.reading.yaml_reader import Reader, key_node, scope_for

_ABILITY_KEYS = (
    "name",
    "description",
    "display",
    "parameter",
    "predicates",
    "transitions",
    "instances",
    "restart",
)
_INSTANCE_KEYS = ("guard", "actions")

Located = list[tuple[Transition, yaml.Node]]  # transitions, each with the node it was read from
Instance = tuple[str, str | None, dict[str, str]]  # its name, parameter value, placeholders


@dataclass(frozen=True)
class _Template:
    """What an ability's entry says once for all of its instances."""

    node: yaml.Node
    resource: str
    name: str
    parameter: Parameter | None
    instances: list[Instance]
    description: str
    display: str
    restart: bool
    predicates: list[tuple[str, yaml.Node]]
    transitions: list[yaml.Node]
    extras: dict[str, yaml.Node]  # parameter value -> extra guard and actions of its start

    @property
    def where(self) -> str:
        return f"ability '{self.resource}.{self.name}'"

    @property
    def words(self) -> dict[str, str]:
        return self.parameter.words if self.parameter else {}


def read_ability(
    reader: Reader,
    node: yaml.Node,
    resource: str,
    domains: dict[str, tuple[Value, ...]],
    aliases: dict[str, str],
    variables: dict[str, Variable],
) -> list[tuple[Ability, Located]]:
    """One ability per parameter value, each with its predicates and named transitions."""
    template = _read_template(reader, node, resource)
    if template is None:
        return []
    read = [
        _read_instance(reader, template, value, values, domains, aliases, variables)
        for _, value, values in template.instances
    ]
    generic = _generic(reader, template, [transitions for _, transitions in read])
    return [
        _named(reader, template, instance, predicates, transitions, generic)
        for instance, (predicates, transitions) in zip(template.instances, read, strict=True)
    ]


def _read_template(reader: Reader, node: yaml.Node, resource: str) -> _Template | None:
    fields = reader.mapping(node, "an ability", _ABILITY_KEYS, required=("name",))
    if fields is None or "name" not in fields:
        return None
    name = reader.name(fields["name"][1], "ability name")
    if name is None:
        return None
    parameter = read_parameter(reader, fields, f"ability '{name}'")
    instances: list[Instance] = (
        [(f"{name}_{v}", v, {parameter.name: v}) for v in parameter.values]
        if parameter
        else [(name, None, {})]
    )
    description = read_description(reader, fields)
    where = f"ability '{resource}.{name}'"
    display = read_display(reader, fields, where, [parameter.name] if parameter else [])
    restart = False
    if "restart" in fields:
        restart = (reader.scalar(fields["restart"][1], "restart") or "").lower() == "true"
    predicates = _pairs(reader, fields.get("predicates"), f"ability '{name}'")
    transitions = (
        reader.sequence(fields["transitions"][1], "transitions") if "transitions" in fields else []
    )
    extras = dict(_pairs(reader, fields.get("instances"), f"ability '{name}'"))
    for value, extra in extras.items():
        if all(value != v for _, v, _ in instances):
            reader.error(extra, f"'{value}' is not a value of the parameter of '{name}'")
    return _Template(
        node,
        resource,
        name,
        parameter,
        instances,
        description,
        display,
        restart,
        predicates,
        transitions,
        extras,
    )


def _read_instance(
    reader: Reader,
    template: _Template,
    value: str | None,
    values: dict[str, str],
    domains: dict[str, tuple[Value, ...]],
    aliases: dict[str, str],
    variables: dict[str, Variable],
) -> tuple[dict[str, Expr], Located]:
    """One value's predicates (each may name the ones before it) and transitions, with the
    names the template gives them."""
    where = template.where
    local: dict[str, Expr] = {}
    for key, value_node in template.predicates:
        scope = scope_for(domains, local, aliases, reader.sizes)
        expr = reader.expression(value_node, scope, f"predicate '{key}' of {where}", values)
        local[key] = expr if expr is not None else TRUE  # reported; avoid follow-on errors
    scope = scope_for(domains, local, aliases, reader.sizes)
    transitions: Located = []
    for node in template.transitions:
        t = read_transition(
            reader,
            node,
            scope,
            variables,
            values,
            f"{template.resource}.{template.name}.",
            parameter_words(template.words, values),
        )
        if t is None:
            continue
        if t.name == "start" and value in template.extras:
            t = _with_extras(reader, t, template.extras[value], scope, variables, values, where)
        transitions.append((t, node))
    return local, transitions


def _generic(reader: Reader, template: _Template, per_instance: list[Located]) -> set[str]:
    """The transitions that come out the same for every value: each is made once."""
    generic: set[str] = set()
    if (
        len(template.instances) < 2
        or not per_instance
        or any(len(ts) != len(per_instance[0]) for ts in per_instance)
    ):
        return generic
    parameter = template.parameter
    for i, (first, first_node) in enumerate(per_instance[0]):
        same = {(ts[i][0].kind, ts[i][0].guard, ts[i][0].actions) for ts in per_instance}
        if first.name != "start" and len(same) == 1:
            generic.add(first.name)
            if parameter and len({ts[i][0].display for ts in per_instance}) > 1:
                reader.error(
                    key_node(first_node, "display") or first_node,
                    f"transition '{template.resource}.{template.name}.{first.name}' is the "
                    f"same for every value of '{parameter.name}', so it is made once: its "
                    f"display cannot name '{{{parameter.name}}}'",
                )
    return generic


def _named(
    reader: Reader,
    template: _Template,
    instance: Instance,
    predicates: dict[str, Expr],
    transitions: Located,
    generic: set[str],
) -> tuple[Ability, Located]:
    """One instance as an ability, its transitions named: `start` after the instance, a
    generic one after the template, the others after the instance."""
    name, value, values = instance
    resource = template.resource
    result: Located = []
    for t, node in transitions:
        if t.name == "start":
            full = f"{resource}.{name}"
        elif t.name in generic:
            full = f"{resource}.{template.name}.{t.name}"
        else:
            full = f"{resource}.{name}.{t.name}"
        result.append((replace(t, name=full), node))
    ability = Ability(
        resource,
        name,
        template.name,
        value,
        predicates,
        tuple(t.name for t, _ in result),
        template.restart,
        filled(template.description, values),
        fill_checked(
            reader,
            key_node(template.node, "display"),
            f"the display of {template.where}",
            template.display,
            parameter_words(template.words, values),
        ),
    )
    return ability, result


def _pairs(
    reader: Reader, entry: tuple[yaml.Node, yaml.Node] | None, what: str
) -> list[tuple[str, yaml.Node]]:
    """The keys and value nodes of a mapping whose keys are free names."""
    if entry is None:
        return []
    node = entry[1]
    if not isinstance(node, yaml.MappingNode):
        reader.error(node, f"the {entry[0].value} of {what} must be a mapping")
        return []
    pairs: list[tuple[str, yaml.Node]] = []
    for key_part, value_node in node.value:
        key = reader.name(key_part, "name")
        if key is not None:
            if any(key == k for k, _ in pairs):
                reader.error(key_part, f"duplicate key '{key}' in the {entry[0].value} of {what}")
            pairs.append((key, value_node))
    return pairs


def _with_extras(
    reader: Reader,
    start: Transition,
    node: yaml.Node,
    scope: Scope,
    variables: dict[str, Variable],
    values: dict[str, str],
    where: str,
) -> Transition:
    """The `start` transition with an instance's extra guard and actions (seed 003 Table V)."""
    fields = reader.mapping(node, f"the instance extras of {where}", _INSTANCE_KEYS)
    if fields is None:
        return start
    guard = start.guard
    if "guard" in fields:
        extra = reader.expression(fields["guard"][1], scope, f"the extra guard of {where}", values)
        guard = conjunction([guard, extra]) if extra is not None else guard
    actions = read_actions(
        reader, fields.get("actions"), scope, where, start.kind, variables, values
    )
    return replace(start, guard=guard, actions=start.actions + (actions or ()))
