"""The engineer's pages: the live station view and its controls, the model editor with its
versions, and the simulation panel (the experiments E1-E9 on the simulated station).

Every control is an action for the runner (app.web.actions): a typo in a name gets a 404
with a suggestion, a refusal a 409 with the runner's reason, and the runner's `operator`
and `refused` events, which carry the user, go to the audit log.  Pages are built from one
`StationView` each and refresh in parts (fragments re-fetched on the SSE `station` event).
"""

from __future__ import annotations

import hashlib
from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Form, HTTPException, Query, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from app import plan_view
from app.auth import Permission, allowed
from app.station_cycle import ScheduledFault
from app.station_view import StationView
from app.store import versions
from app.views import task_cards
from app.web import model_editing
from app.web.actions import (
    answer,
    effect_name,
    estimated_value,
    intention_name,
    known,
    operation_name,
    perform,
)
from app.web.deps import Caller, page_context, require, server
from planner.expressions import format_expr, format_value
from planner.runner import (
    Action,
    CancelIntention,
    EnterRestart,
    EventKind,
    IntentionState,
    LeaveRestart,
    OperationState,
    ReenableEffect,
    ResetOperation,
    SetEstimated,
    StartIntention,
)

router = APIRouter(include_in_schema=False)

Station = Annotated[Caller, Depends(require(Permission.STATION))]
Control = Annotated[Caller, Depends(require(Permission.CONTROL))]
ModelEditor = Annotated[Caller, Depends(require(Permission.MODEL))]
Activator = Annotated[Caller, Depends(require(Permission.ACTIVATE))]
Simulator = Annotated[Caller, Depends(require(Permission.SIMULATE))]
Name = Annotated[str, Form(max_length=200)]
Reason = Annotated[str, Form(max_length=500)]
RECENT_PLANS = 6


def values_for(
    request: Request, caller: Caller, page: str, view: StationView, **extra: Any
) -> dict[str, Any]:
    """The page context; `view` is the one snapshot the whole page or fragment reads."""
    found = page_context(request, caller, page, view=view, **extra)
    found["can_control"] = allowed(caller.role, Permission.CONTROL)
    found["can_activate"] = allowed(caller.role, Permission.ACTIVATE)
    return found


def render(
    request: Request,
    template: str,
    caller: Caller,
    page: str,
    view: StationView,
    status: int = 200,
    headers: dict[str, str] | None = None,
    **extra: Any,
) -> Response:
    response: Response = server(request).templates.TemplateResponse(
        request,
        template,
        values_for(request, caller, page, view, **extra),
        status_code=status,
        headers=headers,
    )
    return response


def live_fragment(
    request: Request, template: str, caller: Caller, page: str, view: StationView, **extra: Any
) -> Response:
    """A fragment re-fetched on every station change (SSE).  The station changes several
    times a second (heartbeats), a fragment far less often: when the client already shows
    this very text (`seen`: the digest it got last), the answer is 204 and htmx leaves the
    page alone, so an open list, the focus and a selection survive."""
    values = values_for(request, caller, page, view, **extra)
    text = server(request).templates.get_template(template).render(values)
    digest = hashlib.blake2b(text.encode(), digest_size=8).hexdigest()
    if request.query_params.get("seen") == digest:
        return Response(status_code=204)
    return HTMLResponse(f'{text}<i hidden data-digest="{digest}"></i>')


def htmx(request: Request) -> bool:
    return bool(request.headers.get("hx-request"))


def required(text: str, what: str) -> str:
    """`text` stripped, or a 422 before anything reaches the runner."""
    text = text.strip()
    if not text:
        raise HTTPException(422, f"{what} is required")
    return text


# -- the station view ---------------------------------------------------------------------------


def status_context(view: StationView) -> dict[str, Any]:
    """Restart mode, resources, intentions, operations, timed-out effects."""
    s, station = view.state, view.model.station
    return {
        "restart": s.restart_mode,
        "restart_reason": s.restart_reason if s.restart_mode else "",
        "restart_user": s.restart_user if s.restart_mode else "",
        "resources": [
            {
                "name": r.name,
                "description": r.description,
                "unavailable": r.name in s.unavailable,
                "silent": int(view.now - s.last_heard.get(r.name, view.now)),
            }
            for r in station.resources
        ],
        "devices": view.devices,
        "intentions": plan_view.intention_rows(station, s),
        "operations": plan_view.operation_rows(station, s),
        "timed_out": sorted(s.timed_out),
        "forbidden": sorted(s.relaxed) if s.recovery is not None else [],
        "halted": s.halted,
        "retries": view.runner.config.retries,
    }


