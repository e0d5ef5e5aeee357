"""Checking a password and opening a session, for the sign-in form and the API's tokens
(app.web.routes.auth, app.web.api.token); audited, throttled.

A sign-in reserves an attempt with the throttle (app.people.throttle) before its password is
checked, checks an unknown name against a dummy hash (the answer takes as long either way),
and holds no database connection while argon2 works or while the audit record is written,
so that a crowd of failed sign-ins can neither exhaust the connection pool nor stall anyone
else's request.  A failure is only counted (app.people.failures): the audit log gets one
record per window and address block, written by a thread of its own.  Signing in opens a
session in the store (app.people.sessions).
"""

from __future__ import annotations

from fastapi import HTTPException
from sqlalchemy.orm import Session

from app.people import sessions as user_sessions
from app.people.auth import dummy_hash, password_matches, user_named
from app.people.sessions import SessionKind
from app.people.throttle import Refused
from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.store.tables import User
from app.web.deps import trusted_user
from app.web.limits import USER_CHARS
from app.web.server import Server

CHECK_WAIT = 10.0  # seconds a sign-in waits for a free password check before "busy"


def check_password(srv: Server, address: str, name: str, password: str) -> User:
    """The user whose password this is, or an HTTPException: 401 (wrong, unknown, disabled
    or tampered: the same answer), 429 (throttled), 503 (too many checks at once)."""
    attempt = srv.throttle.begin(name, address)
    if isinstance(attempt, Refused):  # counted, not written now: one record per window
        srv.failures.note("throttled", address, srv.live.wall(), name=name[:USER_CHARS])
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
        real = found.name if found is not None else ""  # a typed name is no user's name
        srv.failures.note("failed", address, srv.live.wall(), real, name=name, why=why)
        raise HTTPException(401, "wrong user name or password")
    return user


def open_session(srv: Server, user: User, kind: SessionKind, address: str) -> str:
    """A new session of `user` (a browser's or an API token's), audited; its secret."""

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
