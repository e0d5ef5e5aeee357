"""The JSON API under /api: what the pages do, for line systems (MES) and scripts.

Authenticate with `POST /api/token` and send `Authorization: Bearer <token>`; a browser
session works too (with its CSRF token on unsafe methods).  Each route names the
permission it needs (app.people.auth.PERMISSIONS).  Names are checked before the runner sees them
(404 with a suggestion); the runner then takes or refuses the action (409 with its reason);
bodies that do not fit the schema are 422.  Actions answer with the runner's events of the
tick that carried them out, so the caller sees what happened.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, HTTPException, Path, Query, Request
from fastapi.responses import JSONResponse
from fastapi.security import HTTPBearer

from app.pages.cards import task_cards
from app.people.auth import Permission
from app.station.live import StationError
from app.store import audit, versions
from app.web import actions, model_editing
from app.web.actions import answer, perform
from app.web.audit import Criteria, filter_dependency
from app.web.deps import Caller, require, server
from app.web.schemas import (
    AcknowledgeIn,
    ActionAnswer,
    ActivatedOut,
    AlarmChangeOut,
    AlarmOut,
    ApprovalIn,
    AuditPageOut,
    CardDoneOut,
    EstimatedIn,
    ExperimentOut,
    ExperimentStarted,
    Invalid,
    Message,
    ModelIn,
    ModelSaved,
    ModelTextOut,
    ModelVersionOut,
    ProblemOut,
    RestartIn,
    ShelveIn,
    StationOut,
    TaskCardOut,
    UnshelveIn,
    alarm_out,
    card_out,
    change_out,
    events_out,
    record_out,
    station_out,
    version_out,
)
from app.web.server import Server
from planner.reading.yaml_reader import closest
from planner.runner import (
    Approve,
    CancelIntention,
    EnterRestart,
    Event,
    EventKind,
    LeaveRestart,
    MaintenanceDone,
    ReenableEffect,
    Reject,
    ResetOperation,
    SetEstimated,
    StartIntention,
)

# documents the scheme (Swagger's "Authorize"); `require` does the checking
bearer = HTTPBearer(auto_error=False, description="a token from POST /api/token")
router = APIRouter(prefix="/api", dependencies=[Depends(bearer)])


def _errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    described = {
        400: (Message, "the body is not readable (not UTF-8 JSON)"),
        401: (Message, "not signed in, or the bearer token is invalid or expired"),
        403: (Message, "the caller's role lacks the permission"),
        404: (Message, "no such name or number; the message suggests the closest"),
        409: (Message, "the station refuses it now; the message gives the runner's reason"),
        422: (Invalid, "the request does not fit; the message says what to fix"),
        503: (Message, "the station did not answer in time"),
    }
    return {c: {"model": described[c][0], "description": described[c][1]} for c in codes}


ACT = _errors(400, 401, 403, 404, 409, 422, 503)

NamePath = Annotated[str, Path(min_length=1, max_length=200, description="a name in the model")]


def _acted(events: list[Event]) -> ActionAnswer:
    return ActionAnswer(events=events_out(events))


# -- station and tasks ---------------------------------------------------------------------------


@router.get(
    "/station",
    tags=["station"],
    summary="The station: model, modes, resources, states and plans",
    responses=_errors(401, 403),
)
def get_station(
    request: Request,
    _caller: Annotated[Caller, Depends(require(Permission.STATION, Permission.TASKS))],
) -> StationOut:
    """Needs `station` or `tasks`.  Plans list their steps with the partial order: each step
    waits for the steps in its `after` list; the others may run in parallel."""
    live = server(request).live
    return station_out(live.view, live.name)


@router.get(
    "/tasks",
    tags=["tasks"],
    summary="What people must do now: task cards",
    responses=_errors(401, 403),
)
def get_tasks(
    request: Request, _caller: Annotated[Caller, Depends(require(Permission.TASKS))]
) -> list[TaskCardOut]:
    """Approvals first (nothing runs without them), then maintenance steps, then the
    operator's command card.  Needs `tasks`."""
    return [card_out(c) for c in task_cards(server(request).live.view)]


