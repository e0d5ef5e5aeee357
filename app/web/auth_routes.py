"""Signing in and out, first-login password changes, and API tokens (audited, throttled)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import RedirectResponse, Response
from pydantic import BaseModel, Field

from app.auth import hash_password as new_hash
from app.auth import password_matches, password_problem, user_named
from app.store import audit
from app.store.audit import AuditEntry
from app.store.tables import User
from app.web.deps import csrf_token, page_context, server
from app.web.schemas import Invalid, Message
from app.web.server import Server

router = APIRouter()


def _audit(srv: Server, kind: str, subject: str, user: str, **detail: object) -> None:
    audit.append_committed(
        srv.store.sessions,
        srv.live.name,
        [AuditEntry(kind, subject, user, "", detail)],
        srv.live.wall(),
    )


def _address(request: Request) -> str:
    return request.client.host if request.client else "unknown"


def _login_page(request: Request, error: str = "", status: int = 200, **extra: object) -> Response:
    srv = server(request)
    context = page_context(request, None, "login", error=error, **extra)
    response: Response = srv.templates.TemplateResponse(
        request, "login.html", context, status_code=status
    )
    return response


@router.get("/login", include_in_schema=False)
def login_form(request: Request, next: str = "/") -> Response:
    return _login_page(request, next=next)


def _safe_next(target: str) -> str:
    return target if target.startswith("/") and not target.startswith("//") else "/"


def authenticate(request: Request, name: str, password: str) -> User:
    """The user, or an HTTPException (401, or 429 when throttled); failures are audited."""
    srv = server(request)
    address = _address(request)
    wait = srv.throttle.wait(name, address)
    if wait > 0:
        _audit(srv, "login", "throttled", name, address=address)
        raise HTTPException(429, f"too many failed sign-ins; try again in {int(wait) + 1} s")
    with srv.store.sessions() as session:
        user = user_named(session, name)
        if user is None or user.disabled or not password_matches(user.password_hash, password):
            srv.throttle.failed(name, address)
            _audit(srv, "login", "failed", name, address=address)
            raise HTTPException(401, "wrong user name or password")
        session.expunge(user)
    srv.throttle.succeeded(name)
    return user


@router.post("/login", include_in_schema=False)
def login(
    request: Request,
    name: Annotated[str, Form(max_length=64)],
    password: Annotated[str, Form(max_length=200)],
    csrf_token_field: Annotated[str, Form(alias="csrf_token")] = "",
    next: Annotated[str, Form()] = "/",
) -> Response:
    srv = server(request)
    if csrf_token_field != request.session.get("csrf"):
        return _login_page(request, "the sign-in form expired; try again", 403, next=next)
    try:
        user = authenticate(request, name.strip(), password)
    except HTTPException as exc:
        return _login_page(request, str(exc.detail), exc.status_code, next=next)
    request.session.clear()
    request.session["uid"] = user.id
    csrf_token(request)
    _audit(srv, "login", "signed in", user.name, role=user.role)
    if user.must_change_password:
        return RedirectResponse("/password", status_code=303)
    return RedirectResponse(_safe_next(next), status_code=303)


@router.post("/logout", include_in_schema=False)
def logout(
    request: Request, csrf_token_field: Annotated[str, Form(alias="csrf_token")] = ""
) -> Response:
    srv = server(request)
    uid = request.session.get("uid")
    if uid is not None and csrf_token_field == request.session.get("csrf"):
        with srv.store.sessions() as session:
            user = session.get(User, uid)
            if user is not None:
                _audit(srv, "login", "signed out", user.name)
        request.session.clear()
    return RedirectResponse("/login", status_code=303)


@router.get("/password", include_in_schema=False)
def password_form(request: Request) -> Response:
    if request.session.get("uid") is None:
        return RedirectResponse("/login", status_code=303)
    return _login_page(request, must_change=True)


@router.post("/password", include_in_schema=False)
def change_password(
    request: Request,
    new_password: Annotated[str, Form(max_length=200)],
    repeat: Annotated[str, Form(max_length=200)],
    csrf_token_field: Annotated[str, Form(alias="csrf_token")] = "",
) -> Response:
    srv = server(request)
    uid = request.session.get("uid")
    if uid is None:
        return RedirectResponse("/login", status_code=303)
    if csrf_token_field != request.session.get("csrf"):
        return _login_page(request, "the form expired; try again", 403, must_change=True)
    with srv.store.sessions.begin() as session:
        user = session.get(User, uid)
        if user is None:
            return RedirectResponse("/login", status_code=303)
        problem = password_problem(user.name, new_password)
        if not problem and new_password != repeat:
            problem = "the two passwords differ"
        if not problem and password_matches(user.password_hash, new_password):
            problem = "choose a password other than the first-login one"
        if problem:
            return _login_page(request, problem, 422, must_change=True)
        user.password_hash = new_hash(new_password)
        user.must_change_password = False
        name = user.name
    _audit(srv, "login", "password changed", name)
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
    },
)
def api_token(request: Request, body: TokenRequest) -> TokenAnswer:
    """A bearer token for line systems (MES): valid 12 hours, void when the password changes."""
    srv = server(request)
    user = authenticate(request, body.name.strip(), body.password)
    if user.must_change_password:
        raise HTTPException(403, "change the first-login password in the browser first")
    _audit(srv, "login", "api token", user.name, role=user.role)
    return TokenAnswer(token=srv.tokens.issue(user), role=user.role)
