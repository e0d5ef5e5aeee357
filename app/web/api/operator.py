"""The operator's work through the API: the task cards, a command card's Done, a maintenance
step done, a recovery step approved or rejected (permission `tasks`)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path
from pydantic import BaseModel, Field

from app.pages.cards import CardKind, TaskCard, task_cards
from app.station.live import StationError
from app.web import actions
from app.web.actions import Decision, answer, perform, plan_decision, step_decision
from app.web.api.common import ACT, BEARER, PREFIX, NamePath, acted, errors
from app.web.api.schemas import ActionAnswer, EventOut, RequestBody, events_out
from app.web.deps import LiveDep, TasksCaller
from app.web.limits import CARD_CHARS, MAX_PLAN_STEPS, MAX_STEP, StepName
from planner.runner import (
    Event,
    EventKind,
    MaintenanceDone,
)
from planner.runner.vocabulary import PersonAct

router = APIRouter(prefix=PREFIX, tags=["tasks"], dependencies=BEARER)


class TaskCardOut(BaseModel):
    """One thing a person must do now: a command card (POST /api/cards/{card}/done), a
    maintenance instruction (POST /api/maintenance/{transition}/done) or a recovery plan to
    approve (POST /api/recovery-plan with its `plan`; one step at a time: POST
    /api/approvals/{step}).  A `rejectable` instruction is a person's step of a
    forbidden-state recovery: one who cannot do it rejects it like an approval."""

    kind: CardKind
    key: str
    title: str
    why: str
    detail: str
    card: str
    transition: str
    step: int
    of: int
    rejectable: bool = False
    cause: str = Field("", description="what is wrong and what it stops, read first")
    safety: str = Field("", description="a maintenance step's safety note, read before Done")
    steps: list[str] = Field(
        default_factory=list, description="approval: the recovery plan's machine steps in words"
    )
    plan: list[str] = Field(
        default_factory=list,
        description="approval: the steps' transitions; send them back to "
        "POST /api/recovery-plan to approve or reject the whole plan at once",
    )
    waiting: str = Field("", description="instruction shown ahead: what the station does first")


class CardDoneOut(BaseModel):
    card: str
    events: list[EventOut]


class ApprovalIn(RequestBody):
    decision: Decision


class PlanDecisionIn(RequestBody):
    decision: Decision
    steps: list[StepName] = Field(
        min_length=1,
        max_length=MAX_PLAN_STEPS,
        description="the plan's steps as the approval card lists them (its `plan`)",
    )


def card_out(card: TaskCard) -> TaskCardOut:
    return TaskCardOut(
        kind=card.kind,
        key=card.key,
        title=card.title,
        why=card.why,
        detail=card.detail,
        card=card.card,
        transition=card.transition,
        step=card.step,
        of=card.of,
        rejectable=card.rejectable,
        cause=card.cause,
        safety=card.safety,
        steps=list(card.steps),
        plan=list(card.plan),
        waiting=card.waiting,
    )


@router.get("/tasks", summary="What people must do now: task cards", responses=errors(401, 403))
def get_tasks(_caller: TasksCaller, live: LiveDep) -> list[TaskCardOut]:
    """Approvals first (nothing runs without them), then maintenance steps, then the
    operator's command card.  Needs `tasks`."""
    return [card_out(c) for c in task_cards(live.view)]


@router.post(
    "/cards/{card}/done",
    summary="Confirm the command card shown now (the watch's Done)",
    responses=ACT,
)
async def card_done(
    caller: TasksCaller,
    live: LiveDep,
    card: Annotated[str, Path(min_length=1, max_length=CARD_CHARS, description="the card's value")],
) -> CardDoneOut:
    """409 when the card is no longer shown, or cannot be confirmed now.  Needs `tasks`."""
    done = await answer(live.confirm_card(caller.name, card))
    if not done:
        raise StationError(f"card '{card}' cannot be confirmed now; the station is not ready")
    detail = {"user": caller.name, "card": card}
    recorded = Event(live.view.now, EventKind.OPERATOR, PersonAct.CARD_DONE, detail)
    return CardDoneOut(card=card, events=events_out([recorded]))


@router.post(
    "/maintenance/{transition}/done",
    summary="Report a maintenance step as done",
    responses=ACT,
)
async def maintenance_done(
    caller: TasksCaller, live: LiveDep, transition: NamePath
) -> ActionAnswer:
    """Only a step an instruction card asks for now (see GET /api/tasks); 404 for a name
    that is no maintenance transition.  Needs `tasks`."""
    actions.maintenance_step(live, transition)
    return acted(await perform(live, MaintenanceDone(user=caller.name, transition=transition)))


@router.post(
    "/approvals/{step}",
    summary="Approve or reject a step of the forbidden-state recovery",
    responses=ACT,
)
async def approval(
    caller: TasksCaller,
    live: LiveDep,
    step: Annotated[int, Path(ge=0, le=MAX_STEP, description="the recovery plan's step")],
    body: ApprovalIn,
) -> ActionAnswer:
    """A rejected step is left out when the station plans the recovery again.  Needs `tasks`."""
    action = step_decision(caller.name, step, body.decision)
    return acted(await perform(live, action))


@router.post(
    "/recovery-plan",
    summary="Approve or reject the whole forbidden-state recovery plan at once",
    responses=ACT,
)
async def recovery_plan(caller: TasksCaller, live: LiveDep, body: PlanDecisionIn) -> ActionAnswer:
    """One decision on every machine step of the recovery plan the approval card shows
    (GET /api/tasks: its `plan`).  Approved steps are taken as their turn comes, without
    asking again; a rejected plan's steps are left out when the station plans again.  409
    when the plan changed since it was shown.  Needs `tasks`."""
    steps = tuple(body.steps)
    action = plan_decision(caller.name, steps, body.decision)
    return acted(await perform(live, action))
