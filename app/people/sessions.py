"""Signed-in sessions and API tokens, kept in the store so that they can be ended.

A browser's cookie (signed with the station's key, app.store.keys) and an API token each
carry a random secret; the store keeps only its SHA-256 (`UserSession.id`), the user, and
when it expires or was revoked.  Every request looks its session up, so signing out, a
password change and disabling a user end the sessions they should at once, wherever the
cookie or token was copied to.  A session also names its user in the signed cookie: a row
pointed at another user inside the database is refused.
"""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from enum import StrEnum

from itsdangerous import BadSignature, SignatureExpired, URLSafeTimedSerializer
from sqlalchemy import delete, or_, select
from sqlalchemy.orm import Session

from app.store.tables import User, UserSession

HOURS = 12  # how long a browser session or API token lasts
DAY = 24 * 3600.0


class SessionKind(StrEnum):
    BROWSER = "browser"
    API = "api"


def _id(secret: str) -> str:
    return hashlib.sha256(secret.encode()).hexdigest()


def open_session(
    session: Session,
    user: User,
    kind: SessionKind,
    address: str,
    now: float,
    issued_by: UserSession | None = None,
) -> str:
    """A new session for `user`; returns the secret its cookie or token carries.  A token
    `issued_by` a browser session ends with it: at its sign-out, and at its expiry at the
    latest."""
    secret = secrets.token_urlsafe(32)
    expires = now + HOURS * 3600
    if issued_by is not None:
        expires = min(expires, issued_by.expires_at)
    session.add(
        UserSession(
            id=_id(secret),
            user_id=user.id,
            kind=kind.value,
            created_at=now,
            expires_at=expires,
            address=address[:64],
            issued_by=issued_by.id if issued_by is not None else "",
        )
    )
    # sessions ended more than a day ago are of no use to anyone: keep the table small
    session.execute(
        delete(UserSession).where(
            UserSession.user_id == user.id,
            or_(UserSession.expires_at < now - DAY, UserSession.revoked_at < now - DAY),
        )
    )
    return secret


@dataclass(frozen=True)
class Found:
    user: User
    row: UserSession


def find(session: Session, secret: str, user_id: int, now: float) -> Found | None:
    """The live session for `secret` of user `user_id`, or None (unknown, expired, revoked,
    or another user's)."""
    row = session.get(UserSession, _id(secret))
    if row is None or row.revoked_at is not None or row.expires_at <= now:
        return None
    if row.user_id != user_id:
        return None
    user = session.get(User, row.user_id)
    return None if user is None else Found(user, row)


def revoke(session: Session, secret: str, why: str, now: float) -> int:
    """End the session of `secret` and the API tokens it issued; returns how many tokens."""
    row = session.get(UserSession, _id(secret))
    if row is not None and row.revoked_at is None:
        row.revoked_at, row.revoked_why = now, why
    if row is None:
        return 0
    tokens = session.scalars(
        select(UserSession).where(UserSession.issued_by == row.id, UserSession.revoked_at.is_(None))
    ).all()
    for token in tokens:  # row by row: each is sealed again as it is written
        token.revoked_at, token.revoked_why = now, f"its session {why}"[:64]
    return len(tokens)


@dataclass(frozen=True)
class Token:
    """A live API token as its user sees it: never its secret, a handle to revoke it by."""

    handle: str  # the start of the row's id (the SHA-256 of the secret)
    issued_at: float
    expires_at: float
    address: str
    from_session: str  # "this session", "another session", or "" (issued for a password)


HANDLE_CHARS = 16


def tokens_of(session: Session, user_id: int, now: float, current: str = "") -> list[Token]:
    """The user's live API tokens, newest first; `current` is the secret of the browser
    session asking (its tokens are said to be from this session)."""
    rows = session.scalars(
        select(UserSession)
        .where(UserSession.user_id == user_id, UserSession.kind == SessionKind.API.value)
        .where(UserSession.revoked_at.is_(None), UserSession.expires_at > now)
        .order_by(UserSession.created_at.desc())
    ).all()
    mine = _id(current) if current else ""

    def source(row: UserSession) -> str:
        if not row.issued_by:
            return ""
        return "this session" if row.issued_by == mine else "another session"

    return [
        Token(r.id[:HANDLE_CHARS], r.created_at, r.expires_at, r.address, source(r)) for r in rows
    ]


def revoke_token(session: Session, user_id: int, handle: str, why: str, now: float) -> bool:
    """End the user's own live API token of `handle`; False if they have no such token."""
    if len(handle) != HANDLE_CHARS or not all(c in "0123456789abcdef" for c in handle):
        return False
    rows = session.scalars(
        select(UserSession)
        .where(UserSession.user_id == user_id, UserSession.kind == SessionKind.API.value)
        .where(UserSession.id.startswith(handle), UserSession.revoked_at.is_(None))
        .where(UserSession.expires_at > now)
    ).all()
    if len(rows) != 1:
        return False
    rows[0].revoked_at, rows[0].revoked_why = now, why
    return True


def revoke_all(session: Session, user_id: int, why: str, now: float) -> int:
    """End every live session and token of a user; returns how many.  (Row by row, not one
    UPDATE: each row is sealed again as it is written, app.store.row_seals.)"""
    rows = session.scalars(
        select(UserSession)
        .where(UserSession.user_id == user_id, UserSession.revoked_at.is_(None))
        .where(UserSession.expires_at > now)
    ).all()
    for row in rows:
        row.revoked_at, row.revoked_why = now, why
    return len(rows)


class ApiTokens:
    """Bearer tokens for line systems (MES): a signed (user, secret) pair whose session row
    says whether it still holds."""

    def __init__(self, key: str) -> None:
        self.serializer = URLSafeTimedSerializer(key, salt="sequence-planner api token")

    def issue(self, user: User, secret: str) -> str:
        return self.serializer.dumps({"user": user.id, "secret": secret})

    def read(self, token: str) -> tuple[int, str] | None:
        """The (user id, secret) a token carries, if it is ours and not older than its life."""
        try:
            data = self.serializer.loads(token, max_age=HOURS * 3600)
        except (BadSignature, SignatureExpired):
            return None
        if not isinstance(data, dict):
            return None
        user, secret = data.get("user"), data.get("secret")
        if not isinstance(user, int) or not isinstance(secret, str):
            return None
        return user, secret
