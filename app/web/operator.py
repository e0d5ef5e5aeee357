"""The operator's pages: task cards (watch first), approvals, maintenance steps (the alarms
are app.web.alarms)."""

from __future__ import annotations

import hashlib
from collections.abc import Awaitable
from time import time
from typing import Annotated, Any
from urllib.parse import urlsplit

from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import RedirectResponse, Response

from app.history.done_today import done_today
from app.pages.cards import station_activity, task_cards
from app.people.auth import Permission, Role
from app.station.live import StationError
from app.station.view import StationView
from app.web.actions import answer, maintenance_step, perform
from app.web.deps import Caller, current_caller, page_context, require, server
from planner.runner import Approve, MaintenanceDone, Reject

router = APIRouter(include_in_schema=False)


def render(
    request: Request, template: str, caller: Caller | None, page: str, **extra: Any
) -> Response:
    srv = server(request)
    response: Response = srv.templates.TemplateResponse(
        request, template, page_context(request, caller, page, **extra)
    )
    return response


def back(request: Request, fragment: str, stale: str = "") -> Response:
    """After a form: htmx gets the refreshed fragment, a plain browser a redirect."""
    if request.headers.get("hx-request"):
        shown = card_context(server(request).live.view)
        return render(request, fragment, current_caller(request), "tasks", stale=stale, **shown)
    return RedirectResponse(same_origin_path(request), status_code=303)


async def tap(request: Request, done: Awaitable[object], too_late: str) -> Response:
    """Carry out a card's tap.  One that raced a change (the card was done on another device,
    the step is no longer needed: a 409 or 404) gets, from htmx, the fresh card and
    `too_late` in the card area rather than an error; a plain form keeps the error."""
    try:
        await done
    except (StationError, HTTPException) as exc:
        status = exc.status_code if isinstance(exc, HTTPException) else 409
        if not request.headers.get("hx-request") or status not in (404, 409):
            raise
        if status == 404:
            too_late = "This step is no longer needed."
        return back(request, "_tasks.html", stale=too_late)
    return back(request, "_tasks.html")


def same_origin_path(request: Request) -> str:
    """Where the form was (the Referer's path and query) if that is this station, else "/":
    following the header as it came made the station an open redirect to any other site.
    (The last test is auth_routes' `_safe_next`, copied: a "//host" path leaves too.)"""
    referer, own = urlsplit(request.headers.get("referer", "")), urlsplit(str(request.url))
    try:
        theirs = (referer.scheme, referer.hostname, referer.port or _PORTS.get(referer.scheme))
        ours = (own.scheme, own.hostname, own.port or _PORTS.get(own.scheme))
    except ValueError:  # a port that is not a number
        return "/"
    if theirs != ours:
        return "/"
    target = referer.path + (f"?{referer.query}" if referer.query else "")
    return target if target.startswith("/") and not target.startswith(("//", "/\\")) else "/"


_PORTS = {"http": 80, "https": 443}


@router.get("/")
def tasks(request: Request) -> Response:
    caller = current_caller(request)
    if caller is None:
        return RedirectResponse("/login", status_code=303)
    if caller.role == Role.AUDITOR:
        return RedirectResponse("/audit", status_code=303)
    return render(request, "tasks.html", caller, "tasks", **card_context(server(request).live.view))


@router.get("/fragments/tasks")
async def tasks_fragment(
    request: Request, caller: Annotated[Caller, Depends(require(Permission.TASKS))]
) -> Response:
    """The card, re-fetched when the cards change and, while there is none, (throttled) when
    the station does, for what it is doing.  A page that already shows this very card and
    activity (`seen`, the digest it got last; see app.web.engineer's `live_fragment`) is
    answered 204, so a card does not flicker under a finger."""
    shown = card_context(server(request).live.view)
    if request.query_params.get("seen") == shown["digest"]:
        return Response(status_code=204)
    return render(request, "_tasks.html", caller, "tasks", **shown)


def card_context(view: StationView) -> dict[str, Any]:
    """What _tasks.html shows, and its digest."""
    cards, activity = task_cards(view), station_activity(view)
    digest = hashlib.blake2b(repr((cards, activity)).encode(), digest_size=8).hexdigest()
    return {"cards": cards, "station_activity": station_activity, "digest": digest}


@router.post("/tasks/done")
async def card_done(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    card: Annotated[str, Form(max_length=100)],
) -> Response:
    done = answer(server(request).live.confirm_card(caller.name, card))
    return await tap(request, done, "Already done on another device.")


@router.post("/tasks/maintenance")
async def maintenance_done(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    transition: Annotated[str, Form(max_length=200)],
) -> Response:
    live = server(request).live

    async def done() -> None:
        maintenance_step(live, transition)
        await perform(live, MaintenanceDone(user=caller.name, transition=transition))

    return await tap(request, done(), "This step is no longer needed.")


@router.post("/tasks/approve")
async def approve(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    step: Annotated[int, Form(ge=0, le=10_000)],
    decision: Annotated[str, Form(pattern="^(approve|reject)$")] = "approve",
) -> Response:
    action = (
        Approve(user=caller.name, step=step)
        if decision == "approve"
        else Reject(user=caller.name, step=step)
    )
    return await tap(
        request, perform(server(request).live, action), "Already decided on another device."
    )


@router.get("/today")
def today(request: Request) -> Response:
    """The operator's "done today" (app.history.done_today)."""
    caller = current_caller(request)
    if caller is None:
        return RedirectResponse("/login?next=/today", status_code=303)
    if caller.role == Role.AUDITOR:
        return RedirectResponse("/audit", status_code=303)
    srv = server(request)
    model = srv.live.view.model
    found = done_today(srv.store, srv.live.name, caller.name, model.station, model.words, time())
    return render(request, "today.html", caller, "today", today=found)
