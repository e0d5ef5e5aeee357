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


def open_session(session: Session, user: User, kind: SessionKind, address: str, now: float) -> str:
    """A new session for `user`; returns the secret its cookie or token carries."""
    secret = secrets.token_urlsafe(32)
    session.add(
        UserSession(
            id=_id(secret),
            user_id=user.id,
            kind=kind.value,
            created_at=now,
            expires_at=now + HOURS * 3600,
            address=address[:64],
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


def revoke(session: Session, secret: str, why: str, now: float) -> None:
    row = session.get(UserSession, _id(secret))
    if row is not None and row.revoked_at is None:
        row.revoked_at, row.revoked_why = now, why


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
