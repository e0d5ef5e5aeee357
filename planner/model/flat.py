"""The flat model: variables, transitions and specifications (seed 000 Definitions 1-4).

Every richer station model (resources, abilities, operations, intentions) compiles down to
this form, and it is what the planners, the supervisor synthesis and the runner work on.
Values are immutable; a `Model` also carries the indexes that every consumer needs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from planner.model.expressions import TRUE, Assign, Expr, Value, format_value


class VariableKind(Enum):
    """Where a variable's value comes from (seed 003 Definition 1, seed 000 sec. 3)."""

    MEASURED = "measured"  # from a device, through a pipeline
    COMMAND = "command"  # to a device (a goal or output state)
    ESTIMATED = "estimated"  # inferred by the controller from its own actions
    DECISION = "decision"  # abstract product/resource state that operations plan over


class TransitionKind(Enum):
    CONTROLLED = "controlled"  # taken only when a plan says so
    AUTOMATIC = "automatic"  # taken whenever enabled, before any controlled one
    EFFECT = "effect"  # what the world does to measured variables: planned, never executed
    MAINTENANCE = "maintenance"  # an operator's action, planned only during recovery


UNCONTROLLABLE = frozenset((TransitionKind.AUTOMATIC, TransitionKind.EFFECT))


@dataclass(frozen=True, slots=True)
class SourceLocation:
    """Where something was written: 1-based line and column."""

    file: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


@dataclass(frozen=True, slots=True)
class Variable:
    name: str
    domain: tuple[Value, ...]
    initial: Value
    kind: VariableKind = VariableKind.ESTIMATED
    source: SourceLocation | None = field(default=None, compare=False)
    # words for people (planner.words); no planner reads them
    description: str = field(default="", compare=False)
    display: str = field(default="", compare=False)
    display_values: tuple[tuple[Value, str], ...] = field(default=(), compare=False)

    @property
    def is_bool(self) -> bool:
        return self.domain == (False, True)

    def describe_domain(self) -> str:
        return "bool" if self.is_bool else "[" + ", ".join(map(format_value, self.domain)) + "]"


BOOL: tuple[Value, ...] = (False, True)


@dataclass(frozen=True, slots=True)
class Transition:
    """`guard / actions`; all actions read the state before the transition."""

    name: str
    kind: TransitionKind
    guard: Expr = TRUE
    actions: tuple[Assign, ...] = ()
    source: SourceLocation | None = field(default=None, compare=False)
    description: str = field(default="", compare=False)  # plain words, for instructions
    display: str = field(default="", compare=False)  # its name for people (planner.words)
    # a maintenance step's safety note: what a person does first to approach safely
    safety: str = field(default="", compare=False)

    @property
    def written(self) -> frozenset[str]:
        return frozenset(a.target for a in self.actions)


@dataclass(frozen=True, slots=True)
class Specification:
    """An invariant; a state that violates it is forbidden."""

    name: str
    invariant: Expr
    source: SourceLocation | None = field(default=None, compare=False)
    description: str = field(default="", compare=False)  # what it protects, in words
    display: str = field(default="", compare=False)  # its name for people (planner.words)


@dataclass(frozen=True)
class Model:
    """A flat model, checked: names unique, expressions resolved against the variables."""

    variables: tuple[Variable, ...]
    transitions: tuple[Transition, ...]
    specifications: tuple[Specification, ...] = ()
    file: str = "<model>"
    variable_index: dict[str, int] = field(init=False, repr=False, compare=False)
    transition_index: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "variable_index", {v.name: i for i, v in enumerate(self.variables)}
        )
        object.__setattr__(
            self, "transition_index", {t.name: i for i, t in enumerate(self.transitions)}
        )

    def variable(self, name: str) -> Variable:
        return self.variables[self.variable_index[name]]

    def transition(self, name: str) -> Transition:
        return self.transitions[self.transition_index[name]]

    @property
    def domains(self) -> dict[str, tuple[Value, ...]]:
        return {v.name: v.domain for v in self.variables}

    def initial_values(self) -> dict[str, Value]:
        return {v.name: v.initial for v in self.variables}