@router.post(
    "/cards/{card}/done",
    tags=["tasks"],
    summary="Confirm the command card shown now (the watch's Done)",
    responses=ACT,
)
async def card_done(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    card: Annotated[str, Path(min_length=1, max_length=100, description="the card's value")],
) -> CardDoneOut:
    """409 when the card is no longer shown, or cannot be confirmed now.  Needs `tasks`."""
    live = server(request).live
    done = await answer(live.confirm_card(caller.name, card))
    if not done:
        raise StationError(f"card '{card}' cannot be confirmed now; the station is not ready")
    detail = {"user": caller.name, "card": card}
    recorded = Event(live.view.now, EventKind.OPERATOR, "card done", detail)
    return CardDoneOut(card=card, events=events_out([recorded]))


@router.post(
    "/maintenance/{transition}/done",
    tags=["tasks"],
    summary="Report a maintenance step as done",
    responses=ACT,
)
async def maintenance_done(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    transition: NamePath,
) -> ActionAnswer:
    """Only a step an instruction card asks for now (see GET /api/tasks); 404 for a name
    that is no maintenance transition.  Needs `tasks`."""
    live = server(request).live
    actions.maintenance_step(live, transition)
    return _acted(await perform(live, MaintenanceDone(user=caller.name, transition=transition)))


@router.post(
    "/approvals/{step}",
    tags=["tasks"],
    summary="Approve or reject a step of the forbidden-state recovery",
    responses=ACT,
)
async def approval(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    step: Annotated[int, Path(ge=0, le=10_000, description="the recovery plan's step")],
    body: ApprovalIn,
) -> ActionAnswer:
    """A rejected step is left out when the station plans the recovery again.  Needs `tasks`."""
    live = server(request).live
    if body.decision == "approve":
        action: Approve | Reject = Approve(user=caller.name, step=step)
    else:
        action = Reject(user=caller.name, step=step)
    return _acted(await perform(live, action))


# -- control -------------------------------------------------------------------------------------


@router.post(
    "/intentions/{name}/start",
    tags=["control"],
    summary="Start an intention",
    responses=ACT,
)
async def start_intention(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.CONTROL))],
    name: NamePath,
) -> ActionAnswer:
    """The intention runs as soon as its precondition holds.  Needs `control`."""
    live = server(request).live
    known = actions.intention_name(live, name)
    return _acted(await perform(live, StartIntention(user=caller.name, name=known)))


@router.post(
    "/intentions/{name}/cancel",
    tags=["control"],
    summary="Cancel an intention",
    responses=ACT,
)
async def cancel_intention(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.CONTROL))],
    name: NamePath,
) -> ActionAnswer:
    """Needs `control`."""
    live = server(request).live
    known = actions.intention_name(live, name)
    return _acted(await perform(live, CancelIntention(user=caller.name, name=known)))


@router.post(
    "/restart",
    tags=["control"],
    summary="Enter or leave restart mode",
    responses=ACT,
)
async def restart(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.CONTROL))],
    body: RestartIn,
) -> ActionAnswer:
    """Restart mode pauses automatic operation starts, allows resets, restart abilities and
    setting estimated variables.  Entering needs a reason.  Needs `control`."""
    live = server(request).live
    if body.mode == "enter":
        action: EnterRestart | LeaveRestart = EnterRestart(
            user=caller.name, reason=body.reason.strip()
        )
    else:
        action = LeaveRestart(user=caller.name)
    return _acted(await perform(live, action))


@router.post(
    "/operations/{name}/reset",
    tags=["control"],
    summary="Reset an operation (restart mode)",
    responses=ACT,
)
async def reset_operation(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.CONTROL))],
    name: NamePath,
) -> ActionAnswer:
    """The station plans to reach the operation's precondition; 409 outside restart mode.
    Needs `control`."""
    live = server(request).live
    known = actions.operation_name(live, name)
    return _acted(await perform(live, ResetOperation(user=caller.name, name=known)))


@router.post(
    "/estimated",
    tags=["control"],
    summary="Set an estimated or decision variable to match reality (restart mode)",
    responses=ACT,
)
async def set_estimated(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.CONTROL))],
    body: EstimatedIn,
) -> ActionAnswer:
    """`value` is one of the variable's values (true/false for a boolean); the reason is
    recorded.  Needs `control`."""
    live = server(request).live
    text = ("true" if body.value else "false") if isinstance(body.value, bool) else body.value
    variable, value = actions.estimated_value(live, body.variable, text)
    action = SetEstimated(user=caller.name, variable=variable, value=value, reason=body.reason)
    return _acted(await perform(live, action))


