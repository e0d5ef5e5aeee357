"""What the runner looks up about its station model, computed once when it is built.

A tick looks only at what a change can concern: the effects, automatic transitions and
invariants that read a changed variable, the effects that could explain a measured change.
These indexes make that a lookup instead of a pass over the model, so a tick stays cheap on
large models.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from planner.model.expressions import Expr, Value, conjuncts, variables_of
from planner.model.flat import Model, TransitionKind, VariableKind
from planner.model.semantics import CompiledTransition, Semantics, State, compile_expr
from planner.model.station import Intention, Operation, Station

Predicate = Callable[[State], bool]


class StationIndex:
    """Lookups over one station model (immutable once built)."""

    def __init__(self, station: Station, semantics: Semantics) -> None:
        model = station.model
        position = model.variable_index
        self.station = station
        self.model = model
        self.semantics = semantics
        self.variable_kind = {v.name: v.kind for v in model.variables}
        self.measured = {v.name for v in model.variables if v.kind is VariableKind.MEASURED}
        self.decisions = [v.name for v in model.variables if v.kind is VariableKind.DECISION]
        self.effects = [c for c in semantics.transitions if c.kind is TransitionKind.EFFECT]
        self.effect_position = {e.name: k for k, e in enumerate(self.effects)}
        self._index_readers(model, semantics)
        self._index_resources(station)
        self.intentions: dict[str, Intention] = {i.name: i for i in station.intentions}
        self.operations: dict[str, Operation] = {o.name: o for o in station.operations}
        self.intention_precondition = {
            i.name: compile_expr(i.precondition, position) for i in station.intentions
        }
        self.intention_goal = {i.name: compile_expr(i.goal, position) for i in station.intentions}
        # each intention's goal as its conjuncts: how much of it a state satisfies
        self.goal_parts = {
            i.name: [compile_expr(part, position) for part in conjuncts(i.goal)]
            for i in station.intentions
        }
        self.operation_precondition = {
            o.name: compile_expr(o.precondition, position) for o in station.operations
        }
        self.operation_variables = {
            o.name: frozenset(
                variables_of(o.precondition)
                | variables_of(o.goal)
                | {a.target for a in o.effects}
                | {a.source for a in o.effects if a.source is not None}
            )
            for o in station.operations
        }
        # operations whose effects change measured variables only (a robot's position):
        # the operation plan may skip or append them without planning
        self.measures_only = {
            o.name: all(a.target in self.measured for a in o.effects) for o in station.operations
        }
        self._compiled: dict[Expr, Predicate] = {}

    def _index_resources(self, station: Station) -> None:
        """Who owns which transition, and the alternatives among an ability's effects."""
        # the other effects of the same ability: what may happen instead of an expected one
        self.alternatives: dict[str, frozenset[str]] = {}
        for ability in station.abilities:
            own = {n for n in ability.transitions if n in self.effect_position}
            for name in own:
                self.alternatives[name] = self.alternatives.get(name, frozenset()) | (own - {name})
        # transition -> its resource: `Station.owner_of` as a mapping, for the pages and records
        self.owner: dict[str, str] = {
            name: station.owner_of(name) for r in station.resources for name in r.transitions
        }
        self.resource_transitions = {r.name: frozenset(r.transitions) for r in station.resources}
        # what a resource measures: stale while it does not answer
        self.resource_measured = {
            r.name: frozenset(v for v in r.variables if v in self.measured)
            for r in station.resources
        }
        # the transitions of people's resources (their steps are people's to do), and the
        # effects among them: never timed out as a device's would be
        self.person_transitions = frozenset(
            name
            for resource in station.resources
            if resource.person
            for name in resource.transitions
        )
        self.person_effects = frozenset(
            name for name in self.person_transitions if name in self.effect_position
        )

    def _index_readers(self, model: Model, semantics: Semantics) -> None:
        """For each variable (by position): the invariants, automatic transitions and effects
        whose guard reads it; for each measured variable: the effects that write it."""
        position = model.variable_index
        # whose guard reads it; for each measured variable: the effects that write it
        self.invariants_reading: list[list[int]] = [[] for _ in model.variables]
        for k, specification in enumerate(model.specifications):
            for name in variables_of(specification.invariant):
                self.invariants_reading[position[name]].append(k)
        self.automatics_reading: list[list[int]] = [[] for _ in model.variables]
        self.automatic_writes: list[list[int]] = []
        self.automatic_reads: list[frozenset[str]] = []
        for k, automatic in enumerate(semantics.automatic):
            self.automatic_reads.append(frozenset(variables_of(automatic.transition.guard)))
            for name in self.automatic_reads[k]:
                self.automatics_reading[position[name]].append(k)
            written = {position[a.target] for a in automatic.transition.actions}
            self.automatic_writes.append(sorted(written))
        self.effects_reading: list[list[int]] = [[] for _ in model.variables]
        self.effects_writing: dict[str, list[int]] = {}
        for k, effect in enumerate(self.effects):
            for name in variables_of(effect.transition.guard):
                self.effects_reading[position[name]].append(k)
            for action in effect.transition.actions:
                self.effects_writing.setdefault(action.target, []).append(k)

    def as_state(self, values: Mapping[str, Value]) -> State:
        return tuple(values[v.name] for v in self.model.variables)

    def compiled(self, expr: Expr) -> Predicate:
        check = self._compiled.get(expr)
        if check is None:
            check = compile_expr(expr, self.model.variable_index)
            self._compiled[expr] = check
        return check

    def holds(self, expr: Expr, values: Mapping[str, Value]) -> bool:
        return self.compiled(expr)(self.as_state(values))

    def transition(self, name: str) -> CompiledTransition:
        return self.semantics.by_name[name]

    def kind_of(self, transition: str) -> TransitionKind:
        return self.semantics.by_name[transition].kind

    def describe(self, transition: str) -> str:
        """A transition in words: its description, else its actions."""
        t = self.model.transition(transition)
        return t.description or ", ".join(
            f"{a.target} := {a.source if a.source else a.value}" for a in t.actions
        )
