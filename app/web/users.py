"""User administration (admin only): list users, add one with a first-login password,
disable or enable one.  Every change is audited."""

from __future__ import annotations

import re
from typing import Annotated

from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import Response
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app import user_sessions
from app.auth import ROLES, Permission, add_user, password_problem, user_named
from app.store import audit
from app.store.audit import AuditEntry
from app.store.seals import TamperedUser
from app.store.tables import User
from app.web.deps import Caller, page_context, require, server

router = APIRouter(include_in_schema=False)
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.-]{0,63}$")


def _page(request: Request, caller: Caller, status: int = 200, **extra: object) -> Response:
    srv = server(request)
    with srv.store.sessions() as session:
        users = [
            {"name": u.name, "role": u.role, "must_change": u.must_change_password,
             "disabled": u.disabled}
            for u in session.scalars(select(User).order_by(User.name))
        ]  # fmt: skip
    context = page_context(request, caller, "users", users=users, roles=ROLES, **extra)
    response: Response = srv.templates.TemplateResponse(
        request, "users.html", context, status_code=status
    )
    return response


@router.get("/users")
def users(
    request: Request, caller: Annotated[Caller, Depends(require(Permission.USERS))]
) -> Response:
    return _page(request, caller)


@router.post("/users")
def add(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.USERS))],
    name: Annotated[str, Form(max_length=64)],
    role: Annotated[str, Form(max_length=16)],
    password: Annotated[str, Form(max_length=200)],
) -> Response:
    srv = server(request)
    name = name.strip()
    problem = ""
    if not NAME.match(name):
        problem = "a user name starts with a letter: letters, digits, '_', '.', '-'"
    elif role not in ROLES:
        problem = f"unknown role '{role}'; use one of {', '.join(ROLES)}"
    else:
        problem = password_problem(name, password)
    if problem:
        return _page(request, caller, 422, error=problem)

    def added(session: Session) -> bool:
        if user_named(session, name) is not None:
            return False
        add_user(session, name, role, password, must_change=True)
        return True

    entry = AuditEntry("user", "added", caller.name, "", {"name": name, "role": role})
    try:
        done = audit.write(srv.store, srv.live.name, [entry], srv.live.wall(), also=added)
    except IntegrityError:  # another station of the same database took the name just now
        done = False
    if not done:
        return _page(request, caller, 409, error=f"there is already a user '{name}'")
    return _page(
        request, caller, message=f"Added {name} ({role}); they choose a password at first sign-in"
    )


@router.post("/users/disable")
def disable(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.USERS))],
    name: Annotated[str, Form(max_length=64)],
    disabled: Annotated[bool, Form()],
) -> Response:
    srv = server(request)
    if name == caller.name:
        raise HTTPException(409, "you cannot disable yourself")
    subject = "disabled" if disabled else "enabled"
    detail: dict[str, object] = {"name": name}

    def change(session: Session) -> None:
        user = user_named(session, name)
        if user is None:
            raise HTTPException(404, f"there is no user '{name}'")
        user.disabled = disabled
        if disabled:  # whatever they had signed in with ends now
            detail["sessions_ended"] = user_sessions.revoke_all(
                session, user.id, "disabled", srv.live.wall()
            )

    entry = AuditEntry("user", subject, caller.name, "", detail)
    try:
        audit.write(srv.store, srv.live.name, [entry], srv.live.wall(), also=change)
    except TamperedUser as exc:
        raise HTTPException(409, str(exc)) from None
    return _page(request, caller, message=f"{name} is {subject}")