@router.post(
    "/effects/{name}/reenable",
    tags=["control"],
    summary="Re-enable an effect transition that timed out",
    responses=ACT,
)
async def reenable_effect(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.CONTROL))],
    name: NamePath,
) -> ActionAnswer:
    """409 when the effect is not timed out.  Needs `control`."""
    live = server(request).live
    known = actions.effect_name(live, name)
    return _acted(await perform(live, ReenableEffect(user=caller.name, name=known)))


# -- alarms --------------------------------------------------------------------------------------


@router.get(
    "/alarms",
    tags=["alarms"],
    summary="Active, unacknowledged and shelved alarms",
    responses=_errors(401, 403),
)
def get_alarms(
    request: Request, _caller: Annotated[Caller, Depends(require(Permission.ALARMS))]
) -> list[AlarmOut]:
    """Unacknowledged first, then by priority, then newest.  Needs `alarms`."""
    return [alarm_out(a) for a in server(request).live.view.alarms]


def _alarm_key(request: Request, key: str) -> str:
    keys = [a.key for a in server(request).live.view.alarms]
    if key in keys:
        return key
    guess = closest(key, keys)
    hint = f"; did you mean '{guess}'?" if guess else ""
    raise HTTPException(404, f"there is no active or shelved alarm '{key}'{hint}")


@router.post(
    "/alarms/acknowledge",
    tags=["alarms"],
    summary="Acknowledge an alarm",
    responses=ACT,
)
async def acknowledge(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.ACKNOWLEDGE))],
    body: AcknowledgeIn,
) -> AlarmChangeOut:
    """Keys contain ':' (resource:r2), so they travel in the body.  Needs `acknowledge`."""
    key = _alarm_key(request, body.key)
    live = server(request).live
    return change_out(await answer(live.acknowledge(key, caller.name, body.note.strip())))


@router.post(
    "/alarms/shelve",
    tags=["alarms"],
    summary="Shelve an alarm for a while",
    responses=ACT,
)
async def shelve(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.ACKNOWLEDGE))],
    body: ShelveIn,
) -> AlarmChangeOut:
    """It comes back by itself after `minutes` (at most a shift).  Needs `acknowledge`."""
    key = _alarm_key(request, body.key)
    live = server(request).live
    change = await answer(live.shelve(key, caller.name, body.minutes, body.note.strip()))
    return change_out(change)


@router.post(
    "/alarms/unshelve",
    tags=["alarms"],
    summary="Unshelve an alarm",
    responses=ACT,
)
async def unshelve(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.ACKNOWLEDGE))],
    body: UnshelveIn,
) -> AlarmChangeOut:
    """Needs `acknowledge`."""
    key = _alarm_key(request, body.key)
    return change_out(await answer(server(request).live.unshelve(key, caller.name)))


# -- models --------------------------------------------------------------------------------------


@router.get(
    "/models",
    tags=["models"],
    summary="The saved model versions, newest first",
    responses=_errors(401, 403),
)
def list_models(
    request: Request, _caller: Annotated[Caller, Depends(require(Permission.MODEL))]
) -> list[ModelVersionOut]:
    """Needs `model`."""
    srv = server(request)
    active = srv.live.view.model.version_id
    with srv.store.sessions() as session:
        return [version_out(v, active) for v in versions.versions(session, srv.live.name)]


VersionNumber = Annotated[int, Path(ge=1, le=1_000_000_000, description="the version's number")]


@router.get(
    "/models/{number}",
    tags=["models"],
    summary="One model version with its text",
    responses=_errors(401, 403, 404, 422),
)
def get_model(
    request: Request,
    _caller: Annotated[Caller, Depends(require(Permission.MODEL))],
    number: VersionNumber,
) -> ModelTextOut:
    """Needs `model`."""
    srv = server(request)
    row = model_editing.stored(srv, number)
    version = version_out(row, srv.live.view.model.version_id)
    return ModelTextOut(**version.model_dump(), text=row.text)


