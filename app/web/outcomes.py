"""What a page's form answers once it is carried out or refused: POST-redirect-GET for a
plain browser, and a refusal audited as refused.

A form sent without htmx is answered 303 to the page it belongs to, whatever came of it, so
that reloading that page does not send the form again; what came of it (a message, or why
it was refused) travels in the session (signed by the station, never in the URL) and is
shown once by the next page (app.web.pages' `say` and `values_for`).  htmx requests
keep their fragments, and the API its JSON.

A refusal the handler reaches (a name that does not exist, a state that does not allow it,
a form field out of range: `REFUSALS`) is written to the audit log as "<action> refused"
with why, in the area's kind, unless it is already there: the runner records its own
refusals (`refused` events), the users page its own (`AuditedRefusal`).  Refusals at the
gate (signed out, the wrong role, no CSRF token) never reach a handler and are not audited
here.
"""

from __future__ import annotations

from fastapi import HTTPException, Request
from fastapi.responses import RedirectResponse
from starlette.concurrency import run_in_threadpool

from app.store import audit
from app.store.audit import AuditEntry, AuditKind, RecordKind
from app.web.deps import SAFE_METHODS, Caller, is_api, server
from app.web.pages import FLASH_CHARS, htmx, same_origin_path, say
from planner.runner import EventKind

# a handler's refusals (a gate's 401 and 403 are not among them)
REFUSALS = frozenset({400, 404, 409, 422, 429, 503})
# the page each area's forms are on ("/": the task cards, on more than one page)
PAGES = {
    "tasks": "/",
    "alarms": "/alarms",
    "station": "/station",
    "model": "/model",
    "simulation": "/simulation",
    "users": "/users",
    "account": "/account",
}
# the kind each area's refusals are audited as (the pages' and the API's areas); a person's
# action on the station otherwise, as the runner's own refusals are
KINDS: dict[str, RecordKind] = {
    "alarms": AuditKind.ALARM,
    "model": AuditKind.MODEL,
    "models": AuditKind.MODEL,
    "simulation": AuditKind.EXPERIMENT,
    "experiments": AuditKind.EXPERIMENT,
    "users": AuditKind.USER,
    "account": AuditKind.LOGIN,
    "tokens": AuditKind.LOGIN,
}


class AuditedRefusal(HTTPException):
    """A refusal its handler has already written to the audit log."""


def area(path: str) -> str:
    """The area of a path: its first segment past /api ("alarms" for /api/alarms/shelve)."""
    parts = [p for p in path.split("/") if p]
    if parts[:1] == ["api"]:
        parts = parts[1:]
    return parts[0] if parts else ""


def form_page(request: Request) -> str:
    """The page a form was sent from: the task cards' forms are on more than one page (the
    Referer, if it is this station's); the others on their area's page."""
    found = PAGES.get(area(request.url.path), "/")
    return same_origin_path(request) if found == "/" else found


def done(request: Request, to: str, message: str = "", error: str = "") -> RedirectResponse:
    """A form's answer for a plain browser: a 303 to `to`, which shows the outcome once."""
    if message or error:
        say(request, message, error)
    return RedirectResponse(to, status_code=303)


def record_refusal(request: Request, caller: Caller, status: int, why: str) -> None:
    """`<action> refused` with why, as the caller's, in the kind of the request's area."""
    srv = server(request)
    path = request.url.path
    kind = KINDS.get(area(path), EventKind.REFUSED)
    action = path.removeprefix("/api").strip("/").partition("/")[2] or area(path) or path
    detail = {"request": f"{request.method} {path}", "status": status, "why": why[:FLASH_CHARS]}
    entry = AuditEntry(kind, f"{action} refused", caller.name, "", detail)
    audit.write(srv.store, srv.live.name, [entry], srv.live.wall())


async def after_refusal(
    request: Request, status: int, why: str, audited: bool
) -> RedirectResponse | None:
    """A handler's refusal of an unsafe request: audited (unless `audited` already), and
    for a plain browser's form the 303 back to its page (None: answer as usual)."""
    caller = getattr(request.state, "caller", None)
    if not isinstance(caller, Caller) or request.method in SAFE_METHODS:
        return None  # refused at the gate, or a page that was only read
    if status not in REFUSALS:
        return None
    if not audited:
        await run_in_threadpool(record_refusal, request, caller, status, why)
    if is_api(request) or htmx(request):
        return None
    return done(request, form_page(request), error=why)
