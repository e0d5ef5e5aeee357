"""The station form of a model: resources, abilities, operations, intentions (docs/models.md).

It compiles to the flat `Model` of DESIGN.md section 8, and keeps what the runner and the
operation planner need besides: each ability's standard predicates and transitions (seed 003
sec. II-C), the restart abilities (seed 001 VIII-A), and the operations and intentions
(seed 000 Definitions 5 and 6).  Read from YAML by `planner.reading.station`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from functools import cached_property

from planner.model.expressions import (
    Assign,
    BoolVar,
    Equals,
    Expr,
    Not,
    Value,
    conjunction,
)
from planner.model.flat import Model, SourceLocation
from planner.model.watch import Watch


@dataclass(frozen=True)
class Ability:
    """One (instantiated) ability of a resource: its named predicates and its transitions."""

    resource: str
    name: str  # e.g. goto_bp1
    template: str  # e.g. goto
    value: str | None  # the parameter value of this instance
    predicates: dict[str, Expr]
    transitions: tuple[str, ...]
    restart: bool = False
    description: str = ""  # plain words, with the parameter's value filled in
    display: str = ""  # its name for people, the value's words filled in (planner.words)

    @property
    def qualified(self) -> str:
        return f"{self.resource}.{self.name}"


class ResourceKind(StrEnum):
    """Who a resource's effects come from: a device, timed out when late, or a person (an
    operator with a watch), who takes the time the work takes and is never timed out."""

    DEVICE = "device"
    PERSON = "person"


@dataclass(frozen=True)
class Resource:
    name: str
    description: str
    variables: tuple[str, ...]
    abilities: tuple[str, ...]  # qualified ability names
    transitions: tuple[str, ...]  # every transition belonging to the resource
    kind: ResourceKind = ResourceKind.DEVICE
    watch: Watch | None = None  # a person's smartwatch (planner.model.watch)
    display: str = ""  # its name for people (planner.words)

    @property
    def person(self) -> bool:
        return self.kind is ResourceKind.PERSON


@dataclass(frozen=True)
class Operation:
    """`<precondition, effects, goal, actions>` (seed 000 Definition 5)."""

    name: str
    precondition: Expr
    effects: tuple[Assign, ...]
    goal: Expr
    actions: tuple[Assign, ...] = ()
    description: str = ""
    display: str = ""  # its name for people, the value's words filled in (planner.words)
    # the model's estimate of how long it takes, in seconds, until the station has learned
    # it from its own runs (None: no estimate)
    duration: float | None = None

    def planning_goal(self, values: Mapping[str, Value]) -> Expr:
        """The transition planner's goal: `goal` and the effects evaluated in `values`."""
        return conjunction([self.goal, *(effect_as_goal(a, values) for a in self.effects)])


@dataclass(frozen=True)
class Intention:
    """`<precondition, goal, always, actions>` (seed 000 Definition 6; `always U goal`)."""

    name: str
    precondition: Expr
    goal: Expr
    always: Expr | None = None
    actions: tuple[Assign, ...] = ()
    description: str = ""
    display: str = ""  # its name for people (planner.words)
    product: bool = False  # what the station makes: "Done today" counts its finished runs


def effect_as_goal(action: Assign, values: Mapping[str, Value]) -> Expr:
    """`x := v` as `x == v`; `x := y` as `x == <value of y in values>`."""
    if action.source is None:
        assert action.value is not None
        return value_is(action.target, action.value)
    return value_is(action.target, values[action.source])


def value_is(name: str, value: Value) -> Expr:
    if isinstance(value, bool):
        return BoolVar(name) if value else Not(BoolVar(name))
    return Equals(name, value)


@dataclass(frozen=True)
class StepRequirement:
    """A state some steps need before they are taken (a specification with `before`): a
    person's step on a robot needs its tools idle.  Compiled into those steps' guards (so
    plans and the supervisor follow it); kept to say why on the cards."""

    name: str
    requires: Expr
    steps: tuple[str, ...]
    source: SourceLocation | None = field(default=None, compare=False)
    description: str = field(default="", compare=False)
    display: str = field(default="", compare=False)


@dataclass(frozen=True)
class Station:
    model: Model
    name: str = ""
    resources: tuple[Resource, ...] = ()
    abilities: tuple[Ability, ...] = ()
    operations: tuple[Operation, ...] = ()
    intentions: tuple[Intention, ...] = ()
    predicates: dict[str, Expr] = field(default_factory=dict)
    restart_transitions: frozenset[str] = frozenset()
    description: str = ""
    display: str = ""  # the station's name for people (planner.words)
    step_requirements: tuple[StepRequirement, ...] = ()

    def operation(self, name: str) -> Operation:
        return next(o for o in self.operations if o.name == name)

    def intention(self, name: str) -> Intention:
        return next(i for i in self.intentions if i.name == name)

    def owner_of(self, name: str) -> str:
        """The resource a transition or variable belongs to; "" if station-wide or unknown."""
        return self._owners.get(name, "")

    @cached_property
    def _owners(self) -> dict[str, str]:
        """Name -> resource, made once; a transition's owner wins over a variable of the
        same name (names are unique per list, not across lists)."""
        owners = {name: r.name for r in self.resources for name in r.variables}
        owners.update({name: r.name for r in self.resources for name in r.transitions})
        return owners

    @property
    def watches(self) -> tuple[tuple[Resource, Watch], ...]:
        """The people's watches, with the person each belongs to."""
        return tuple((r, r.watch) for r in self.resources if r.watch is not None)
