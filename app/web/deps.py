"""FastAPI dependencies: the server, the current user and their permissions, CSRF checks.

Pages and API routes share them: a browser session (signed cookie) or, for line systems, a
bearer token.  Unsafe methods from a browser session must carry the session's CSRF token,
as a form field `csrf_token` or an `X-CSRF-Token` header; bearer requests need none (no
cookie a third-party page could ride on).
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

from fastapi import HTTPException, Request

from app.auth import Permission, allowed, new_csrf_token, same_token
from app.station_view import StationView
from app.store.tables import User
from app.web.server import Server

SAFE_METHODS = ("GET", "HEAD", "OPTIONS")


class LoginRequired(Exception):
    """A page needs a signed-in user: redirect to /login (the API answers 401 instead)."""


class PasswordChangeRequired(Exception):
    """A first-login password must be changed before anything else."""


def server(request: Request) -> Server:
    found: Server = request.app.state.server
    return found


@dataclass(frozen=True)
class Caller:
    """The signed-in user, as handlers see them (no ORM object escapes the session)."""

    id: int
    name: str
    role: str
    bearer: bool = False


def csrf_token(request: Request) -> str:
    token = request.session.get("csrf")
    if not token:
        token = new_csrf_token()
        request.session["csrf"] = token
    return str(token)


def is_api(request: Request) -> bool:
    return request.url.path.startswith("/api")


def current_caller(request: Request) -> Caller | None:
    srv = server(request)
    header = request.headers.get("authorization", "")
    if header.lower().startswith("bearer "):
        with srv.store.sessions() as session:
            user = srv.tokens.user(session, header[7:].strip())
            if user is None:
                raise HTTPException(401, "the bearer token is invalid or expired; get a new one")
            return Caller(user.id, user.name, user.role, bearer=True)
    uid = request.session.get("uid")
    if uid is None:
        return None
    with srv.store.sessions() as session:
        user = session.get(User, uid)
        if user is None or user.disabled:
            request.session.clear()
            return None
        if user.must_change_password:
            raise PasswordChangeRequired()
        return Caller(user.id, user.name, user.role)


async def check_csrf(request: Request, caller: Caller) -> None:
    if request.method in SAFE_METHODS or caller.bearer:
        return
    expected = request.session.get("csrf")
    given = request.headers.get("x-csrf-token")
    if not given and "form" in request.headers.get("content-type", ""):
        form = await request.form()
        value = form.get("csrf_token")
        given = value if isinstance(value, str) else None
    if not same_token(expected, given):
        raise HTTPException(403, "the form has expired or did not come from this station; reload")


def require(*permissions: Permission) -> Callable[[Request], Awaitable[Caller]]:
    """A dependency: the caller, who must be signed in and hold one of `permissions`."""

    async def dependency(request: Request) -> Caller:
        caller = current_caller(request)
        if caller is None:
            if is_api(request):
                raise HTTPException(401, "sign in first: POST /api/token, then send a bearer token")
            raise LoginRequired()
        if not any(allowed(caller.role, p) for p in permissions):
            needs = " or ".join(f"'{p}'" for p in permissions)
            raise HTTPException(403, f"a {caller.role} may not do this (needs {needs})")
        await check_csrf(request, caller)
        return caller

    return dependency


def alarm_badge(view: StationView) -> tuple[int, str]:
    """Alarms waiting for a person (unacknowledged, active or returned), and the highest
    priority among them ("" if none)."""
    waiting = [a for a in view.alarms if "unacknowledged" in str(a.state)]
    if not waiting:
        return 0, ""
    return len(waiting), str(min(waiting, key=lambda a: a.priority.rank).priority)


def page_context(
    request: Request, caller: Caller | None, page: str, **extra: Any
) -> dict[str, Any]:
    """What every template gets (see templates/base.html)."""
    srv = server(request)
    view = srv.live.view
    alarm_count, alarm_priority = alarm_badge(view)
    return {
        "request": request,
        "user": caller,
        "csrf_token": csrf_token(request),
        "station_name": srv.live.name,
        "alarm_count": alarm_count,
        "alarm_priority": alarm_priority,
        "simulated": view.simulated,
        "on_emulators": srv.live.on_emulators,
        "page": page,
        "view": view,
        **extra,
    }
