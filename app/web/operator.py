"""The operator's pages: task cards (watch first), approvals, maintenance steps, alarms."""

from __future__ import annotations

from typing import Annotated, Any
from urllib.parse import urlsplit

from fastapi import APIRouter, Depends, Form, Request
from fastapi.responses import RedirectResponse, Response

from app.auth import Permission, Role
from app.views import task_cards
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


def back(request: Request, fragment: str) -> Response:
    """After a form: htmx gets the refreshed fragment, a plain browser a redirect."""
    if request.headers.get("hx-request"):
        return render(
            request,
            fragment,
            current_caller(request),
            "tasks",
            cards=task_cards(server(request).live.view),
        )
    return RedirectResponse(same_origin_path(request), status_code=303)


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
    return render(
        request, "tasks.html", caller, "tasks", cards=task_cards(server(request).live.view)
    )


@router.get("/fragments/tasks")
async def tasks_fragment(
    request: Request, caller: Annotated[Caller, Depends(require(Permission.TASKS))]
) -> Response:
    return render(
        request, "_tasks.html", caller, "tasks", cards=task_cards(server(request).live.view)
    )


@router.post("/tasks/done")
async def card_done(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    card: Annotated[str, Form(max_length=100)],
) -> Response:
    await answer(server(request).live.confirm_card(caller.name, card))
    return back(request, "_tasks.html")


@router.post("/tasks/maintenance")
async def maintenance_done(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.TASKS))],
    transition: Annotated[str, Form(max_length=200)],
) -> Response:
    live = server(request).live
    maintenance_step(live, transition)
    await perform(live, MaintenanceDone(user=caller.name, transition=transition))
    return back(request, "_tasks.html")


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
    await perform(server(request).live, action)
    return back(request, "_tasks.html")


@router.get("/alarms")
def alarms(request: Request) -> Response:
    caller = current_caller(request)
    if caller is None:
        return RedirectResponse("/login?next=/alarms", status_code=303)
    return render(request, "alarms.html", caller, "alarms", alarms=server(request).live.view.alarms)


@router.get("/fragments/alarms")
async def alarms_fragment(
    request: Request, caller: Annotated[Caller, Depends(require(Permission.ALARMS))]
) -> Response:
    return render(
        request, "_alarms.html", caller, "alarms", alarms=server(request).live.view.alarms
    )


@router.post("/alarms/acknowledge")
async def acknowledge(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.ACKNOWLEDGE))],
    key: Annotated[str, Form(max_length=200)],
    note: Annotated[str, Form(max_length=500)] = "",
) -> Response:
    await answer(server(request).live.acknowledge(key, caller.name, note.strip()))
    return _alarms_back(request, caller)


@router.post("/alarms/shelve")
async def shelve(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.ACKNOWLEDGE))],
    key: Annotated[str, Form(max_length=200)],
    minutes: Annotated[float, Form(gt=0, le=480)],
    note: Annotated[str, Form(max_length=500)] = "",
) -> Response:
    await answer(server(request).live.shelve(key, caller.name, minutes, note.strip()))
    return _alarms_back(request, caller)


@router.post("/alarms/unshelve")
async def unshelve(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.ACKNOWLEDGE))],
    key: Annotated[str, Form(max_length=200)],
) -> Response:
    await answer(server(request).live.unshelve(key, caller.name))
    return _alarms_back(request, caller)


def _alarms_back(request: Request, caller: Caller) -> Response:
    if request.headers.get("hx-request"):
        return render(
            request, "_alarms.html", caller, "alarms", alarms=server(request).live.view.alarms
        )
    return RedirectResponse("/alarms", status_code=303)