def plans_context(view: StationView) -> dict[str, Any]:
    """The plans being followed, drawn as their partial orders, and the latest planning."""
    s, model = view.state, view.model.station.model
    plans = []
    if s.recovery is not None:
        plans.append(
            (
                "Recovery from a forbidden state",
                "Every step waits for an operator's approval on the tasks page.",
                plan_view.transition_plan("recovery", s.recovery, model, s.rejected),
            )
        )
    if s.maintenance is not None:
        plans.append(
            (
                "Maintenance plan" + (f" for {s.maintenance_for}" if s.maintenance_for else ""),
                "The operator's steps appear as instruction cards on the tasks page.",
                plan_view.transition_plan("maintenance", s.maintenance, model),
            )
        )
    if s.operation_plan is not None:
        sequential = not view.runner.config.parallel_operations
        plans.append(
            (
                "Operation plan",
                "Operations side by side are independent; this station starts one at a time."
                if sequential
                else "Operations side by side are independent and start together.",
                plan_view.operation_plan(s.operation_plan, view.model.station, s.operations),
            )
        )
    if s.transition_plan is not None:
        plans.append(
            (
                "Transition plan" + (" (restart mode: resets)" if s.restart_mode else ""),
                "Steps side by side touch no common variable: they may run in parallel.",
                plan_view.transition_plan("transitions", s.transition_plan, model),
            )
        )
    planning = [e for e in view.events if e.kind is EventKind.PLAN][-RECENT_PLANS:]
    return {"plans": plans, "planning": list(reversed(planning))}


def variables_context(view: StationView) -> dict[str, Any]:
    station = view.model.station
    return {"groups": plan_view.variable_groups(station, view.state.values, view.state.unavailable)}


def set_form_context(view: StationView, variable: str = "") -> dict[str, Any]:
    """The set-a-variable form: which variable, its domain, its current value."""
    model = view.model.station.model
    names = plan_view.settable_variables(model)
    chosen = variable or (names[0] if names else "")
    if chosen:
        known(chosen, names, "estimated or decision variable")
    groups = plan_view.variable_groups(view.model.station, view.state.values)
    options = [
        (g.resource or "product", [row.name for _, rows in g.kinds for row in rows if row.settable])
        for g in groups
    ]
    return {
        "set_options": [(label, names) for label, names in options if names],
        "set_variable": chosen,
        "set_domain": plan_view.domain_texts(model, chosen) if chosen else [],
        "set_current": format_value(view.state.values[chosen]) if chosen else "",
    }


@router.get("/station")
def station_page(request: Request, caller: Station, variable: str = "") -> Response:
    view = server(request).live.view
    return render(
        request,
        "station.html",
        caller,
        "station",
        view,
        **status_context(view),
        **plans_context(view),
        **variables_context(view),
        **set_form_context(view, variable),
    )


@router.get("/station/fragments/status")
def station_status(request: Request, caller: Station) -> Response:
    view = server(request).live.view
    context = status_context(view)
    return live_fragment(request, "_station_status.html", caller, "station", view, **context)


@router.get("/station/fragments/plans")
def station_plans(request: Request, caller: Station) -> Response:
    view = server(request).live.view
    context = plans_context(view)
    return live_fragment(request, "_station_plans.html", caller, "station", view, **context)


@router.get("/station/fragments/variables")
def station_variables(request: Request, caller: Station) -> Response:
    view = server(request).live.view
    context = variables_context(view)
    return live_fragment(request, "_station_variables.html", caller, "station", view, **context)


@router.get("/station/fragments/set-variable")
def station_set_form(
    request: Request, caller: Station, variable: Annotated[str, Query(max_length=200)] = ""
) -> Response:
    view = server(request).live.view
    context = set_form_context(view, variable)
    return render(request, "_station_set.html", caller, "station", view, **context)


# -- station controls ---------------------------------------------------------------------------


async def control(request: Request, caller: Caller, action: Action, done: str) -> Response:
    """Carry out `action`; htmx gets the refreshed status with `done` as a message, a plain
    browser a redirect back to the page it came from."""
    await perform(server(request).live, action)
    if not htmx(request):
        return RedirectResponse("/station", status_code=303)
    view = server(request).live.view
    context = status_context(view)
    return render(request, "_station_status.html", caller, "station", view, flash=done, **context)


@router.post("/station/intentions/start")
async def start_intention(request: Request, caller: Control, name: Name) -> Response:
    live = server(request).live
    action = StartIntention(user=caller.name, name=intention_name(live, name.strip()))
    return await control(request, caller, action, f"Intention {action.name} started.")


@router.post("/station/intentions/cancel")
async def cancel_intention(request: Request, caller: Control, name: Name) -> Response:
    live = server(request).live
    action = CancelIntention(user=caller.name, name=intention_name(live, name.strip()))
    return await control(request, caller, action, f"Intention {action.name} cancelled.")


