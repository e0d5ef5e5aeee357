"""The station form read from YAML: resources, abilities (one per parameter value),
operations and intentions, compiled to the flat model with every problem located.

The parts are read in the order their names become known: the variables (station-wide, then
each resource's, named `RESOURCE.NAME`), each resource's abilities (`planner.reading.abilities`)
and own transitions, the station-wide transitions and specifications, which may name the
abilities' predicates, then the operations and the intentions, which may also name the
operations' (`planner.reading.operations`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import yaml

from planner.model.expression_text import Scope
from planner.model.expressions import Expr, Value
from planner.model.flat import Model, Specification, Transition, Variable
from planner.model.station import Ability, Resource, ResourceKind, Station, StepRequirement
from planner.reading.abilities import Located, read_ability
from planner.reading.flat import (
    name_nodes,
    read_description,
    read_display,
    read_specification,
    read_transition,
    read_variable,
)
from planner.reading.operations import read_intentions, read_operations
from planner.reading.step_requirements import guarded, read_step_requirement
from planner.reading.watch import read_watch
from planner.reading.yaml_reader import Fields, Reader, each, key_node, name_node, scope_for

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


def read_station(reader: Reader, top: Fields) -> Station:
    """The station a model file's top-level keys describe; raises `ModelError` with every
    problem found."""
    return _StationReader(reader, top).station()


class _StationReader:
    """One station file's parts, read in order into the lists the station is made of."""

    def __init__(self, reader: Reader, top: Fields) -> None:
        self.reader, self.top = reader, top
        self.variables: list[Variable] = []
        self.by_name: dict[str, Variable] = {}
        self.domains: dict[str, tuple[Value, ...]] = {}
        self.resource_fields: list[tuple[str, Fields]] = []
        # named predicates, added as they are read: a scope made from this dict (once it is
        # not empty) sees the ones added after it too
        self.predicates: dict[str, Expr] = {}
        self.transitions: Located = []
        self.names: set[str] = set()  # of the resources' transitions so far
        self.abilities: list[Ability] = []
        self.restart: set[str] = set()

    def station(self) -> Station:
        reader, top = self.reader, self.top
        name = reader.scalar(top["station"][1], "station name") if "station" in top else ""
        display = read_display(reader, top, f"station '{name}'")
        self.read_variables()
        prefixed = _by_prefix(self.variables)
        resources = [self.read_resource(r, f, prefixed) for r, f in self.resource_fields]
        scope = scope_for(self.domains, self.predicates, sizes=reader.sizes)
        self.read_station_transitions(scope)
        specifications, requirements = self.read_specifications(scope)
        operations = read_operations(
            reader, self.sequence(top, "operations"), scope, self.by_name, self.predicates
        )
        scope = scope_for(self.domains, self.predicates, sizes=reader.sizes)
        intentions = read_intentions(
            reader, self.sequence(top, "intentions"), scope, self.by_name, self.predicates
        )
        resources = _with_watches(
            reader, resources, self.resource_fields, self.by_name, self.transitions
        )
        reader.raise_if_errors()
        located = guarded(reader, self.transitions, requirements)
        reader.raise_if_errors()
        transitions = tuple(t for t, _ in located)
        model = Model(tuple(self.variables), transitions, tuple(specifications), reader.file)
        return Station(
            model,
            name or "",
            tuple(resources),
            tuple(self.abilities),
            tuple(operations),
            tuple(intentions),
            self.predicates,
            frozenset(self.restart),
            read_description(reader, top),
            display,
            tuple(r for r, _ in requirements),
        )

    def sequence(self, fields: Fields, key: str) -> list[yaml.Node]:
        """The list under `key`, [] when there is none."""
        return self.reader.sequence(fields[key][1], key) if key in fields else []

    def read_variables(self) -> None:
        """The station-wide variables, then each resource's (its fields kept for later)."""
        reader = self.reader
        variable_nodes = self.sequence(self.top, "variables")
        self.variables = list(each(reader, variable_nodes, lambda n: read_variable(reader, n)))
        located = list(variable_nodes)
        for node in self.sequence(self.top, "resources"):
            fields = reader.mapping(node, "a resource", _RESOURCE_KEYS, required=("name",))
            if fields is None or "name" not in fields:
                continue
            resource = reader.name(fields["name"][1], "resource name")
            if resource is None:
                continue
            self.resource_fields.append((resource, fields))
            nodes = self.sequence(fields, "variables")
            self.variables += [
                v for n in nodes if (v := read_variable(reader, n, resource + ".")) is not None
            ]
        reader.unique([(r, f["name"][1]) for r, f in self.resource_fields], "resource")
        for _, fields in self.resource_fields:
            if "variables" in fields and isinstance(fields["variables"][1], yaml.SequenceNode):
                located += fields["variables"][1].value
        at = name_nodes(located)
        reader.unique([(v.name, at(v.source)) for v in self.variables], "variable")
        self.by_name = {v.name: v for v in self.variables}
        self.domains = {v.name: v.domain for v in self.variables}

    def read_resource(
        self, resource: str, fields: Fields, prefixed: Mapping[str, list[str]]
    ) -> Resource:
        """A resource with its abilities and its own transitions (named `RESOURCE.NAME`)."""
        prefix = resource + "."
        aliases = {name[len(prefix) :]: name for name in prefixed.get(prefix, ())}
        own: list[str] = []
        abilities = self.read_abilities(resource, fields, aliases, own)
        scope = scope_for(self.domains, self.predicates, aliases, self.reader.sizes)
        for node in self.sequence(fields, "transitions"):
            read = read_transition(self.reader, node, scope, self.by_name)
            if read is not None:
                named = replace(read, name=prefix + read.name)
                self.transitions.append((named, node))
                self.names.add(named.name)
                own.append(named.name)
        return Resource(
            resource,
            read_description(self.reader, fields),
            tuple(aliases.values()),
            tuple(abilities),
            tuple(own),
            _resource_kind(self.reader, fields.get("kind")),
            display=read_display(self.reader, fields, f"resource '{resource}'"),
        )

    def read_abilities(
        self, resource: str, fields: Fields, aliases: dict[str, str], own: list[str]
    ) -> list[str]:
        """The resource's abilities (their transitions added to `own`); their names."""
        names: list[str] = []
        for node in self.sequence(fields, "abilities"):
            read = read_ability(self.reader, node, resource, self.domains, aliases, self.by_name)
            for ability, transitions in read:
                self.abilities.append(ability)
                names.append(ability.qualified)
                for predicate, expr in ability.predicates.items():
                    self.predicates[f"{ability.qualified}.{predicate}"] = expr
                for t, t_node in transitions:
                    if t.name not in self.names:  # a generic one, made once for all values
                        self.names.add(t.name)
                        self.transitions.append((t, t_node))
                        own.append(t.name)
                if ability.restart:
                    self.restart.update(ability.transitions)
        return names

    def read_station_transitions(self, scope: Scope) -> None:
        for node in self.sequence(self.top, "transitions"):
            station_wide = read_transition(self.reader, node, scope, self.by_name)
            if station_wide is not None:
                self.transitions.append((station_wide, node))
        self.reader.unique([(t.name, name_node(n)) for t, n in self.transitions], "transition")

    def read_specifications(
        self, scope: Scope
    ) -> tuple[list[Specification], list[tuple[StepRequirement, list[yaml.Node]]]]:
        """The invariants, and the specifications with `before` (`step_requirements`)."""
        reader = self.reader
        nodes = self.sequence(self.top, "specifications")
        steps = [n for n in nodes if key_node(n, "before") is not None]
        states = [n for n in nodes if key_node(n, "before") is None]
        specifications = list(each(reader, states, lambda n: read_specification(reader, n, scope)))
        requirements = list(each(reader, steps, lambda n: read_step_requirement(reader, n, scope)))
        at = name_nodes(nodes)
        named = [(s.name, s.source) for s in specifications]
        named += [(r.name, r.source) for r, _ in requirements]
        reader.unique([(name, at(source)) for name, source in named], "specification")
        return specifications, requirements


def _by_prefix(variables: list[Variable]) -> dict[str, list[str]]:
    """ "r1." -> the variables named r1.something (for the resource's short names)."""
    by_prefix: dict[str, list[str]] = {}
    for v in variables:
        parts = v.name.split(".")
        for k in range(1, len(parts)):
            by_prefix.setdefault(".".join(parts[:k]) + ".", []).append(v.name)
    return by_prefix


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
