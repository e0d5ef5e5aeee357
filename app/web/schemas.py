"""Pydantic models at the JSON API's boundary (`app.web.api`), and only there, with the
functions that make answers out of the station's own values.

Requests carry constraints (lengths, ranges, literals) so that junk is refused with a 422
that names the field before any handler runs; answers say what the station did.  Times in
answers are UTC date-times, except the runner's own clock (seconds since the station
started) in events.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from datetime import UTC, datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, model_validator
from pydantic_core import PydanticCustomError

from app.pages.cards import CardKind, TaskCard
from app.station.alarms import SHELVE_LIMIT, Alarm, AlarmChange
from app.station.view import StationView
from app.store.tables import AuditRecord, ModelVersion
from app.web.audit import detail_of
from app.web.model_editing import MAX_MODEL_CHARS
from planner.model.expressions import format_expr
from planner.runner import Event, IntentionState, TransitionPlan

INITIAL = IntentionState.INITIAL.value  # the same letter for operations

Name = Annotated[str, StringConstraints(min_length=1, max_length=200)]
Note = Annotated[str, StringConstraints(max_length=500)]
Reason = Annotated[str, StringConstraints(strip_whitespace=True, min_length=1, max_length=500)]
AlarmKey = Annotated[str, StringConstraints(min_length=1, max_length=200)]


class RequestBody(BaseModel):
    """A request body: unknown fields are refused rather than silently ignored."""

    model_config = ConfigDict(extra="forbid")


# -- errors ------------------------------------------------------------------------------------


class Message(BaseModel):
    """An error: what went wrong and, where possible, what to do instead."""

    detail: str


class FieldError(BaseModel):
    loc: list[str | int]
    msg: str


class ProblemOut(BaseModel):
    """A problem in a model text, where the editor would show it."""

    line: int
    column: int
    message: str


class Invalid(BaseModel):
    """A 422: `detail` says what to fix; `errors` locate bad request fields, `problems`
    locate errors in a model text (POST /api/models)."""

    detail: str
    errors: list[FieldError] = []
    problems: list[ProblemOut] = []


# -- events and actions ------------------------------------------------------------------------


class EventOut(BaseModel):
    """One thing the runner did (its kind is one of planner.runner.EventKind)."""

    time: float = Field(description="the runner's clock: seconds since the station started")
    kind: str
    subject: str
    detail: dict[str, Any] = {}
    millis: float | None = Field(None, description="planning time, for a plan event")


class ActionAnswer(BaseModel):
    """An action the station took: the runner's events of the tick that carried it out."""

    events: list[EventOut]


class ApprovalIn(RequestBody):
    decision: Literal["approve", "reject"]


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
    value: Annotated[str, StringConstraints(max_length=100)] | bool = Field(
        description="one of the variable's values; true/false for a boolean"
    )
    reason: Reason


# -- station -----------------------------------------------------------------------------------


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


class TaskCardOut(BaseModel):
    """One thing a person must do now: a command card (POST /api/cards/{card}/done), a
    maintenance instruction (POST /api/maintenance/{transition}/done) or a recovery step to
    approve (POST /api/approvals/{step}).  A `rejectable` instruction is a person's step of
    a forbidden-state recovery: one who cannot do it rejects it like an approval."""

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


class CardDoneOut(BaseModel):
    card: str
    events: list[EventOut]


# -- alarms ------------------------------------------------------------------------------------


class AlarmOut(BaseModel):
    key: str
    priority: Literal["critical", "high", "medium", "low"]
    message: str
    resource: str
    state: str
    active: bool = Field(description="its condition holds now")
    raised_at: datetime
    returned_at: datetime | None
    acked_by: str | None
    acked_at: datetime | None
    note: str
    shelved_by: str | None
    shelved_until: datetime | None


class AlarmChangeOut(BaseModel):
    key: str
    before: str | None
    after: str
    user: str | None
    note: str
    at: datetime
    alarm: AlarmOut


class AcknowledgeIn(RequestBody):
    key: AlarmKey
    note: Note = ""


class ShelveIn(RequestBody):
    key: AlarmKey
    minutes: float = Field(ge=1, le=SHELVE_LIMIT, allow_inf_nan=False)
    note: Note = ""


