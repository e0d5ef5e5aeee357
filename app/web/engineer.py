"""The engineer's pages: the station's details (`/station/details`: states, plans, variables,
devices) and its controls, and the simulation panel (the experiments E1-E9 on the simulated
station); the page helpers the other engineer modules share.  The overview and the timeline
are in app.web.station_pages, the model editor in app.web.model_pages.  Texts are in the
model's words (planner.words); names stay in form fields and data-* attributes only.

Every control is an action for the runner (app.web.actions): a typo in a name gets a 404
with a suggestion, a refusal a 409 with the runner's reason, and the runner's `operator`
and `refused` events, which carry the user, go to the audit log.  Pages are built from one
`StationView` each and refresh in parts (fragments re-fetched on the SSE `station` event).
"""

from __future__ import annotations

import hashlib
import time
from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Form, HTTPException, Query, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from app.pages import plans as plan_view
from app.pages.cards import task_cards
from app.people.auth import Permission, allowed
from app.station.cycle import ScheduledFault
from app.station.view import StationView
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
from planner.model.expressions import Value, format_value
from planner.runner import (
    Action,
    CancelIntention,
    EnterRestart,
    Event,
    EventKind,
    IntentionState,
    LeaveRestart,
    OperationState,
    ReenableEffect,
    ResetOperation,
    SetEstimated,
    StartIntention,
)
from planner.words import Wording, replan_words, sentence

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
    s, station, words = view.state, view.model.station, view.model.words
    return {
        "restart": s.restart_mode,
        "restart_reason": s.restart_reason if s.restart_mode else "",
        "restart_user": s.restart_user if s.restart_mode else "",
        "resources": [
            {
                "name": r.name,
                "label": sentence(words.resource(r.name)),
                "unavailable": r.name in s.unavailable,
                "silent": int(view.now - s.last_heard.get(r.name, view.now)),
            }
            for r in station.resources
        ],
        "devices": view.devices,
        "intentions": plan_view.intention_rows(station, s, words, view.runner.holds),
        "operations": plan_view.operation_rows(station, s, words),
        "timed_out": sorted(s.timed_out),
        "timed_out_words": {n: sentence(words.step(n)) for n in s.timed_out},
        "forbidden": [words.specification(n) for n in sorted(s.relaxed)]
        if s.recovery is not None
        else [],
        "halted": s.halted,
        "retries": view.runner.config.retries,
    }


def plans_context(view: StationView) -> dict[str, Any]:
    """The plans being followed, drawn as their partial orders, and the latest planning."""
    s, model, words = view.state, view.model.station.model, view.model.words
    plans = []
    if s.recovery is not None:
        plans.append(
            (
                "Recovery from a forbidden state",
                "Every step waits for an operator's approval on the tasks page.",
                plan_view.transition_plan("recovery", s.recovery, model, s.rejected, words),
            )
        )
    if s.maintenance is not None:
        drawing = plan_view.transition_plan("maintenance", s.maintenance, model, (), words)
        found = [e for e in view.events if e.kind is EventKind.PLAN]
        found = [e for e in found if e.detail.get("reason") == "maintenance"]
        length = int(found[-1].detail.get("length", 0) or 0) if found else 0
        shown = len(drawing.nodes)
        # the runner follows the plan found up to its last maintenance step (seed 000 4.5)
        part = (
            f"The first {steps(shown)} of the {steps(length)} planned, up to the last "
            "maintenance step; after it the station plans production again. "
            if length > shown
            else ""
        )
        about = f" for {words.operation(s.maintenance_for)}" if s.maintenance_for else ""
        plans.append(
            (
                "Maintenance plan" + about,
                part + "The operator's steps appear as instruction cards on the tasks page.",
                drawing,
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
                plan_view.operation_plan(s.operation_plan, view.model.station, s.operations, words),
            )
        )
    if s.transition_plan is not None:
        plans.append(
            (
                "Transition plan" + (" (restart mode: resets)" if s.restart_mode else ""),
                "Steps side by side touch no common variable: they may run in parallel.",
                plan_view.transition_plan("transitions", s.transition_plan, model, (), words),
            )
        )
    planning = [e for e in view.events if e.kind is EventKind.PLAN][-RECENT_PLANS:]
    return {"plans": plans, "planning": [planning_row(view, e) for e in reversed(planning)]}