@router.post("/station/restart/enter")
async def enter_restart(request: Request, caller: Control, reason: Reason = "") -> Response:
    action = EnterRestart(user=caller.name, reason=required(reason, "a reason for restart mode"))
    return await control(request, caller, action, "Restart mode entered.")


@router.post("/station/restart/leave")
async def leave_restart(request: Request, caller: Control) -> Response:
    return await control(request, caller, LeaveRestart(user=caller.name), "Restart mode left.")


@router.post("/station/operations/reset")
async def reset_operation(request: Request, caller: Control, name: Name) -> Response:
    live = server(request).live
    action = ResetOperation(user=caller.name, name=operation_name(live, name.strip()))
    done = f"Operation {action.name} is being reset to its precondition."
    return await control(request, caller, action, done)


@router.post("/station/effects/reenable")
async def reenable_effect(request: Request, caller: Control, name: Name) -> Response:
    live = server(request).live
    action = ReenableEffect(user=caller.name, name=effect_name(live, name.strip()))
    return await control(request, caller, action, f"Effect {action.name} re-enabled.")


@router.post("/station/variables/set")
async def set_variable(
    request: Request,
    caller: Control,
    variable: Name,
    value: Annotated[str, Form(max_length=200)],
    reason: Reason = "",
) -> Response:
    live = server(request).live
    name, chosen = estimated_value(live, variable.strip(), value)
    why = required(reason, "a reason for setting the variable")
    await perform(live, SetEstimated(user=caller.name, variable=name, value=chosen, reason=why))
    if not htmx(request):
        return RedirectResponse(f"/station?variable={name}", status_code=303)
    view = live.view
    done = f"{name} set to {format_value(view.state.values[name])}."
    context = {**variables_context(view), **set_form_context(view, name), "set_form_oob": True}
    return render(
        request, "_station_variables.html", caller, "station", view, flash=done, **context
    )


# -- the model editor ---------------------------------------------------------------------------


def versions_context(request: Request) -> dict[str, Any]:
    srv = server(request)
    active_id = srv.live.model.version_id
    with srv.store.sessions() as session:
        rows = [
            {
                "number": v.number,
                "author": v.author,
                "note": v.note,
                "saved": datetime.fromtimestamp(v.created_at).astimezone(),
                "active": v.id == active_id,
            }
            for v in versions.versions(session, srv.live.name)
        ]
    return {"versions": rows, "active_number": srv.live.model.number}


def busy_context(request: Request) -> dict[str, Any]:
    return {"busy": server(request).live.busy()}


def model_page(
    request: Request,
    caller: Caller,
    text: str,
    shown: str,
    status: int = 200,
    **extra: Any,
) -> Response:
    return render(
        request,
        "model.html",
        caller,
        "model",
        server(request).live.view,
        status=status,
        text=text,
        shown=shown,
        **versions_context(request),
        **busy_context(request),
        **extra,
    )


@router.get("/model")
def model_editor(
    request: Request,
    caller: ModelEditor,
    version: Annotated[int | None, Query(ge=1, le=model_editing.MAX_VERSION)] = None,
) -> Response:
    srv = server(request)
    if version is None:
        text, shown = srv.live.model.text, f"version {srv.live.model.number} (active)"
    else:
        text, shown = model_editing.stored(srv, version).text, f"version {version}"
    return model_page(request, caller, text, shown)


Text = Annotated[str, Form(max_length=model_editing.MAX_MODEL_CHARS)]


@router.post(
    "/model/validate",
    max_body_size=model_editing.MODEL_BODY_BYTES,
    form_limits=model_editing.MODEL_FORM_LIMITS,  # type: ignore[arg-type]
)
def validate_model(request: Request, caller: ModelEditor, text: Text = "") -> Response:
    found = model_editing.problems(text)
    return render(
        request, "_model_errors.html", caller, "model", server(request).live.view, problems=found
    )


@router.post(
    "/model/save",
    max_body_size=model_editing.MODEL_BODY_BYTES,
    form_limits=model_editing.MODEL_FORM_LIMITS,  # type: ignore[arg-type]
)
def save_model(
    request: Request,
    caller: ModelEditor,
    text: Text = "",
    note: Annotated[str, Form(max_length=500)] = "",
) -> Response:
    srv = server(request)
    row, found = model_editing.save(srv, text, caller.name, note.strip())
    view = srv.live.view
    if row is None:
        message = f"Not saved: the model has {len(found)} problem{'' if len(found) == 1 else 's'}."
        if not htmx(request):
            return model_page(
                request, caller, text, "unsaved text", 422, problems=found, error=message
            )
        headers = {"HX-Retarget": "#model-errors", "HX-Reswap": "outerHTML"}
        return render(
            request,
            "_model_errors.html",
            caller,
            "model",
            view,
            status=422,
            headers=headers,
            problems=found,
            flash_error=message,
        )
    if not htmx(request):
        return RedirectResponse(f"/model?version={row.number}", status_code=303)
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        view,
        flash=f"Saved as version {row.number}; activate it to run it.",
        problems=[],
        clear_errors=True,
        **versions_context(request),
        **busy_context(request),
    )


