"""Signing in and out, and password changes (audited, throttled: app.web.sign_in).

Signing in opens a session in the store (app.people.sessions); signing out ends it and the
API tokens it issued (the account page's, app.web.routes.account), and a password change
ends every session and token of the user.  These forms check their CSRF token themselves
(`Requires` does for everything else): a form that fails is shown again with a 403, and a
sign-out without it signs nobody out.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import RedirectResponse, Response
from sqlalchemy.orm import Session

from app.people import sessions as user_sessions
from app.people.auth import MIN_PASSWORD, password_problem
from app.people.auth import hash_password as new_hash
from app.people.sessions import SessionKind
from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.store.tables import User
from app.web.deps import ServerDep, browser_session, client_address, csrf_token
from app.web.limits import NEXT_CHARS, PASSWORD_CHARS, USER_CHARS
from app.web.pages import local_path, render
from app.web.sign_in import check_password, open_session

router = APIRouter(include_in_schema=False)
Password = Annotated[str, Form(max_length=PASSWORD_CHARS)]
FormToken = Annotated[str, Form(alias="csrf_token")]


def _login_page(
    request: Request, error: str = "", status_code: int = 200, **extra: Any
) -> Response:
    return render(
        request,
        "login.html",
        None,
        "login",
        status_code=status_code,
        error=error,
        min_password=MIN_PASSWORD,
        **extra,
    )


@router.get("/login")
def login_form(request: Request, next: str = "/") -> Response:
    return _login_page(request, next=local_path(next))


@router.post("/login")
def login(
    request: Request,
    srv: ServerDep,
    name: Annotated[str, Form(max_length=USER_CHARS)],
    password: Password,
    csrf_token_field: FormToken = "",
    next: Annotated[str, Form(max_length=NEXT_CHARS)] = "/",
) -> Response:
    name = name.strip()
    if csrf_token_field != request.session.get("csrf"):
        return _login_page(
            request, "the sign-in form expired; try again", 403, next=next, name=name
        )
    try:
        user = check_password(srv, client_address(request), name, password)
    except HTTPException as exc:
        return _login_page(request, str(exc.detail), exc.status_code, next=next, name=name)
    secret = open_session(srv, user, SessionKind.BROWSER, client_address(request))
    request.session.clear()  # a new session: nothing of the signed-out one is carried over
    request.session.update(sid=secret, uid=user.id)
    csrf_token(request)
    if user.must_change_password:
        return RedirectResponse("/password", status_code=303)
    return RedirectResponse(local_path(next), status_code=303)


@router.post("/logout")
def logout(request: Request, srv: ServerDep, csrf_token_field: FormToken = "") -> Response:
    found = browser_session(request)
    if found is not None and csrf_token_field == request.session.get("csrf"):
        secret = str(request.session.get("sid"))

        def end(session: Session) -> int:
            # the API tokens this session issued end with it (app.people.sessions)
            return user_sessions.revoke(session, secret, "signed out", srv.live.wall())

        def entries(tokens: int | None) -> list[AuditEntry]:
            detail = {"tokens_ended": tokens} if tokens else {}
            return [AuditEntry(AuditKind.LOGIN, "signed out", found.user.name, "", detail)]

        audit.write(srv.store, srv.live.name, entries, srv.live.wall(), also=end)
        request.session.clear()
    return RedirectResponse("/login", status_code=303)


@router.get("/password")
def password_form(request: Request) -> Response:
    found = browser_session(request)
    if found is None:
        return RedirectResponse("/login", status_code=303)
    return _login_page(request, must_change=True, first=found.user.must_change_password)


@router.post("/password")
def change_password(
    request: Request,
    srv: ServerDep,
    current_password: Password,
    new_password: Password,
    repeat: Password,
    csrf_token_field: FormToken = "",
) -> Response:
    """The user's own password: the current one is asked for (a cookie alone is not enough),
    and every session and token of the user ends; this browser gets a new session."""
    found = browser_session(request)
    if found is None:
        return RedirectResponse("/login", status_code=303)
    first = found.user.must_change_password

    def again(problem: str, status: int) -> Response:
        return _login_page(request, problem, status, must_change=True, first=first)

    if csrf_token_field != request.session.get("csrf"):
        return again("the form expired; try again", 403)
    try:
        user = check_password(srv, client_address(request), found.user.name, current_password)
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
