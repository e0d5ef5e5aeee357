"""The engineer's station controls: start or cancel an intention, enter or leave restart
mode, reset an operation, re-enable a timed-out effect, set an estimated variable.

Every control is an action for the runner (app.web.actions): a typo in a name gets a 404
with a suggestion, a refusal a 409 with the runner's reason, and the runner's `operator`
and `refused` events, which carry the user, go to the audit log.  htmx gets the refreshed
part of the station page it came from (app.web.routes.station), a plain browser a redirect.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import Response

from app.pages import station_rows
from app.station.live import LiveStation
from app.station.view import StationView
from app.web import outcomes
from app.web.actions import effect_name, estimated_value, intention_name, operation_name, perform
from app.web.deps import Caller, Controller, LiveDep
from app.web.limits import CONFIRM_CHARS, NAME_CHARS, NOTE_CHARS, VALUE_CHARS
from app.web.pages import htmx, render, required
from app.web.routes.station import (
    overview_fragment,
    set_form_context,
    station_page_with,
    status_context,
    variables_context,
    would_violate,
)
from planner.model.expressions import format_value
from planner.runner import (
    Action,
    CancelIntention,
    EnterRestart,
    LeaveRestart,
    ReenableEffect,
    ResetOperation,
    SetEstimated,
    StartIntention,
)
from planner.words import sentence

router = APIRouter(include_in_schema=False)
Name = Annotated[str, Form(max_length=NAME_CHARS)]
Reason = Annotated[str, Form(max_length=NOTE_CHARS)]


async def control(
    request: Request,
    caller: Caller,
    live: LiveStation,
    action: Action,
    done: str,
    restart_oob: bool = False,
) -> Response:
    """Carry out `action`; htmx gets the refreshed status with `done` as a message, a plain
    browser a redirect back to the page it came from."""
    await perform(live, action)
    if not htmx(request):
        return outcomes.done(request, "/station", done)
    if request.headers.get("hx-target") == "station-overview":  # a Start or Cancel there
        return overview_fragment(request, caller, live.view, done)
    view = live.view
    context = status_context(view)
    return render(
        request,
        "_station_status.html",
        caller,
        "station",
        view=view,
        flash=done,
        restart_oob=restart_oob,
        **context,
    )


def started(view: StationView, name: str) -> str:
    """What a Start did: started, or armed until its precondition holds (said in words)."""
    words = view.model.words
    found = [i for i in view.model.station.intentions if i.name == name]
    waits = station_rows.unmet(found[0].precondition, view.state.values, view.runner.holds, words)
    title = sentence(words.intention(name))
    if waits:
        return f"{title}: starts once its precondition holds; not yet: {waits}."
    return f"{title}: started."


@router.post("/station/intentions/start")
async def start_intention(
    request: Request, caller: Controller, live: LiveDep, name: Name
) -> Response:
    action = StartIntention(user=caller.name, name=intention_name(live, name.strip()))
    return await control(request, caller, live, action, started(live.view, action.name))


@router.post("/station/intentions/cancel")
async def cancel_intention(
    request: Request, caller: Controller, live: LiveDep, name: Name
) -> Response:
    action = CancelIntention(user=caller.name, name=intention_name(live, name.strip()))
    done = f"{sentence(live.view.model.words.intention(action.name))}: cancelled."
    return await control(request, caller, live, action, done)


@router.post("/station/restart/enter")
async def enter_restart(
    request: Request, caller: Controller, live: LiveDep, reason: Reason = ""
) -> Response:
    state = live.view.state
    if state.restart_mode:  # entering again would replace who entered it and why
        by = f" by {state.restart_user}" if state.restart_user else ""
        why = f" ({state.restart_reason})" if state.restart_reason else ""
        raise HTTPException(409, f"The station is already in restart mode{why}{by}.")
    action = EnterRestart(user=caller.name, reason=required(reason, "a reason for restart mode"))
    return await control(request, caller, live, action, "Restart mode entered.", True)


@router.post("/station/restart/leave")
async def leave_restart(request: Request, caller: Controller, live: LiveDep) -> Response:
    action = LeaveRestart(user=caller.name)
    return await control(request, caller, live, action, "Restart mode left.", True)


@router.post("/station/operations/reset")
async def reset_operation(
    request: Request, caller: Controller, live: LiveDep, name: Name
) -> Response:
    action = ResetOperation(user=caller.name, name=operation_name(live, name.strip()))
    done = f"Operation {action.name} is being reset to its precondition."
    return await control(request, caller, live, action, done)


@router.post("/station/effects/reenable")
async def reenable_effect(
    request: Request, caller: Controller, live: LiveDep, name: Name
) -> Response:
    action = ReenableEffect(user=caller.name, name=effect_name(live, name.strip()))
    return await control(request, caller, live, action, f"Effect {action.name} re-enabled.")


@router.post("/station/variables/set")
async def set_variable(
    request: Request,
    caller: Controller,
    live: LiveDep,
    variable: Name,
    value: Annotated[str, Form(max_length=VALUE_CHARS)],
    reason: Reason = "",
    forbidden: Annotated[str, Form(max_length=CONFIRM_CHARS)] = "",
) -> Response:
    """Set an estimated or decision variable; a value that would make the state forbidden
    is shown back with a warning first, and set once the form confirms it."""
    name, chosen = estimated_value(live, variable.strip(), value)
    why = required(reason, "a reason for setting the variable")
    violated = would_violate(live.view, name, chosen)
    if violated and forbidden != "confirmed":  # warn first; the form asks to confirm
        context = set_form_context(live.view, name, format_value(chosen), why, violated)
        if not htmx(request):
            return station_page_with(request, caller, live.view, context)
        headers = {"HX-Retarget": "#set-variable", "HX-Reswap": "outerHTML"}
        return render(
            request,
            "_station_set.html",
            caller,
            "station",
            view=live.view,
            headers=headers,
            **context,
        )
    await perform(live, SetEstimated(user=caller.name, variable=name, value=chosen, reason=why))
    view = live.view
    done = f"{sentence(view.model.words.value(name, view.state.values[name]))}: set."
    if not htmx(request):
        return outcomes.done(request, f"/station/details?variable={name}", done)
    context = {**variables_context(view), **set_form_context(view, name), "set_form_oob": True}
    return render(
        request, "_station_variables.html", caller, "station", view=view, flash=done, **context
    )
