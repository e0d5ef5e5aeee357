"""User administration (admin only): list users with their last sign-in, add one with a
first-login password, disable or enable one, reset a password, change a role.  Every change
is audited (`app.store.audit.write`, in the change's own transaction; user rows are sealed as
they are flushed, app.store.seals), and a reset or a new role ends the user's sessions: they
sign in again, to choose a password or under the new role's permissions."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Annotated, Any, NoReturn

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import RedirectResponse, Response
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.people import sessions as user_sessions
from app.people.auth import (
    ROLES,
    Role,
    add_user,
    hash_password,
    password_problem,
    user_named,
)
from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.store.seals import TamperedUser
from app.store.tables import AuditRecord, User
from app.web import outcomes
from app.web.deps import Caller, ServerDep, UserAdmin
from app.web.limits import PASSWORD_CHARS, ROLE_CHARS, USER_CHARS
from app.web.outcomes import AuditedRefusal
from app.web.pages import render
from app.web.server import Server

router = APIRouter(include_in_schema=False)
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.-]{0,63}$")
UserName = Annotated[str, Form(max_length=USER_CHARS)]
Password = Annotated[str, Form(max_length=PASSWORD_CHARS)]
RoleName = Annotated[str, Form(max_length=ROLE_CHARS)]


@dataclass(frozen=True, slots=True)
class UserRow:
    """A user as the page shows them, with their last browser sign-in (from the audit log)."""

    name: str
    role: str
    must_change: bool
    disabled: bool
    signed_in: str  # "2025-05-01 14:03 UTC", or "" if never
    address: str


def user_rows(session: Session) -> list[UserRow]:
    """Every user and their last sign-in, in one query: the newest "signed in" record per
    user name (the login records' index, `ix_audit_kind`, keeps it quick on a long log)."""
    newest = (
        select(AuditRecord.user.label("name"), func.max(AuditRecord.id).label("id"))
        .where(AuditRecord.kind == AuditKind.LOGIN, AuditRecord.subject == "signed in")
        .group_by(AuditRecord.user)
        .subquery()
    )
    query = (
        select(User, AuditRecord.time, AuditRecord.detail)
        .outerjoin(newest, newest.c.name == User.name)
        .outerjoin(AuditRecord, AuditRecord.id == newest.c.id)
        .order_by(User.name)
    )
    rows = []
    for user, time, detail in session.execute(query):
        rows.append(
            UserRow(
                user.name,
                user.role,
                user.must_change_password,
                user.disabled,
                "" if time is None else _when(time),
                _address(detail),
            )
        )
    return rows


def _when(time: float) -> str:
    """As the audit page shows times: UTC, to the minute."""
    return datetime.fromtimestamp(time, UTC).strftime("%Y-%m-%d %H:%M UTC")


def _address(detail: str | None) -> str:
    try:
        found = json.loads(detail or "{}").get("address", "")
    except (ValueError, AttributeError):  # not JSON, or not an object: nothing to show
        return ""
    return found if isinstance(found, str) else ""


def _page(
    request: Request, caller: Caller, srv: Server, status_code: int = 200, **extra: Any
) -> Response:
    with srv.store.sessions() as session:
        users = user_rows(session)
    return render(
        request,
        "users.html",
        caller,
        "users",
        status_code=status_code,
        users=users,
        roles=ROLES,
        **extra,
    )


def _done(request: Request, message: str) -> Response:
    """After a change: back to the page by a redirect (a reload does not send the form
    again), the message carried over in the session (app.web.outcomes)."""
    return outcomes.done(request, "/users", message)


def _refused(
    caller: Caller,
    srv: Server,
    what: str,
    detail: dict[str, object],
    status_code: int,
    why: str,
) -> NoReturn:
    """A change refused: audited as refused, with why (never as done); back to the page by a
    redirect too, which says why (htmx gets the error where it shows them)."""
    entry = AuditEntry(AuditKind.USER, f"{what} refused", caller.name, "", {**detail, "why": why})
    audit.write(srv.store, srv.live.name, [entry], srv.live.wall())
    raise AuditedRefusal(status_code, why)


@router.get("/users")
def users(request: Request, caller: UserAdmin, srv: ServerDep) -> Response:
    return _page(request, caller, srv)


@router.post("/users")
def add(
    request: Request,
    caller: UserAdmin,
    srv: ServerDep,
    name: UserName,
    role: RoleName,
    password: Password,
) -> Response:
    name = name.strip()
    problem = ""
    if not NAME.match(name):
        problem = "a user name starts with a letter: letters, digits, '_', '.', '-'"
    elif role not in ROLES:
        problem = f"unknown role '{role}'; use one of {', '.join(ROLES)}"
    else:
        problem = password_problem(name, password)
    detail: dict[str, object] = {"name": name, "role": role}
    if problem:
        return _refused(caller, srv, "add", detail, 422, problem)

    def added(session: Session) -> bool:
        if user_named(session, name) is not None:
            return False
        add_user(session, name, role, password, must_change=True)
        return True

    entry = AuditEntry(AuditKind.USER, "added", caller.name, "", detail)
    try:  # the record only when the row was added
        done = audit.write(
            srv.store, srv.live.name, lambda ok: [entry] if ok else [], srv.live.wall(), added
        )
    except IntegrityError:  # another station of the same database took the name just now
        done = False
    if not done:
        why = f"there is already a user '{name}'"
        return _refused(caller, srv, "add", detail, 409, why)
    return _done(request, f"Added {name} ({role}); they choose a password at first sign-in")


@router.post("/users/disable")
def disable(
    request: Request,
    caller: UserAdmin,
    srv: ServerDep,
    name: UserName,
    disabled: Annotated[bool, Form()],
) -> Response:
    subject = "disabled" if disabled else "enabled"
    if name == caller.name:
        return _refused(caller, srv, subject, {"name": name}, 409, "you cannot disable yourself")
    now = srv.live.wall()
    detail: dict[str, object] = {"name": name}

    def change(session: Session) -> None:
        user = _named(session, name)
        user.disabled = disabled
        if disabled:  # whatever they had signed in with ends now
            detail["sessions_ended"] = user_sessions.revoke_all(session, user.id, "disabled", now)

    _write(srv, AuditEntry(AuditKind.USER, subject, caller.name, "", detail), now, change)
    return _done(request, f"{name} is {subject}")


@router.post("/users/password")
def reset_password(
    request: Request,
    caller: UserAdmin,
    srv: ServerDep,
    name: UserName,
    password: Password,
) -> Response:
    """A new first-login password for someone who forgot theirs: they must change it at their
    next sign-in, and whatever they were signed in with ends now."""
    if name == caller.name:
        why = "change your own password with Change password (/password)"
        return _refused(caller, srv, "password reset", {"name": name}, 409, why)
    problem = password_problem(name, password)
    if problem:
        return _refused(caller, srv, "password reset", {"name": name}, 422, problem)
    now = srv.live.wall()
    detail: dict[str, object] = {"name": name}

    def reset(session: Session) -> None:
        user = _named(session, name)
        user.password_hash = hash_password(password)
        user.must_change_password = True
        detail["sessions_ended"] = user_sessions.revoke_all(session, user.id, "password reset", now)

    _write(srv, AuditEntry(AuditKind.USER, "password reset", caller.name, "", detail), now, reset)
    return _done(request, f"{name} has a new first-login password; they choose their own")


@router.post("/users/role")
def change_role(
    request: Request,
    caller: UserAdmin,
    srv: ServerDep,
    name: UserName,
    role: RoleName,
) -> Response:
    """Give a user another role; their sessions end, so the new role's permissions hold from
    their next sign-in.  The last enabled admin may not step down (nobody could manage the
    users any more); an admin who does step down is signed out with the rest."""
    if role not in ROLES:
        why = f"unknown role '{role}'; use one of {', '.join(ROLES)}"
        return _refused(caller, srv, "role change", {"name": name, "role": role}, 422, why)
    now = srv.live.wall()
    detail: dict[str, object] = {"name": name, "role": role}

    def change(session: Session) -> None:
        user = _named(session, name)
        if user.role == role:
            raise HTTPException(409, f"{name} is already {_article(role)} {role}")
        if user.role == Role.ADMIN and not user.disabled and _admins(session) <= 1:
            raise HTTPException(409, f"{name} is the last admin: make another user admin first")
        detail["previous"] = user.role
        user.role = role
        detail["sessions_ended"] = user_sessions.revoke_all(session, user.id, "role changed", now)

    _write(srv, AuditEntry(AuditKind.USER, "role changed", caller.name, "", detail), now, change)
    if name == caller.name:  # their own session ended with the others
        request.session.clear()
        return RedirectResponse("/login", status_code=303)
    return _done(request, f"{name} is now {_article(role)} {role}; signed out")


def _named(session: Session, name: str) -> User:
    user = user_named(session, name)
    if user is None:
        raise HTTPException(404, f"there is no user '{name}'")
    return user


def _admins(session: Session) -> int:
    """Enabled admins (a disabled one cannot sign in to manage anyone)."""
    query = select(func.count()).select_from(User)
    found = session.scalar(query.where(User.role == Role.ADMIN, User.disabled.is_(False)))
    return int(found or 0)


def _article(role: str) -> str:
    return "an" if role[:1] in "aeiou" else "a"


def _write(srv: Server, entry: AuditEntry, now: float, change: Callable[[Session], None]) -> None:
    """The change and its audit record, in one transaction; a change refused (a tampered row,
    the last admin, ...) leaves no record of it done but one of it refused, with why."""
    try:
        audit.write(srv.store, srv.live.name, [entry], now, also=change)
    except (HTTPException, TamperedUser) as exc:
        why = str(exc.detail) if isinstance(exc, HTTPException) else str(exc)
        detail = {**entry.detail, "why": why}
        refused = AuditEntry(entry.kind, f"{entry.subject} refused", entry.user, "", detail)
        audit.write(srv.store, srv.live.name, [refused], now)
        status = exc.status_code if isinstance(exc, HTTPException) else 409
        raise AuditedRefusal(status, why) from None
