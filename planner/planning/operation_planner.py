"""The operation planner: which operations reach the active intentions (seed 000 sec. 4.2).

Operations become controlled transitions (guard: precondition, actions: effects) over the
variables they and the intentions use, and are planned with the same engines as the
transition planner.  Intentions' `phi U goal` are combined as "every state before the end
satisfies phi_k or goal_k, for each k": stricter than the LTL only in that phi_k must hold
again if goal_k is reached and then lost, so every plan found satisfies every intention.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from planner.model.expressions import TRUE, Value, conjunction, disjunction, variables_of
from planner.model.flat import Model, Transition, TransitionKind
from planner.model.station import Intention, Operation, Station
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

    def query(
        self,
        values: Mapping[str, Value],
        intentions: Iterable[Intention],
        *,
        disabled: Iterable[str] = (),
        max_steps: int = 100,
    ) -> PlanQuery:
        """The query for the given active intentions from the station's current values."""
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
        )

    def plan(self, query: PlanQuery, engine: str | None = None) -> PlanResult:
        return self.planner.plan(query, engine)

    def operations(self, result: PlanResult) -> list[Operation]:
        return [self.station.operation(name) for name in result.plan]
