"""The engineer's station pages: the overview (`/station`, ISA-101 level 2) and the details
(`/station/details`: states, plans, variables, devices, and the forms of the controls, which
are app.web.routes.control).  Texts are in the model's words (planner.words); names stay in
form fields and data-* attributes only.

The overview fits one screen: each intention with its state and progress, each resource's
availability and what it does now, the alarms, what the station waits for, and links to the
details and to the timeline (app.web.routes.timeline).  Pages are built from one
`StationView` each and refresh in parts (fragments re-fetched on the SSE `station` event).
"""

from __future__ import annotations

import time
from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from fastapi.responses import Response

from app.pages import station_rows
from app.pages.activity import ResourceActivity, resource_activities
from app.pages.plans import operation_plan, transition_plan
from app.station.view import StationView
from app.web.actions import known
from app.web.deps import Caller, LiveDep, StationViewer
from app.web.limits import NAME_CHARS
from app.web.pages import live_fragment, render
from planner.model.expressions import Value, format_value
from planner.planning.query import PlanStatus
from planner.runner import Event, EventKind, IntentionState, PlanLevel, ReplanReason
from planner.runner.state import RunnerState
from planner.runner.vocabulary import RestartMove
from planner.runner.waiting import Waiting, waiting_for
from planner.words import replan_words, sentence

router = APIRouter(include_in_schema=False)
RECENT_PLANS = 6
# the planning level, in words
PLANNERS: dict[str, str] = {
    PlanLevel.OPERATIONS: "operations",
    PlanLevel.TRANSITIONS: "transitions",
}


def progress_words(state: RunnerState) -> str:
    """Operations done in this run (before a replan too) of done plus what the current
    plan still has: "11 of 11 operations done" at the end, never a count that restarts."""
    done = len(state.run_finished)
    plan = state.operation_plan
    left = len(plan.steps) - len(plan.finished) if plan is not None else 0
    if plan is None and not done:
        return ""
    return f"{done} of {done + left} operation{'' if done + left == 1 else 's'} done"


def queued_intentions(view: StationView) -> list[dict[str, str]]:
    """Intentions started (or allowed to start) that wait: for the station to be free, for
    restart mode to end, or for their precondition (`RunnerState.auto_start`)."""
    s, words, runner = view.state, view.model.words, view.runner
    busy = s.busy_intentions()
    out = []
    for intention in view.model.station.intentions:
        name = intention.name
        if name not in s.auto_start or s.intentions.get(name) is not IntentionState.INITIAL:
            continue
        if s.restart_mode:
            why = "restart mode: it starts once restart mode is left"
        elif busy:
            doing = ", ".join(words.intention(n) for n in busy)
            why = f"the station is busy with {doing}"
        else:
            why = station_rows.unmet(intention.precondition, s.values, runner.holds, words)
            why = f"needs {why}" if why else "starts in the next round"
        out.append({"name": name, "label": sentence(words.intention(name)), "why": why})
    return out


def activities(view: StationView) -> tuple[list[ResourceActivity], list[Waiting]]:
    s = view.state
    waits = waiting_for(view.runner, s)
    rows = resource_activities(view.model.station, s, waits, view.now, view.model.words)
    return rows, waits


def overview_context(view: StationView) -> dict[str, Any]:
    """What the overview shows: one consistent round."""
    s, station, words = view.state, view.model.station, view.model.words
    resources, found = activities(view)
    waits = [(str(w.who), sentence(words.text(w.what))) for w in found]
    return {
        "intentions": station_rows.intention_rows(station, s, words, view.runner.holds),
        "progress": progress_words(s),
        "running": [sentence(words.operation(n)) for n in s.executing()],
        "resources": resources,
        "queued": queued_intentions(view),
        "waits": waits,
        "restart": s.restart_mode,
        "forbidden": [words.specification(n) for n in sorted(s.relaxed)]
        if s.recovery is not None
        else [],
        "halted": words.text(s.halted) if s.halted else "",
        "active": bool(s.intentions_in(IntentionState.EXECUTING)),
    }


def overview_fragment(
    request: Request, caller: Caller, view: StationView, flash: str = ""
) -> Response:
    """The overview's live part, after a Start or Cancel on it (with `flash`)."""
    context = overview_context(view)
    return render(
        request, "_station_overview.html", caller, "station", view=view, flash=flash, **context
    )


@router.get("/station")
def station_overview(request: Request, caller: StationViewer, live: LiveDep) -> Response:
    view = live.view
    return render(request, "station.html", caller, "station", view=view, **overview_context(view))


@router.get("/station/fragments/overview")
def station_overview_part(request: Request, caller: StationViewer, live: LiveDep) -> Response:
    view = live.view
    context = overview_context(view)
    return live_fragment(request, "_station_overview.html", caller, "station", view=view, **context)


def status_context(view: StationView) -> dict[str, Any]:
    """Restart mode, resources, intentions, operations, timed-out effects."""
    s, station, words = view.state, view.model.station, view.model.words
    return {
        "restart": s.restart_mode,
        "restart_reason": s.restart_reason if s.restart_mode else "",
        "restart_user": s.restart_user if s.restart_mode else "",
        "restart_since": restart_since(view),
        "resources": activities(view)[0],
        "queued": queued_intentions(view),
        "devices": view.devices,
        "intentions": station_rows.intention_rows(station, s, words, view.runner.holds),
        "operations": station_rows.operation_rows(station, s, words),
        "timed_out": sorted(s.timed_out),
        "timed_out_words": {n: sentence(words.step(n)) for n in s.timed_out},
        "forbidden": [words.specification(n) for n in sorted(s.relaxed)]
        if s.recovery is not None
        else [],
        "halted": s.halted,
        "retries": view.runner.config.retries,
    }