def steps(count: int) -> str:
    return f"{count} step{'' if count == 1 else 's'}"


PLANNERS = {"OP": "operations", "TP": "transitions"}  # the planning level, in words


def planning_row(view: StationView, event: Event) -> dict[str, Any]:
    """One planning call in words, at its time of day."""
    words, detail = view.model.words, event.detail
    found = detail.get("status") == "found"
    result = "found" + (f", {steps(int(detail['length']))}" if "length" in detail else "")
    operation = str(detail.get("operation", ""))
    wall = time.time() - (view.now - event.time)
    return {
        "planner": PLANNERS.get(str(detail.get("level", "")), "planner")
        + (f" for {words.operation(operation)}" if operation else ""),
        "why": replan_words(str(detail.get("reason", ""))),
        "result": result if found else f"no plan ({words.text(str(detail.get('status', '')))})",
        "found": found,
        "at": datetime.fromtimestamp(wall).astimezone().strftime("%H:%M:%S"),
        "millis": event.millis,
    }


def variables_context(view: StationView) -> dict[str, Any]:
    station = view.model.station
    return {"groups": plan_view.variable_groups(station, view.state.values, view.state.unavailable)}


def set_form_context(
    view: StationView,
    variable: str = "",
    value: str = "",
    reason: str = "",
    violated: tuple[str, ...] = (),
) -> dict[str, Any]:
    """The set-a-variable form: which variable, its domain, its current value; after a
    value that would make the state forbidden, that value and reason, and the warning."""
    model, words = view.model.station.model, view.model.words
    names = plan_view.settable_variables(model)
    chosen = variable or (names[0] if names else "")
    if chosen:
        known(chosen, names, "estimated or decision variable")
    groups = plan_view.variable_groups(view.model.station, view.state.values)
    options = [
        (
            sentence(words.resource(g.resource)) if g.resource else "The product",
            [(r.name, words.variable(r.name)) for _, rows in g.kinds for r in rows if r.settable],
        )
        for g in groups
    ]
    domain = plan_view.domain_texts(model, chosen) if chosen else []
    current = format_value(view.state.values[chosen]) if chosen else ""
    return {
        "set_options": [(label, names) for label, names in options if names],
        "set_variable": chosen,
        "set_domain": [(v, words.value_name(chosen, v)) for v in domain],
        "set_current": current,
        "set_current_words": words.value_name(chosen, current) if chosen else "",
        "set_value": value or current,
        "set_reason": reason,
        "set_violated": [words.specification(n) for n in violated],
        "set_value_words": words.value(chosen, value) if violated else "",
    }


def would_violate(view: StationView, variable: str, value: Value) -> tuple[str, ...]:
    """The specifications that hold now and would not with `variable` set to `value`: the
    state it makes forbidden (the station would start recovering from it at once)."""
    now = view.state.values
    after = {**now, variable: value}
    holds = view.runner.holds
    return tuple(
        spec.name
        for spec in view.model.station.model.specifications
        if holds(spec.invariant, now) and not holds(spec.invariant, after)
    )


@router.get("/station/details")
def station_page(request: Request, caller: Station, variable: str = "") -> Response:
    view = server(request).live.view
    return station_page_with(request, caller, view, set_form_context(view, variable))


