"""The operator's pages: task cards (watch first), approvals, maintenance steps, and what
was done today (the alarms are app.web.routes.alarms).

A "Done" on a command card and an approval travel different ways: the watch is a device
(seed 001), so its Done goes to the devices (`LiveStation.confirm_card`) and the runner
learns of it as a measured change, while an approval is an action for the runner
(app.web.actions)."""

from __future__ import annotations

import hashlib
from collections.abc import Awaitable
from time import time
from typing import Annotated, Any

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import RedirectResponse, Response

from app.history.done_today import done_today
from app.pages.cards import station_activity, task_cards
from app.people.auth import Role
from app.station.live import LiveStation, StationError
from app.station.view import StationView
from app.web import outcomes
from app.web.actions import (
    Decision,
    answer,
    maintenance_step,
    perform,
    plan_decision,
    step_decision,
)
from app.web.deps import Caller, LiveDep, OptionalCaller, StoreDep, TasksCaller
from app.web.limits import CARD_CHARS, MAX_PLAN_STEPS, MAX_STEP, NAME_CHARS, StepName
from app.web.pages import htmx, render, same_origin_path
from planner.runner import MaintenanceDone

router = APIRouter(include_in_schema=False)


def card_context(view: StationView) -> dict[str, Any]:
    """What _tasks.html shows, and its digest."""
    cards, activity = task_cards(view), station_activity(view)
    digest = hashlib.blake2b(repr((cards, activity)).encode(), digest_size=8).hexdigest()
    return {"cards": cards, "station_activity": station_activity, "digest": digest}


def back(
    request: Request, caller: Caller, live: LiveStation, fragment: str, stale: str = ""
) -> Response:
    """After a form: htmx gets the refreshed fragment, a plain browser a redirect to the
    page the form was on, which says it once."""
    if htmx(request):
        shown = card_context(live.view)
        return render(request, fragment, caller, "tasks", stale=stale, **shown)
    return outcomes.done(request, same_origin_path(request), "Done.")


async def tap(
    request: Request, caller: Caller, live: LiveStation, done: Awaitable[object], too_late: str
) -> Response:
    """Carry out a card's tap.  One that raced a change (the card was done on another device,
    the step is no longer needed: a 409 or 404) gets, from htmx, the fresh card and
    `too_late` in the card area rather than an error; a plain form keeps the error."""
    try:
        await done
    except (StationError, HTTPException) as exc:
        status = exc.status_code if isinstance(exc, HTTPException) else 409
        if not htmx(request) or status not in (404, 409):
            raise
        if status == 404:
            too_late = "This step is no longer needed."
        return back(request, caller, live, "_tasks.html", stale=too_late)
    return back(request, caller, live, "_tasks.html")


@router.get("/")
def tasks(request: Request, caller: OptionalCaller, live: LiveDep) -> Response:
    if caller is None:
        return RedirectResponse("/login", status_code=303)
    if caller.role == Role.AUDITOR:
        return RedirectResponse("/audit", status_code=303)
    return render(request, "tasks.html", caller, "tasks", **card_context(live.view))


@router.get("/fragments/tasks")
async def tasks_fragment(request: Request, caller: TasksCaller, live: LiveDep) -> Response:
    """The card, re-fetched when the cards change and, while there is none, (throttled) when
    the station does, for what it is doing.  A page that already shows this very card and
    activity (`seen`, the digest it got last; see app.web.pages' `live_fragment`) is
    answered 204, so a card does not flicker under a finger."""
    shown = card_context(live.view)
    if request.query_params.get("seen") == shown["digest"]:
        return Response(status_code=204)
    return render(request, "_tasks.html", caller, "tasks", **shown)


@router.post("/tasks/done")
async def card_done(
    request: Request,
    caller: TasksCaller,
    live: LiveDep,
    card: Annotated[str, Form(max_length=CARD_CHARS)],
) -> Response:

    async def done() -> None:
        # False: another device's tap was taken first, in this very round too
        if not await answer(live.confirm_card(caller.name, card)):
            raise StationError(f"card '{card}' was confirmed already, on another device")

    return await tap(request, caller, live, done(), "Already done on another device.")


@router.post("/tasks/maintenance")
async def maintenance_done(
    request: Request,
    caller: TasksCaller,
    live: LiveDep,
    transition: Annotated[str, Form(max_length=NAME_CHARS)],
) -> Response:
    async def done() -> None:
        maintenance_step(live, transition)
        await perform(live, MaintenanceDone(user=caller.name, transition=transition))

    return await tap(request, caller, live, done(), "This step is no longer needed.")


@router.post("/tasks/approve")
async def approve(
    request: Request,
    caller: TasksCaller,
    live: LiveDep,
    step: Annotated[int, Form(ge=0, le=MAX_STEP)],
    decision: Annotated[Decision, Form()] = "approve",
) -> Response:
    action = step_decision(caller.name, step, decision)
    return await tap(
        request, caller, live, perform(live, action), "Already decided on another device."
    )


@router.post("/tasks/approve-plan")
async def approve_plan(
    request: Request,
    caller: TasksCaller,
    live: LiveDep,
    steps: Annotated[list[StepName], Form(max_length=MAX_PLAN_STEPS)],
    decision: Annotated[Decision, Form()] = "approve",
) -> Response:
    """The recovery plan approved or rejected in one decision, its steps as the card showed
    them (a plan that changed since is refused: the fresh card comes back)."""
    action = plan_decision(caller.name, tuple(steps), decision)
    return await tap(
        request, caller, live, perform(live, action), "The plan changed or was decided meanwhile."
    )


@router.get("/today")
def today(request: Request, caller: OptionalCaller, live: LiveDep, store: StoreDep) -> Response:
    """The operator's "done today" (app.history.done_today)."""
    if caller is None:
        return RedirectResponse("/login?next=/today", status_code=303)
    if caller.role == Role.AUDITOR:
        return RedirectResponse("/audit", status_code=303)
    model = live.view.model
    found = done_today(store, live.name, caller.name, model.station, model.words, time())
    return render(request, "today.html", caller, "today", today=found)