class UnshelveIn(RequestBody):
    key: AlarmKey


# -- models ------------------------------------------------------------------------------------


class ModelVersionOut(BaseModel):
    number: int
    author: str
    created: datetime
    note: str
    sha256: str
    active: bool = Field(description="the version the station runs")


class ModelTextOut(ModelVersionOut):
    text: str


class ModelIn(RequestBody):
    text: Annotated[str, StringConstraints(min_length=1, max_length=MAX_MODEL_CHARS)]
    note: Note = ""


class ModelSaved(BaseModel):
    number: int


class ActivatedOut(BaseModel):
    number: int
    active: bool


# -- simulation --------------------------------------------------------------------------------


class ExperimentOut(BaseModel):
    """One of the papers' experiments E1-E9, playable on a simulated station."""

    id: str
    title: str
    description: str
    intentions: list[str] = Field(description="the intentions it starts")


class ExperimentStarted(BaseModel):
    id: str
    title: str


# -- audit -------------------------------------------------------------------------------------


class AuditRecordOut(BaseModel):
    id: int
    time: datetime
    station: str
    user: str
    kind: str
    subject: str
    resource: str
    detail: dict[str, Any]
    hash: str


class AuditPageOut(BaseModel):
    records: list[AuditRecordOut] = Field(description="newest first")
    total: int = Field(description="records that match the filter")
    page: int
    pages: int
    page_size: int


# -- answers from the station's own values -----------------------------------------------------


def _json_ready(detail: Mapping[str, Any]) -> dict[str, Any]:
    """Event details are plain values, but sets or tuples may appear: make them JSON."""
    ready: dict[str, Any] = json.loads(json.dumps(dict(detail), default=_jsonable))
    return ready


def _jsonable(value: object) -> object:
    if isinstance(value, set | frozenset):
        return sorted(value, key=str)
    return str(value)


def events_out(events: Iterable[Event]) -> list[EventOut]:
    return [
        EventOut(
            time=round(e.time, 3),
            kind=e.kind,
            subject=e.subject,
            detail=_json_ready(e.detail),
            millis=None if e.millis is None else round(e.millis, 2),
        )
        for e in events
    ]


def _when(time: float | None) -> datetime | None:
    return None if time is None else datetime.fromtimestamp(time, UTC)


def alarm_out(alarm: Alarm) -> AlarmOut:
    return AlarmOut(
        key=alarm.key,
        priority=alarm.priority.value,
        message=alarm.message,
        resource=alarm.resource,
        state=str(alarm.state),
        active=alarm.active,
        raised_at=datetime.fromtimestamp(alarm.raised_at, UTC),
        returned_at=_when(alarm.returned_at),
        acked_by=alarm.acked_by,
        acked_at=_when(alarm.acked_at),
        note=alarm.note,
        shelved_by=alarm.shelved_by,
        shelved_until=_when(alarm.shelved_until),
    )


def change_out(change: AlarmChange) -> AlarmChangeOut:
    return AlarmChangeOut(
        key=change.key,
        before=None if change.before is None else str(change.before),
        after=str(change.after),
        user=change.user,
        note=change.note,
        at=datetime.fromtimestamp(change.at, UTC),
        alarm=alarm_out(change.alarm),
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
    )


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
        intentions={i.name: state.intentions.get(i.name, INITIAL) for i in station.intentions},
        operations={o.name: state.operations.get(o.name, INITIAL) for o in station.operations},
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


def version_out(row: ModelVersion, active_id: int) -> ModelVersionOut:
    return ModelVersionOut(
        number=row.number,
        author=row.author,
        created=datetime.fromtimestamp(row.created_at, UTC),
        note=row.note,
        sha256=row.sha256,
        active=row.id == active_id,
    )


def record_out(record: AuditRecord) -> AuditRecordOut:
    return AuditRecordOut(
        id=record.id,
        time=datetime.fromtimestamp(record.time, UTC),
        station=record.station,
        user=record.user,
        kind=record.kind,
        subject=record.subject,
        resource=record.resource,
        detail=detail_of(record),
        hash=record.hash,
    )
