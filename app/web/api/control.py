"""The engineer's station controls through the API: start or cancel an intention, enter or
leave restart mode, reset an operation, set an estimated variable, re-enable a timed-out
effect (permission `control`)."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter
from pydantic import Field, StringConstraints, model_validator
from pydantic_core import PydanticCustomError

from app.web import actions
from app.web.actions import perform
from app.web.api.common import ACT, BEARER, PREFIX, NamePath, acted
from app.web.api.schemas import ActionAnswer, Name, Note, RequestBody
from app.web.deps import Controller, LiveDep
from app.web.limits import API_VALUE_CHARS, NOTE_CHARS
from planner.runner import (
    CancelIntention,
    EnterRestart,
    LeaveRestart,
    ReenableEffect,
    ResetOperation,
    SetEstimated,
    StartIntention,
)

router = APIRouter(prefix=PREFIX, tags=["control"], dependencies=BEARER)
Reason = Annotated[
    str, StringConstraints(strip_whitespace=True, min_length=1, max_length=NOTE_CHARS)
]


class RestartIn(RequestBody):
    mode: Literal["enter", "leave"]
    reason: Note = Field("", description="why; required to enter restart mode")

    @model_validator(mode="after")
    def _reason_to_enter(self) -> RestartIn:
        if self.mode == "enter" and not self.reason.strip():
            raise PydanticCustomError(
                "reason_required", "say why the station enters restart mode (reason)"
            )
        return self


class EstimatedIn(RequestBody):
    variable: Name
    value: Annotated[str, StringConstraints(max_length=API_VALUE_CHARS)] | bool = Field(
        description="one of the variable's values; true/false for a boolean"
    )
    reason: Reason


@router.post("/intentions/{name}/start", summary="Start an intention", responses=ACT)
async def start_intention(caller: Controller, live: LiveDep, name: NamePath) -> ActionAnswer:
    """The intention runs as soon as its precondition holds.  Needs `control`."""
    known = actions.intention_name(live, name)
    return acted(await perform(live, StartIntention(user=caller.name, name=known)))


@router.post("/intentions/{name}/cancel", summary="Cancel an intention", responses=ACT)
async def cancel_intention(caller: Controller, live: LiveDep, name: NamePath) -> ActionAnswer:
    """Needs `control`."""
    known = actions.intention_name(live, name)
    return acted(await perform(live, CancelIntention(user=caller.name, name=known)))


@router.post("/restart", summary="Enter or leave restart mode", responses=ACT)
async def restart(caller: Controller, live: LiveDep, body: RestartIn) -> ActionAnswer:
    """Restart mode pauses automatic operation starts, allows resets, restart abilities and
    setting estimated variables.  Entering needs a reason.  Needs `control`."""
    if body.mode == "enter":
        action: EnterRestart | LeaveRestart = EnterRestart(
            user=caller.name, reason=body.reason.strip()
        )
    else:
        action = LeaveRestart(user=caller.name)
    return acted(await perform(live, action))


@router.post(
    "/operations/{name}/reset",
    summary="Reset an operation (restart mode)",
    responses=ACT,
)
async def reset_operation(caller: Controller, live: LiveDep, name: NamePath) -> ActionAnswer:
    """The station plans to reach the operation's precondition; 409 outside restart mode.
    Needs `control`."""
    known = actions.operation_name(live, name)
    return acted(await perform(live, ResetOperation(user=caller.name, name=known)))


@router.post(
    "/estimated",
    summary="Set an estimated or decision variable to match reality (restart mode)",
    responses=ACT,
)
async def set_estimated(caller: Controller, live: LiveDep, body: EstimatedIn) -> ActionAnswer:
    """`value` is one of the variable's values (true/false for a boolean); the reason is
    recorded.  Needs `control`."""
    text = ("true" if body.value else "false") if isinstance(body.value, bool) else body.value
    variable, value = actions.estimated_value(live, body.variable, text)
    action = SetEstimated(user=caller.name, variable=variable, value=value, reason=body.reason)
    return acted(await perform(live, action))


@router.post(
    "/effects/{name}/reenable",
    summary="Re-enable an effect transition that timed out",
    responses=ACT,
)
async def reenable_effect(caller: Controller, live: LiveDep, name: NamePath) -> ActionAnswer:
    """409 when the effect is not timed out.  Needs `control`."""
    known = actions.effect_name(live, name)
    return acted(await perform(live, ReenableEffect(user=caller.name, name=known)))