@router.get("/model/diff")
def model_diff(
    request: Request,
    caller: ModelEditor,
    version: Annotated[int, Query(ge=1, le=model_editing.MAX_VERSION)],
) -> Response:
    srv = server(request)
    row = model_editing.stored(srv, version)
    active = srv.live.model
    lines = model_editing.diff(
        active.text, row.text, f"version {active.number} (active)", f"version {version}"
    )
    context: dict[str, Any] = {"diff": lines, "diff_version": version, "diff_active": active.number}
    if htmx(request):
        return render(request, "_model_diff.html", caller, "model", srv.live.view, **context)
    return model_page(request, caller, active.text, f"version {active.number} (active)", **context)


@router.post("/model/activate")
async def activate_model(
    request: Request,
    caller: Activator,
    version: Annotated[int, Form(ge=1, le=model_editing.MAX_VERSION)],
) -> Response:
    srv = server(request)
    await model_editing.activate(srv, version, caller.name)
    if not htmx(request):
        return RedirectResponse("/model", status_code=303)
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        srv.live.view,
        flash=f"Version {version} is active now.",
        **versions_context(request),
        **busy_context(request),
    )


@router.get("/model/fragments/station")
def model_station(request: Request, caller: ModelEditor) -> Response:
    view = server(request).live.view
    context = busy_context(request)
    return live_fragment(request, "_model_station.html", caller, "model", view, **context)


# -- the simulation panel -----------------------------------------------------------------------


def simulated(request: Request) -> StationView:
    live = server(request).live
    view = live.view
    if not live.simulated:
        raise HTTPException(404, "this station runs real devices: there is no simulation panel")
    return view


def fault_text(fault: ScheduledFault) -> str:
    text = plan_view.fault_words(fault.fault)
    if fault.when is not None:
        return f"{text}, when {format_expr(fault.when)}"
    if fault.at is not None:
        return f"{text}, {fault.at:g} s after the start"
    return text


def experiments_context(request: Request) -> dict[str, Any]:
    rows = []
    for key, (title, scenario) in sorted(server(request).experiments.items()):
        expect = scenario.expect
        rows.append(
            {
                "id": key,
                "title": title,
                "description": scenario.description,
                "intentions": list(scenario.intentions or ()),
                "faults": [fault_text(f) for f in scenario.faults],
                "recovery": [str(r) for r in expect.get("recovery") or ()],
                "operator": [str(o) for o in expect.get("operator") or ()],
            }
        )
    return {"experiments": rows}


def simulation_status(request: Request, view: StationView) -> dict[str, Any]:
    s = view.state
    playing = [sc for title, sc in server(request).experiments.values() if title == view.experiment]
    words = {f.text: fault_text(f) for f in (playing[0].faults if playing else ())}
    return {
        "armed": [words.get(text, text) for text in view.armed_faults],
        "executing": s.intentions_in(IntentionState.EXECUTING)
        + s.operations_in(OperationState.EXECUTING),
        "errors": s.intentions_in(IntentionState.ERROR) + s.operations_in(OperationState.ERROR),
        "tasks": len(task_cards(view)),
    }


@router.get("/simulation")
def simulation_page(request: Request, caller: Simulator) -> Response:
    view = simulated(request)
    return render(
        request,
        "simulation.html",
        caller,
        "simulation",
        view,
        **experiments_context(request),
        **simulation_status(request, view),
    )


@router.get("/simulation/fragments/status")
def simulation_fragment(request: Request, caller: Simulator) -> Response:
    view = simulated(request)
    context = simulation_status(request, view)
    return live_fragment(request, "_simulation_status.html", caller, "simulation", view, **context)


@router.post("/simulation/experiment")
async def play_experiment(request: Request, caller: Simulator, experiment: Name) -> Response:
    simulated(request)
    srv = server(request)
    key = known(experiment.strip(), sorted(srv.experiments), "experiment")
    title, scenario = srv.experiments[key]
    await answer(srv.live.play_experiment(scenario, title, caller.name))
    if not htmx(request):
        return RedirectResponse("/simulation", status_code=303)
    view = srv.live.view
    return render(
        request,
        "_simulation_status.html",
        caller,
        "simulation",
        view,
        flash=f"{title}: started. Watch the station and the tasks pages.",
        **simulation_status(request, view),
    )
