"""The station form read from YAML: resources, abilities (one per parameter value),
operations and intentions, compiled to the flat model with every problem located.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import yaml

from planner.model.expression_text import Scope, is_name, substitute
from planner.model.expressions import TRUE, Assign, Expr, SameValue, Value, conjunction
from planner.model.flat import Model, Specification, Transition, TransitionKind, Variable
from planner.model.station import (
    Ability,
    Intention,
    Operation,
    Resource,
    ResourceKind,
    Station,
    value_is,
)
from planner.reading.display import fill_checked, parameter_words, read_value_words
from planner.reading.flat import (
    name_nodes,
    read_actions,
    read_display,
    read_specification,
    read_transition,
    read_variable,
)
from planner.reading.watch import read_watch
from planner.reading.yaml_reader import Reader, each, scope_for

STATION_KEYS = ("station", "description", "display", "resources", "operations", "intentions")
_RESOURCE_KEYS = (
    "name",
    "description",
    "display",
    "kind",
    "variables",
    "abilities",
    "transitions",
    "watch",
)
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
_OPERATION_KEYS = (
    "name",
    "description",
    "display",
    "parameter",
    "precondition",
    "effects",
    "goal",
    "actions",
)
_INTENTION_KEYS = ("name", "description", "display", "precondition", "goal", "always", "actions")
_PARAMETER_KEYS = ("name", "values", "display_values")


Fields = dict[str, tuple[yaml.Node, yaml.Node]]


def read_station(reader: Reader, top: Fields) -> Station:
    name = reader.scalar(top["station"][1], "station name") if "station" in top else ""
    display = read_display(reader, top, f"station '{name}'")
    # 1. variables: station-wide ones, then each resource's (named RESOURCE.NAME)
    variable_nodes = reader.sequence(top["variables"][1], "variables") if "variables" in top else []
    variables = list(each(reader, variable_nodes, lambda n: read_variable(reader, n)))
    resource_nodes = reader.sequence(top["resources"][1], "resources") if "resources" in top else []
    resource_fields: list[tuple[str, Fields]] = []
    for node in resource_nodes:
        fields = reader.mapping(node, "a resource", _RESOURCE_KEYS, required=("name",))
        if fields is None or "name" not in fields:
            continue
        resource = reader.name(fields["name"][1], "resource name")
        if resource is None:
            continue
        resource_fields.append((resource, fields))
        nodes = (
            reader.sequence(fields["variables"][1], "variables") if "variables" in fields else []
        )
        variables += [
            v for n in nodes if (v := read_variable(reader, n, resource + ".")) is not None
        ]
    reader.unique([(r, f["name"][1]) for r, f in resource_fields], "resource")
    located = list(variable_nodes)
    for _, fields in resource_fields:
        if "variables" in fields and isinstance(fields["variables"][1], yaml.SequenceNode):
            located += fields["variables"][1].value
    at = name_nodes(located)
    reader.unique([(v.name, at(v.source)) for v in variables], "variable")
    by_name = {v.name: v for v in variables}
    domains = {v.name: v.domain for v in variables}

    # 2. abilities and resource transitions
    predicates: dict[str, Expr] = {}
    transitions: list[tuple[Transition, yaml.Node]] = []
    abilities: list[Ability] = []
    resources: list[Resource] = []
    restart: set[str] = set()
    by_prefix: dict[str, list[str]] = {}  # "r1." -> the variables named r1.something
    for v in variables:
        parts = v.name.split(".")
        for k in range(1, len(parts)):
            by_prefix.setdefault(".".join(parts[:k]) + ".", []).append(v.name)
    names = {t.name for t, _ in transitions}
    for resource, fields in resource_fields:
        prefix = resource + "."
        aliases = {name[len(prefix) :]: name for name in by_prefix.get(prefix, ())}
        own: list[str] = []
        ability_names: list[str] = []
        for node in (
            reader.sequence(fields["abilities"][1], "abilities") if "abilities" in fields else []
        ):
            for ability, compiled in _read_ability(
                reader, node, resource, domains, aliases, by_name
            ):
                abilities.append(ability)
                ability_names.append(ability.qualified)
                for predicate, expr in ability.predicates.items():
                    predicates[f"{ability.qualified}.{predicate}"] = expr
                for t, t_node in compiled:
                    if t.name not in names:
                        names.add(t.name)
                        transitions.append((t, t_node))
                        own.append(t.name)
                if ability.restart:
                    restart.update(ability.transitions)
        scope = scope_for(domains, predicates, aliases)
        nodes = (
            reader.sequence(fields["transitions"][1], "transitions")
            if "transitions" in fields
            else []
        )
        for node in nodes:
            read = read_transition(reader, node, scope, by_name)
            if read is not None:
                prefixed = replace(read, name=prefix + read.name)
                transitions.append((prefixed, node))
                names.add(prefixed.name)
                own.append(prefixed.name)
        description = fields.get("description")
        resources.append(
            Resource(
                resource,
                (reader.scalar(description[1], "description") or "") if description else "",
                tuple(aliases.values()),
                tuple(ability_names),
                tuple(own),
                _resource_kind(reader, fields.get("kind")),
                display=read_display(reader, fields, f"resource '{resource}'"),
            )
        )

    # 3. station-wide transitions and specifications (may name ability predicates)
    scope = scope_for(domains, predicates)
    nodes = reader.sequence(top["transitions"][1], "transitions") if "transitions" in top else []
    for node in nodes:
        station_wide = read_transition(reader, node, scope, by_name)
        if station_wide is not None:
            transitions.append((station_wide, node))
    reader.unique([(t.name, _name_node(n)) for t, n in transitions], "transition")
    spec_nodes = (
        reader.sequence(top["specifications"][1], "specifications")
        if "specifications" in top
        else []
    )
    specifications: list[Specification] = list(
        each(reader, spec_nodes, lambda n: read_specification(reader, n, scope))
    )
    at = name_nodes(spec_nodes)
    reader.unique([(s.name, at(s.source)) for s in specifications], "specification")

    # 4. operations, then intentions (which may name operations' predicates)
    operations: list[Operation] = []
    named: list[tuple[str, yaml.Node]] = []
    for node in reader.sequence(top["operations"][1], "operations") if "operations" in top else []:
        for operation in _read_operation(reader, node, scope, by_name):
            operations.append(operation)
            named.append((operation.name, _name_node(node)))
            predicates[f"{operation.name}.precondition"] = operation.precondition
            predicates[f"{operation.name}.goal"] = conjunction(
                [operation.goal, *(_effect_predicate(a) for a in operation.effects)]
            )
    reader.unique(named, "operation")
    scope = scope_for(domains, predicates)
    intentions: list[Intention] = []
    for node in reader.sequence(top["intentions"][1], "intentions") if "intentions" in top else []:
        intention = _read_intention(reader, node, scope, by_name)
        if intention is not None:
            intentions.append(intention)
            predicates[f"{intention.name}.precondition"] = intention.precondition
            predicates[f"{intention.name}.goal"] = intention.goal
            if intention.always is not None:
                predicates[f"{intention.name}.always"] = intention.always
    resources = _with_watches(reader, resources, resource_fields, by_name, transitions)
    reader.raise_if_errors()
    model = Model(
        tuple(variables), tuple(t for t, _ in transitions), tuple(specifications), reader.file
    )
    return Station(
        model,
        name or "",
        tuple(resources),
        tuple(abilities),
        tuple(operations),
        tuple(intentions),
        predicates,
        frozenset(restart),
        _description(reader, top),
        display,
    )


def _with_watches(
    reader: Reader,
    resources: list[Resource],
    fields: list[tuple[str, Fields]],
    variables: Mapping[str, Variable],
    transitions: list[tuple[Transition, yaml.Node]],
) -> list[Resource]:
    """Resources with their `watch:` read; a watch belongs to a person."""
    declared = {name: f["watch"] for name, f in fields if "watch" in f}
    result = []
    for resource in resources:
        if resource.name not in declared:
            result.append(resource)
            continue
        key, node = declared[resource.name]
        if not resource.person:
            reader.error(key, f"only a person carries a watch; give '{resource.name}' kind: person")
        own = {t.name: t for t, _ in transitions if t.name in resource.transitions}
        watch = read_watch(reader, node, resource.name, variables, own)
        result.append(replace(resource, watch=watch))
    return result


def _effect_predicate(action: Assign) -> Expr:
    if action.source is not None:
        return SameValue(action.target, action.source)
    assert action.value is not None
    return value_is(action.target, action.value)


def _key_node(node: yaml.Node, key: str) -> yaml.Node | None:
    """The value node of `key` in a mapping node, if it has one."""
    if isinstance(node, yaml.MappingNode):
        for key_node, value in node.value:
            if key_node.value == key:
                return value  # type: ignore[no-any-return]
    return None


def _name_node(node: yaml.Node) -> yaml.Node:
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            if key.value == "name":
                return value  # type: ignore[no-any-return]
    return node


@dataclass(frozen=True)
class _Parameter:
    """`parameter: {name, values, display_values}` of an ability or operation."""

    name: str
    values: list[str]
    words: dict[str, str]  # value → words for people (display_values), where given


def _parameter(reader: Reader, fields: Fields, what: str) -> _Parameter | None:
    """The parameter of `what`; None when absent or broken (errors recorded)."""
    if "parameter" not in fields:
        return None
    node = fields["parameter"][1]
    parameter = reader.mapping(
        node, f"the parameter of {what}", _PARAMETER_KEYS, ("name", "values")
    )
    if parameter is None or "name" not in parameter or "values" not in parameter:
        return None
    name = reader.name(parameter["name"][1], "parameter name")
    values = [
        reader.scalar(v, "parameter value")
        for v in reader.sequence(parameter["values"][1], "values")
    ]
    if name is None or not values or any(v is None for v in values):
        if not values:
            reader.error(parameter["values"][1], "a parameter needs at least one value")
        return None
    given = [v for v in values if v is not None]
    words: dict[str, str] = {}
    if "display_values" in parameter:
        about = f"the parameter '{name}' of {what}"
        pairs = read_value_words(reader, parameter["display_values"][1], about, tuple(given))
        words = {str(value): text for value, text in pairs}
    return _Parameter(name, given, words)


def _read_ability(
    reader: Reader,
    node: yaml.Node,
    resource: str,
    domains: dict[str, tuple[Value, ...]],
    aliases: dict[str, str],
    variables: dict[str, Variable],
) -> list[tuple[Ability, list[tuple[Transition, yaml.Node]]]]:
    """One ability per parameter value, each with its predicates and named transitions."""
    fields = reader.mapping(node, "an ability", _ABILITY_KEYS, required=("name",))
    if fields is None or "name" not in fields:
        return []
    template = reader.name(fields["name"][1], "ability name")
    if template is None:
        return []
    parameter = _parameter(reader, fields, f"ability '{template}'")
    instances: list[tuple[str, str | None, dict[str, str]]] = (
        [(f"{template}_{v}", v, {parameter.name: v}) for v in parameter.values]
        if parameter
        else [(template, None, {})]
    )
    description = _description(reader, fields)
    where = f"ability '{resource}.{template}'"
    display = read_display(reader, fields, where, [parameter.name] if parameter else [])
    words = parameter.words if parameter else {}
    restart = False
    if "restart" in fields:
        restart = (reader.scalar(fields["restart"][1], "restart") or "").lower() == "true"
    predicate_nodes = _pairs(reader, fields.get("predicates"), f"ability '{template}'")
    transition_nodes = (
        reader.sequence(fields["transitions"][1], "transitions") if "transitions" in fields else []
    )
    extra_nodes = dict(_pairs(reader, fields.get("instances"), f"ability '{template}'"))
    for extra_value, extra_node in extra_nodes.items():
        if all(extra_value != v for _, v, _ in instances):
            reader.error(
                extra_node, f"'{extra_value}' is not a value of the parameter of '{template}'"
            )

    per_instance: list[list[tuple[Transition, yaml.Node]]] = []
    instance_predicates: list[dict[str, Expr]] = []
    for _instance, value, values in instances:
        # messages name the template, so that one mistake is reported once, not per value
        local: dict[str, Expr] = {}
        for key, value_node in predicate_nodes:
            scope = scope_for(domains, local, aliases)
            expr = reader.expression(value_node, scope, f"predicate '{key}' of {where}", values)
            local[key] = expr if expr is not None else TRUE  # reported; avoid follow-on errors
        scope = scope_for(domains, local, aliases)
        transitions: list[tuple[Transition, yaml.Node]] = []
        for t_node in transition_nodes:
            t = read_transition(
                reader,
                t_node,
                scope,
                variables,
                values,
                f"{resource}.{template}.",
                parameter_words(words, values),
            )
            if t is None:
                continue
            if t.name == "start" and value in extra_nodes:
                t = _with_extras(reader, t, extra_nodes[value], scope, variables, values, where)
            transitions.append((t, t_node))
        instance_predicates.append(local)
        per_instance.append(transitions)

    # a transition that comes out the same for every value is emitted once (a generic effect)
    generic: set[str] = set()
    if (
        len(instances) > 1
        and per_instance
        and all(len(ts) == len(per_instance[0]) for ts in per_instance)
    ):
        for i, (first, first_node) in enumerate(per_instance[0]):
            same = {(ts[i][0].kind, ts[i][0].guard, ts[i][0].actions) for ts in per_instance}
            if first.name != "start" and len(same) == 1:
                generic.add(first.name)
                if parameter and len({ts[i][0].display for ts in per_instance}) > 1:
                    reader.error(
                        _key_node(first_node, "display") or first_node,
                        f"transition '{resource}.{template}.{first.name}' is the same for every "
                        f"value of '{parameter.name}', so it is made once: its display cannot "
                        f"name '{{{parameter.name}}}'",
                    )

    compiled: list[tuple[Ability, list[tuple[Transition, yaml.Node]]]] = []
    for k, (instance, value, values) in enumerate(instances):
        result: list[tuple[Transition, yaml.Node]] = []
        for t, t_node in per_instance[k]:
            if t.name == "start":
                full = f"{resource}.{instance}"
            elif t.name in generic:
                full = f"{resource}.{template}.{t.name}"
            else:
                full = f"{resource}.{instance}.{t.name}"
            result.append((replace(t, name=full), t_node))
        ability = Ability(
            resource,
            instance,
            template,
            value,
            instance_predicates[k],
            tuple(t.name for t, _ in result),
            restart,
            _filled(description, values),
            fill_checked(
                reader,
                _key_node(node, "display"),
                f"the display of {where}",
                display,
                parameter_words(words, values),
            ),
        )
        compiled.append((ability, result))
    return compiled


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
    for key_node, value_node in node.value:
        key = reader.name(key_node, "name")
        if key is not None:
            if any(key == k for k, _ in pairs):
                reader.error(key_node, f"duplicate key '{key}' in the {entry[0].value} of {what}")
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


def _names_and_values(
    reader: Reader, fields: Fields, what: str
) -> tuple[list[tuple[str, dict[str, str]]], _Parameter | None] | None:
    """Instance names and placeholder values for a possibly parameterised operation."""
    text = reader.scalar(fields["name"][1], f"{what} name")
    if text is None:
        return None
    parameter = _parameter(reader, fields, f"{what} '{text}'")
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
    description = _description(reader, fields)
    template = reader.scalar(fields["name"][1], "operation name")
    what = f"operation '{template}'"
    display = read_display(reader, fields, what, [parameter.name] if parameter else [])
    words = parameter.words if parameter else {}
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
        filled = fill_checked(
            reader,
            _key_node(node, "display"),
            f"the display of {what}",
            display,
            parameter_words(words, values),
        )
        result.append(
            Operation(name, pre, effects, goal, actions, _filled(description, values), filled)
        )
    return result


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
    return Intention(name, pre, goal, always, actions, _description(reader, fields), display)


def _optional_expr(
    reader: Reader, fields: Fields, key: str, scope: Scope, where: str, values: dict[str, str]
) -> Expr | None:
    if key not in fields:
        return TRUE
    return reader.expression(fields[key][1], scope, f"the {key} of {where}", values)


def _filled(description: str, values: Mapping[str, str]) -> str:
    """A template's description for one parameter value: `{bp}` becomes `bp3`."""
    for key, value in values.items():
        description = description.replace("{" + key + "}", value)
    return description


def _description(reader: Reader, fields: Fields) -> str:
    if "description" not in fields:
        return ""
    return reader.scalar(fields["description"][1], "description") or ""


def _resource_kind(reader: Reader, field: tuple[yaml.Node, yaml.Node] | None) -> ResourceKind:
    if field is None:
        return ResourceKind.DEVICE
    text = reader.scalar(field[1], "kind")
    kinds = [k.value for k in ResourceKind]
    if text not in kinds:
        if text is not None:
            reader.error(field[1], f"a resource's kind is one of {', '.join(kinds)}, not '{text}'")
        return ResourceKind.DEVICE
    return ResourceKind(text)
