"""The operation planner: which operations reach the active intentions (seed 000 sec. 4.2).

Operations become controlled transitions (guard: precondition, actions: effects) over the
variables they and the intentions use, and are planned with the same engines as the
transition planner.  Intentions' `phi U goal` are combined as "every state before the end
satisfies phi_k or goal_k, for each k": stricter than the LTL only in that phi_k must hold
again if goal_k is reached and then lost, so every plan found satisfies every intention.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import replace

from planner.model.expressions import TRUE, Value, conjunction, disjunction, variables_of
from planner.model.flat import Model, Transition, TransitionKind
from planner.model.station import Intention, Operation, Station
from planner.planning.makespan import expected_makespan
from planner.planning.query import PlanQuery, PlanResult
from planner.planning.transition_planner import TransitionPlanner


def operation_model(station: Station) -> Model:
    """The flat model the operation planner searches: one transition per operation."""
    used: set[str] = set()
    for operation in station.operations:
        used |= variables_of(operation.precondition)
        for effect in operation.effects:
            used.add(effect.target)
            if effect.source is not None:
                used.add(effect.source)
    for intention in station.intentions:
        used |= variables_of(intention.goal)
        if intention.always is not None:
            used |= variables_of(intention.always)
    variables = tuple(v for v in station.model.variables if v.name in used)
    transitions = tuple(
        Transition(o.name, TransitionKind.CONTROLLED, o.precondition, o.effects)
        for o in station.operations
    )
    return Model(variables, transitions, (), station.model.file)


class OperationPlanner:
    def __init__(self, station: Station, engine: str = "bdd") -> None:
        self.station = station
        self.model = operation_model(station)
        self.planner = TransitionPlanner(self.model, engine=engine)
        # what each operation reads and writes: its partial order with the others
        self.variables = {
            o.name: variables_of(o.precondition)
            | variables_of(o.goal)
            | {a.target for a in o.effects}
            | {a.source for a in o.effects if a.source is not None}
            for o in station.operations
        }

    def query(
        self,
        values: Mapping[str, Value],
        intentions: Iterable[Intention],
        *,
        disabled: Iterable[str] = (),
        max_steps: int = 100,
        durations: Mapping[str, float] | None = None,
    ) -> PlanQuery:
        """The query for the given active intentions from the station's current values;
        `durations`: seconds per operation, to prefer the shortest cycle (`plan`)."""
        active = list(intentions)
        goal = conjunction([i.goal for i in active])
        always = conjunction(
            [disjunction([i.always, i.goal]) for i in active if i.always is not None]
        )
        return PlanQuery(
            start=tuple(values[v.name] for v in self.model.variables),
            goal=goal,
            max_steps=max_steps,
            always=None if always == TRUE else always,
            disabled=frozenset(disabled),
            durations=tuple(sorted((durations or {}).items())),
        )

    def plan(self, query: PlanQuery, engine: str | None = None) -> PlanResult:
        """A minimal plan; with `query.durations`, of the plans of that length found by
        leaving out one of its operations at a time, one of the least expected makespan
        (the first found among equals), its makespan in `statistics`."""
        first = self.planner.plan(replace(query, durations=()), engine)
        if not query.durations or not first.found or first.length < 1:
            return first
        durations = dict(query.durations)
        found = {first.plan: first}
        for name in dict.fromkeys(first.plan):
            other = replace(
                query, disabled=query.disabled | {name}, max_steps=first.length, durations=()
            )
            result = self.planner.plan(other, engine)
            if result.found and result.length == first.length:
                found.setdefault(result.plan, result)
        spans = {plan: expected_makespan(self.variables, plan, durations) for plan in found}
        best = min(found, key=lambda plan: spans[plan])  # min keeps the first among equals
        statistics = dict(found[best].statistics)
        statistics.update(makespan=spans[best], alternatives=len(found))
        return replace(found[best], statistics=statistics)

    def operations(self, result: PlanResult) -> list[Operation]:
        return [self.station.operation(name) for name in result.plan]