@router.post(
    "/models",
    tags=["models"],
    summary="Save a model text as a new version",
    max_body_size=model_editing.MODEL_BODY_BYTES,
    status_code=201,
    response_model=ModelSaved,
    responses={
        **_errors(400, 401, 403),
        422: {
            "model": Invalid,
            "description": "the model is not valid: `problems` lists each at its line and column",
        },
    },
)
def save_model(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.MODEL))],
    body: ModelIn,
) -> Any:
    """The text is checked as `sp check` would; a valid one becomes the next version (not
    yet active: POST /api/models/{number}/activate).  Needs `model`."""
    srv = server(request)
    row, problems = model_editing.save(srv, body.text, caller.name, body.note.strip())
    if row is None:
        first = problems[0]
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        invalid = Invalid(
            detail=f"the model is not valid: line {first.line}, column {first.column}: "
            f"{first.message}{more}",
            problems=[
                ProblemOut(line=p.line, column=p.column, message=p.message) for p in problems
            ],
        )
        return JSONResponse(invalid.model_dump(), status_code=422)
    return ModelSaved(number=row.number)


@router.post(
    "/models/{number}/activate",
    tags=["models"],
    summary="Run a saved model version",
    responses=_errors(401, 403, 404, 409, 422, 503),
)
async def activate_model(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.ACTIVATE))],
    number: VersionNumber,
) -> ActivatedOut:
    """Refused (409) while the station runs intentions or operations, unless it is in
    restart mode.  Building the new version's planners can take seconds.  Needs `activate`."""
    await model_editing.activate(server(request), number, caller.name)
    return ActivatedOut(number=number, active=True)


# -- simulation ----------------------------------------------------------------------------------


def _simulated(request: Request) -> Server:
    srv = server(request)
    if not srv.live.simulated:
        raise HTTPException(404, "this station runs real devices: there are no experiments")
    return srv


@router.get(
    "/experiments",
    tags=["simulation"],
    summary="The experiments a simulated station can play",
    responses=_errors(401, 403, 404),
)
def list_experiments(
    request: Request, _caller: Annotated[Caller, Depends(require(Permission.SIMULATE))]
) -> list[ExperimentOut]:
    """404 on a station with real devices.  Needs `simulate`."""
    return [
        ExperimentOut(
            id=key,
            title=title,
            description=scenario.description,
            intentions=list(scenario.intentions or ()),
        )
        for key, (title, scenario) in sorted(_simulated(request).experiments.items())
    ]


@router.post(
    "/experiments/{experiment}/play",
    tags=["simulation"],
    summary="Reset the simulated station to an experiment's start and play it",
    responses=ACT,
)
async def play_experiment(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.SIMULATE))],
    experiment: Annotated[str, Path(min_length=1, max_length=100, description="its id")],
) -> ExperimentStarted:
    """The experiment's faults are armed and its intentions started; its operator steps
    appear as task cards.  Needs `simulate`."""
    srv = _simulated(request)
    key = actions.known(experiment, sorted(srv.experiments), "experiment")
    title, scenario = srv.experiments[key]
    await answer(srv.live.play_experiment(scenario, title, caller.name))
    return ExperimentStarted(id=key, title=title)


# -- audit ---------------------------------------------------------------------------------------


@router.get(
    "/audit",
    tags=["audit"],
    summary="The audit log, filtered, newest first, in pages",
    responses=_errors(401, 403, 422),
)
def get_audit(
    request: Request,
    _caller: Annotated[Caller, Depends(require(Permission.AUDIT))],
    chosen: Annotated[Criteria, Depends(filter_dependency)],
    page: Annotated[int, Query(ge=1, le=1_000_000_000, description="1-based")] = 1,
) -> AuditPageOut:
    """The same filter as the audit page.  A page past the end gives the last page.  Needs
    `audit`."""
    with server(request).store.sessions() as session:
        found = audit.page_of(session, chosen.where, page)
        records = [record_out(r) for r in found.records]
    return AuditPageOut(
        records=records,
        total=found.total,
        page=found.page,
        pages=found.pages,
        page_size=audit.PAGE_SIZE,
    )
