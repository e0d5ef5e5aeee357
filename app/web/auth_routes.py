"""Signing in and out, password changes, and API tokens (audited, throttled).

A sign-in reserves an attempt with the throttle (app.people.throttle) before its password is
checked, checks an unknown name against a dummy hash (the answer takes as long either way),
and holds no database connection while argon2 works or while the audit record is written,
so that a crowd of failed sign-ins can neither exhaust the connection pool nor stall anyone
else's request.  Signing in opens a session in the store (app.people.sessions); signing out
ends it, and a password change ends every session and token of the user.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import RedirectResponse, Response
from pydantic import BaseModel, Field
from sqlalchemy.orm import Session

from app.people import sessions as user_sessions
from app.people.auth import dummy_hash, password_matches, password_problem, user_named
from app.people.auth import hash_password as new_hash
from app.people.sessions import SessionKind
from app.people.throttle import Refused
from app.store import audit
from app.store.audit import AuditEntry, AuditKind, RecordKind
from app.store.tables import User
from app.web.deps import (
    browser_session,
    client_address,
    csrf_token,
    page_context,
    server,
    trusted_user,
)
from app.web.schemas import Invalid, Message
from app.web.server import Server

router = APIRouter()
CHECK_WAIT = 10.0  # seconds a sign-in waits for a free password check before "busy"


def _audit(srv: Server, kind: RecordKind, subject: str, user: str, **detail: object) -> None:
    entry = AuditEntry(kind, subject, user, "", detail)
    audit.write(srv.store, srv.live.name, [entry], srv.live.wall())


def _login_page(request: Request, error: str = "", status: int = 200, **extra: object) -> Response:
    srv = server(request)
    context = page_context(request, None, "login", error=error, **extra)
    response: Response = srv.templates.TemplateResponse(
        request, "login.html", context, status_code=status
    )
    return response


@router.get("/login", include_in_schema=False)
def login_form(request: Request, next: str = "/") -> Response:
    return _login_page(request, next=_safe_next(next))


def _safe_next(target: str) -> str:
    return target if target.startswith("/") and not target.startswith(("//", "/\\")) else "/"


def check_password(request: Request, name: str, password: str) -> User:
    """The user whose password this is, or an HTTPException: 401 (wrong, unknown, disabled
    or tampered: the same answer), 429 (throttled), 503 (too many checks at once)."""
    srv = server(request)
    address = client_address(request)
    attempt = srv.throttle.begin(name, address)
    if isinstance(attempt, Refused):
        if attempt.audit:
            _audit(
                srv, AuditKind.LOGIN, "throttled", name[:64], address=address, **_unaudited(attempt)
            )
        raise HTTPException(
            429, f"too many failed sign-ins; try again in {int(attempt.wait) + 1} s"
        )
    user, why = None, "unknown user"
    try:
        with srv.store.sessions() as session:
            found = user_named(session, name)
            if found is not None:
                session.expunge(found)
        stored = found.password_hash if found is not None else dummy_hash()
        if not srv.password_checks.acquire(timeout=CHECK_WAIT):
            raise HTTPException(503, "the station is busy checking sign-ins; try again")
        try:
            matches = password_matches(str(stored), password)
        finally:
            srv.password_checks.release()
        if found is not None:
            why = "wrong password" if not matches else ""
            if matches and not trusted_user(srv, found):
                why = "disabled" if found.disabled else "row changed outside the station"
        user = found if found is not None and not why else None
    finally:
        srv.throttle.end(attempt, user is not None)
    if user is None:
        _audit(srv, AuditKind.LOGIN, "failed", name[:64], address=address, why=why)
        raise HTTPException(401, "wrong user name or password")
    return user


def _unaudited(refused: Refused) -> dict[str, int]:
    return {"not_audited_since": refused.unaudited} if refused.unaudited else {}


def _open(srv: Server, user: User, kind: SessionKind, address: str) -> str:
    def opened(session: Session) -> str:
        return user_sessions.open_session(session, user, kind, address, srv.live.wall())

    entry = AuditEntry(
        AuditKind.LOGIN,
        "signed in" if kind is SessionKind.BROWSER else "api token",
        user.name,
        "",
        {"role": user.role, "address": address},
    )
    return audit.write(srv.store, srv.live.name, [entry], srv.live.wall(), also=opened) or ""


@router.post("/login", include_in_schema=False)
def login(
    request: Request,
    name: Annotated[str, Form(max_length=64)],
    password: Annotated[str, Form(max_length=200)],
    csrf_token_field: Annotated[str, Form(alias="csrf_token")] = "",
    next: Annotated[str, Form(max_length=2000)] = "/",
) -> Response:
    srv = server(request)
    name = name.strip()
    if csrf_token_field != request.session.get("csrf"):
        return _login_page(
            request, "the sign-in form expired; try again", 403, next=next, name=name
        )
    try:
        user = check_password(request, name, password)
    except HTTPException as exc:
        return _login_page(request, str(exc.detail), exc.status_code, next=next, name=name)
    secret = _open(srv, user, SessionKind.BROWSER, client_address(request))
    request.session.clear()  # a new session: nothing of the signed-out one is carried over
    request.session.update(sid=secret, uid=user.id)
    csrf_token(request)
    if user.must_change_password:
        return RedirectResponse("/password", status_code=303)
    return RedirectResponse(_safe_next(next), status_code=303)


@router.post("/logout", include_in_schema=False)
def logout(
    request: Request, csrf_token_field: Annotated[str, Form(alias="csrf_token")] = ""
) -> Response:
    srv = server(request)
    found = browser_session(request)
    if found is not None and csrf_token_field == request.session.get("csrf"):
        secret = str(request.session.get("sid"))

        def end(session: Session) -> None:
            user_sessions.revoke(session, secret, "signed out", srv.live.wall())

        entry = AuditEntry(AuditKind.LOGIN, "signed out", found.user.name)
        audit.write(srv.store, srv.live.name, [entry], srv.live.wall(), also=end)
        request.session.clear()
    return RedirectResponse("/login", status_code=303)


@router.get("/password", include_in_schema=False)
def password_form(request: Request) -> Response:
    found = browser_session(request)
    if found is None:
        return RedirectResponse("/login", status_code=303)
    return _login_page(request, must_change=True, first=found.user.must_change_password)


@router.post("/password", include_in_schema=False)
def change_password(
    request: Request,
    current_password: Annotated[str, Form(max_length=200)],
    new_password: Annotated[str, Form(max_length=200)],
    repeat: Annotated[str, Form(max_length=200)],
    csrf_token_field: Annotated[str, Form(alias="csrf_token")] = "",
) -> Response:
    """The user's own password: the current one is asked for (a cookie alone is not enough),
    and every session and token of the user ends; this browser gets a new session."""
    srv = server(request)
    found = browser_session(request)
    if found is None:
        return RedirectResponse("/login", status_code=303)
    first = found.user.must_change_password

    def again(problem: str, status: int) -> Response:
        return _login_page(request, problem, status, must_change=True, first=first)

    if csrf_token_field != request.session.get("csrf"):
        return again("the form expired; try again", 403)
    try:
        user = check_password(request, found.user.name, current_password)
    except HTTPException as exc:
        message = "the current password is wrong" if exc.status_code == 401 else str(exc.detail)
        return again(message, exc.status_code)
    problem = password_problem(user.name, new_password)
    if not problem and new_password != repeat:
        problem = "the two passwords differ"
    if not problem and new_password == current_password:
        problem = "choose a password other than the current one"
    if problem:
        return again(problem, 422)
    now = srv.live.wall()
    detail: dict[str, object] = {}

    def change(session: Session) -> str:
        row = session.get(User, user.id)
        assert row is not None
        row.password_hash = new_hash(new_password)
        row.must_change_password = False
        ended = user_sessions.revoke_all(session, user.id, "password changed", now)
        secret = user_sessions.open_session(
            session, row, SessionKind.BROWSER, client_address(request), now
        )
        detail["sessions_ended"] = ended
        return secret

    entry = AuditEntry(AuditKind.LOGIN, "password changed", user.name, "", detail)
    secret = audit.write(srv.store, srv.live.name, [entry], now, also=change) or ""
    request.session.clear()
    request.session.update(sid=secret, uid=user.id)
    csrf_token(request)
    return RedirectResponse("/", status_code=303)


class TokenRequest(BaseModel):
    name: str = Field(min_length=1, max_length=64)
    password: str = Field(min_length=1, max_length=200)


class TokenAnswer(BaseModel):
    token: str
    token_type: str = "bearer"
    role: str


@router.post(
    "/api/token",
    tags=["auth"],
    responses={
        400: {"model": Message, "description": "the body is not JSON"},
        401: {"model": Message, "description": "wrong user name or password"},
        403: {"model": Message, "description": "the first-login password is not changed yet"},
        422: {"model": Invalid, "description": "a field is missing or too long"},
        429: {"model": Message, "description": "too many failed sign-ins"},
        503: {"model": Message, "description": "too many sign-ins being checked at once"},
    },
)
def api_token(request: Request, body: TokenRequest) -> TokenAnswer:
    """A bearer token for line systems (MES): valid 12 hours; void when the password changes
    or the user is disabled."""
    srv = server(request)
    user = check_password(request, body.name.strip(), body.password)
    if user.must_change_password:
        raise HTTPException(403, "change the first-login password in the browser first")
    secret = _open(srv, user, SessionKind.API, client_address(request))
    return TokenAnswer(token=srv.tokens.issue(user, secret), role=user.role)