def restart_since(view: StationView) -> str:
    """When restart mode was entered, as a time of day ("" if not in it, or if the event
    is older than the events a view keeps)."""
    if not view.state.restart_mode:
        return ""
    for event in reversed(view.events):
        if event.kind is EventKind.RESTART and event.subject == RestartMove.ENTERED:
            return wall_clock(view, event.time)
    return ""


def wall_clock(view: StationView, at: float) -> str:
    """A time of the station's clock as the time of day."""
    wall = time.time() - (view.now - at)
    return datetime.fromtimestamp(wall).astimezone().strftime("%H:%M:%S")


def plans_context(view: StationView) -> dict[str, Any]:
    """The plans being followed, drawn as their partial orders, and the latest planning."""
    s, model, words = view.state, view.model.station.model, view.model.words
    plans = []
    if s.recovery is not None:
        plans.append(
            (
                "Recovery from a forbidden state",
                "Every step waits for an operator's approval on the tasks page.",
                transition_plan("recovery", s.recovery, model, s.rejected, words),
            )
        )
    if s.maintenance is not None:
        drawing = transition_plan("maintenance", s.maintenance, model, (), words)
        found = [e for e in view.events if e.kind is EventKind.PLAN]
        found = [e for e in found if e.detail.get("reason") == ReplanReason.MAINTENANCE]
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
        sequential = view.runner.config.sequential
        plans.append(
            (
                "Operation plan",
                "Operations side by side are independent; this station starts one at a time."
                if sequential
                else "Operations side by side are independent and start together.",
                operation_plan(s.operation_plan, view.model.station, s.operations, words),
            )
        )
    if s.transition_plan is not None:
        plans.append(
            (
                "Transition plan" + (" (restart mode: resets)" if s.restart_mode else ""),
                "Steps side by side touch no common variable: they may run in parallel.",
                transition_plan("transitions", s.transition_plan, model, (), words),
            )
        )
    planning = [e for e in view.events if e.kind is EventKind.PLAN][-RECENT_PLANS:]
    return {"plans": plans, "planning": [planning_row(view, e) for e in reversed(planning)]}


def steps(count: int) -> str:
    return f"{count} step{'' if count == 1 else 's'}"


def planning_row(view: StationView, event: Event) -> dict[str, Any]:
    """One planning call in words, at its time of day."""
    words, detail = view.model.words, event.detail
    found = detail.get("status") == PlanStatus.FOUND.value
    result = "found" + (f", {steps(int(detail['length']))}" if "length" in detail else "")
    operation = str(detail.get("operation", ""))
    return {
        "planner": PLANNERS.get(str(detail.get("level", "")), "planner")
        + (f" for {words.operation(operation)}" if operation else ""),
        "why": replan_words(str(detail.get("reason", ""))),
        "result": result if found else f"no plan ({words.text(str(detail.get('status', '')))})",
        "found": found,
        "at": wall_clock(view, event.time),
        "millis": event.millis,
    }


def variables_context(view: StationView) -> dict[str, Any]:
    station = view.model.station
    return {
        "groups": station_rows.variable_groups(station, view.state.values, view.state.unavailable)
    }


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
    names = station_rows.settable_variables(model)
    chosen = variable or (names[0] if names else "")
    if chosen:
        known(chosen, names, "estimated or decision variable")
    groups = station_rows.variable_groups(view.model.station, view.state.values)
    options = [
        (
            sentence(words.resource(g.resource)) if g.resource else "The product",
            [(r.name, words.variable(r.name)) for _, rows in g.kinds for r in rows if r.settable],
        )
        for g in groups
    ]
    domain = station_rows.domain_texts(model, chosen) if chosen else []
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
def station_page(
    request: Request, caller: StationViewer, live: LiveDep, variable: str = ""
) -> Response:
    view = live.view
    return station_page_with(request, caller, view, set_form_context(view, variable))


def station_page_with(
    request: Request, caller: Caller, view: StationView, set_form: dict[str, Any]
) -> Response:
    return render(
        request,
        "station_details.html",
        caller,
        "station",
        view=view,
        **status_context(view),
        **plans_context(view),
        **variables_context(view),
        **set_form,
    )


@router.get("/station/fragments/status")
def station_status(request: Request, caller: StationViewer, live: LiveDep) -> Response:
    view = live.view
    context = status_context(view)
    return live_fragment(request, "_station_status.html", caller, "station", view=view, **context)


@router.get("/station/fragments/plans")
def station_plans(request: Request, caller: StationViewer, live: LiveDep) -> Response:
    view = live.view
    context = plans_context(view)
    return live_fragment(request, "_station_plans.html", caller, "station", view=view, **context)


@router.get("/station/fragments/variables")
def station_variables(request: Request, caller: StationViewer, live: LiveDep) -> Response:
    view = live.view
    context = variables_context(view)
    return live_fragment(
        request, "_station_variables.html", caller, "station", view=view, **context
    )


@router.get("/station/fragments/set-variable")
def station_set_form(
    request: Request,
    caller: StationViewer,
    live: LiveDep,
    variable: Annotated[str, Query(max_length=NAME_CHARS)] = "",
) -> Response:
    view = live.view
    context = set_form_context(view, variable)
    return render(request, "_station_set.html", caller, "station", view=view, **context)
