"""The station through the API: its model, modes, resources, states and plans, as a line
system needs them (permission `station` or `tasks`)."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from app.station.view import StationView
from app.web.api.common import BEARER, PREFIX, errors
from app.web.deps import LiveDep, StationOrTasksCaller
from planner.model.expressions import format_expr
from planner.runner import IntentionState, OperationState, TransitionPlan

router = APIRouter(prefix=PREFIX, tags=["station"], dependencies=BEARER)


class ResourceOut(BaseModel):
    name: str
    description: str
    available: bool = Field(description="false while the device does not answer")
    variables: list[str]


class OperationStepOut(BaseModel):
    index: int
    operation: str
    after: list[int] = Field(description="indexes of the steps it waits for")
    started: bool
    finished: bool


class BlockOut(BaseModel):
    """A controlled step and the uncontrollable steps that follow it."""

    index: int
    transition: str
    steps: list[str]
    after: list[int] = Field(description="indexes of the blocks it waits for")
    taken: bool
    done: bool
    approved: bool = Field(description="recovery plans: an operator approved it")


class TransitionPlanOut(BaseModel):
    goal: str
    steps: list[str]
    blocks: list[BlockOut]


class PlansOut(BaseModel):
    operations: list[OperationStepOut] | None = Field(
        None, description="the operation plan, in start order"
    )
    transitions: TransitionPlanOut | None = None
    recovery: TransitionPlanOut | None = Field(
        None, description="forbidden-state recovery: each step waits for an approval"
    )
    maintenance: TransitionPlanOut | None = Field(
        None, description="maintenance steps for an operation in error"
    )
    maintained: str = Field("", description="the operation the maintenance plan is for")


class ModelRef(BaseModel):
    number: int
    name: str


class StationOut(BaseModel):
    name: str
    model: ModelRef
    simulated: bool
    restart: bool = Field(description="restart mode: automatic starts paused, resets allowed")
    resets: list[str] = Field(description="operations being reset in restart mode")
    halted: str = Field(description="why automatic steps are halted ('' if they are not)")
    resources: list[ResourceOut]
    intentions: dict[str, str] = Field(
        description="name -> state: i (idle), e (executing), f (finished) or error"
    )
    operations: dict[str, str] = Field(description="name -> state: i, e or error")
    goals: dict[str, str] = Field(description="executing operations' planning goals")
    failures: dict[str, int] = Field(description="operations that failed, and how often")
    plans: PlansOut
    timed_out: list[str] = Field(description="effect transitions disabled after a time-out")
    variables: dict[str, bool | str] = Field(description="the live value of every variable")


def _plan_out(plan: TransitionPlan | None) -> TransitionPlanOut | None:
    if plan is None:
        return None
    done = plan.done
    return TransitionPlanOut(
        goal=format_expr(plan.goal),
        steps=list(plan.steps),
        blocks=[
            BlockOut(
                index=k,
                transition=block.transition,
                steps=list(block.steps),
                after=sorted(block.after),
                taken=k in plan.taken,
                done=k in done,
                approved=k in plan.approved,
            )
            for k, block in enumerate(plan.blocks)
        ],
    )


def station_out(view: StationView, name: str) -> StationOut:
    """The station as a line system needs it: version, modes, resources, states, plans."""
    station, state = view.model.station, view.state
    operation_plan = state.operation_plan
    steps = None
    if operation_plan is not None:
        steps = [
            OperationStepOut(
                index=i,
                operation=operation,
                after=sorted(operation_plan.after[i]) if i < len(operation_plan.after) else [],
                started=i in operation_plan.started,
                finished=i in operation_plan.finished,
            )
            for i, operation in enumerate(operation_plan.steps)
        ]
    return StationOut(
        name=name,
        model=ModelRef(number=view.model.number, name=station.name),
        simulated=view.simulated,
        restart=state.restart_mode,
        resets=sorted(state.resetting),
        halted=state.halted,
        resources=[
            ResourceOut(
                name=r.name,
                description=r.description,
                available=r.name not in state.unavailable,
                variables=list(r.variables),
            )
            for r in station.resources
        ],
        intentions={
            i.name: state.intentions.get(i.name, IntentionState.INITIAL) for i in station.intentions
        },
        operations={
            o.name: state.operations.get(o.name, OperationState.INITIAL) for o in station.operations
        },
        goals={name: format_expr(goal) for name, goal in sorted(state.operation_goals.items())},
        failures={name: n for name, n in sorted(state.failures.items()) if n},
        plans=PlansOut(
            operations=steps,
            transitions=_plan_out(state.transition_plan),
            recovery=_plan_out(state.recovery),
            maintenance=_plan_out(state.maintenance),
            maintained=state.maintenance_for,
        ),
        timed_out=sorted(state.timed_out),
        variables=dict(state.values),
    )


@router.get(
    "/station",
    summary="The station: model, modes, resources, states and plans",
    responses=errors(401, 403),
)
def get_station(_caller: StationOrTasksCaller, live: LiveDep) -> StationOut:
    """Needs `station` or `tasks`.  Plans list their steps with the partial order: each step
    waits for the steps in its `after` list; the others may run in parallel."""
    return station_out(live.view, live.name)