def station_page_with(
    request: Request, caller: Caller, view: StationView, set_form: dict[str, Any]
) -> Response:
    return render(
        request,
        "station_details.html",
        caller,
        "station",
        view,
        **status_context(view),
        **plans_context(view),
        **variables_context(view),
        **set_form,
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
    if request.headers.get("hx-target") == "station-overview":  # a Start or Cancel there
        from app.web.station_pages import overview_fragment

        return overview_fragment(request, caller, done)
    view = server(request).live.view
    context = status_context(view)
    return render(request, "_station_status.html", caller, "station", view, flash=done, **context)


def started(view: StationView, name: str) -> str:
    """What a Start did: started, or armed until its precondition holds (said in words)."""
    words = view.model.words
    found = [i for i in view.model.station.intentions if i.name == name]
    waits = plan_view.unmet(found[0].precondition, view.state.values, view.runner.holds, words)
    title = sentence(words.intention(name))
    if waits:
        return f"{title}: starts once its precondition holds; not yet: {waits}."
    return f"{title}: started."


@router.post("/station/intentions/start")
async def start_intention(request: Request, caller: Control, name: Name) -> Response:
    live = server(request).live
    action = StartIntention(user=caller.name, name=intention_name(live, name.strip()))
    return await control(request, caller, action, started(live.view, action.name))


@router.post("/station/intentions/cancel")
async def cancel_intention(request: Request, caller: Control, name: Name) -> Response:
    live = server(request).live
    action = CancelIntention(user=caller.name, name=intention_name(live, name.strip()))
    done = f"{sentence(live.view.model.words.intention(action.name))}: cancelled."
    return await control(request, caller, action, done)


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
    forbidden: Annotated[str, Form(max_length=20)] = "",
) -> Response:
    live = server(request).live
    name, chosen = estimated_value(live, variable.strip(), value)
    why = required(reason, "a reason for setting the variable")
    violated = would_violate(live.view, name, chosen)
    if violated and forbidden != "confirmed":  # warn first; the form asks to confirm
        context = set_form_context(live.view, name, format_value(chosen), why, violated)
        if not htmx(request):
            return station_page_with(request, caller, live.view, context)
        headers = {"HX-Retarget": "#set-variable", "HX-Reswap": "outerHTML"}
        return render(
            request, "_station_set.html", caller, "station", live.view, headers=headers, **context
        )
    await perform(live, SetEstimated(user=caller.name, variable=name, value=chosen, reason=why))
    if not htmx(request):
        return RedirectResponse(f"/station/details?variable={name}", status_code=303)
    view = live.view
    done = f"{sentence(view.model.words.value(name, view.state.values[name]))}: set."
    context = {**variables_context(view), **set_form_context(view, name), "set_form_oob": True}
    return render(
        request, "_station_variables.html", caller, "station", view, flash=done, **context
    )


# -- the simulation panel -----------------------------------------------------------------------


def simulated(request: Request) -> StationView:
    live = server(request).live
    view = live.view
    if not live.simulated:
        raise HTTPException(404, "this station runs real devices: there is no simulation panel")
    return view


def fault_text(fault: ScheduledFault, words: Wording) -> str:
    text = plan_view.fault_words(fault.fault, words)
    if fault.when is not None:
        return f"{text}, when {words.condition(fault.when)}"
    if fault.at is not None:
        return f"{text}, {fault.at:g} s after the start"
    return text


def experiments_context(request: Request) -> dict[str, Any]:
    words = server(request).live.view.model.words
    rows = []
    for key, (title, scenario) in sorted(server(request).experiments.items()):
        expect = scenario.expect
        rows.append(
            {
                "id": key,
                "title": words.text(title),
                "description": words.text(scenario.description),
                "intentions": [words.intention(i) for i in scenario.intentions or ()],
                "faults": [fault_text(f, words) for f in scenario.faults],
                "recovery": [words.text(str(r)) for r in expect.get("recovery") or ()],
                "operator": [words.text(str(o)) for o in expect.get("operator") or ()],
            }
        )
    return {"experiments": rows}


def simulation_status(request: Request, view: StationView) -> dict[str, Any]:
    s, words = view.state, view.model.words
    playing = [sc for title, sc in server(request).experiments.values() if title == view.experiment]
    faults = playing[0].faults if playing else ()
    said = {f.text: fault_text(f, words) for f in faults}
    return {
        "armed": [said.get(text, words.text(text)) for text in view.armed_faults],
        "executing": [words.intention(n) for n in s.intentions_in(IntentionState.EXECUTING)]
        + [words.operation(n) for n in s.operations_in(OperationState.EXECUTING)],
        "errors": [words.intention(n) for n in s.intentions_in(IntentionState.ERROR)]
        + [words.operation(n) for n in s.operations_in(OperationState.ERROR)],
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
        flash=f"{view.model.words.text(title)}: started. Watch the station and the tasks pages.",
        **simulation_status(request, view),
    )


def _include_model_pages() -> None:
    """The model editor's routes (app.web.model_pages), served with these: it uses this
    module's page helpers, so it is imported once they exist."""
    from app.web import model_pages

    router.include_router(model_pages.router)


_include_model_pages()
