"""Seals: HMACs under the station's key (app.store.keys) over user rows and audit records.

A plain hash chain can be recomputed by anyone who can write the database; a seal cannot
without the key, which is not in the database.  Every user row written through the store's
sessions is sealed as it is flushed (`install`); a row whose seal does not match was changed
outside the station: it is not trusted (no sign-in, no session) and `sp audit verify` names
it.  A row found broken is never sealed again by an ordinary change, so tampering cannot be
laundered by the next legitimate edit.

`open_keys` starts a store's keys: the key file is read, or made on a store that nothing
was sealed in yet (a new store, or one from before seals), whose users are then sealed and
whose audit log gets a first sealed record covering the older chain.
"""

from __future__ import annotations

import hmac
import json
from pathlib import Path
from typing import Any

from sqlalchemy import event, func, inspect, select
from sqlalchemy.orm import Session, sessionmaker

from app.store.keys import KeyFileError, StationKeys, create_keys, ephemeral_keys, read_keys
from app.store.tables import AuditRecord, User

USERS = "user rows"
RECORDS = "audit records"


class TamperedUser(RuntimeError):
    """A user row changed outside the station was about to be sealed again."""


def _user_text(values: list[Any]) -> str:
    id_, name, role, password_hash, must_change, disabled, created_at = values
    fields = [
        id_,
        name,
        role,
        password_hash,
        bool(must_change),
        bool(disabled),
        repr(float(created_at)),
    ]
    return json.dumps(fields, separators=(",", ":"), ensure_ascii=True)


SEALED_FIELDS = ("id", "name", "role", "password_hash", "must_change_password", "disabled")


def user_mac(keys: StationKeys, user: User) -> str:
    values = [getattr(user, f) for f in SEALED_FIELDS] + [user.created_at]
    return keys.mac(USERS, _user_text(values))


def user_intact(keys: StationKeys, user: User) -> bool:
    """Was this row last written by the station? (False for any field of unexpected type.)"""
    try:
        return hmac.compare_digest(str(user.mac or ""), user_mac(keys, user))
    except (TypeError, ValueError):
        return False


def record_mac(keys: StationKeys, record_hash: str) -> str:
    """An audit record's seal: its hash covers its fields and the previous record's hash."""
    return keys.mac(RECORDS, record_hash)


def _committed(user: User, field: str) -> Any:
    history = inspect(user).attrs[field].history
    if history.deleted:
        return history.deleted[0]
    return getattr(user, field)


def _was_intact(keys: StationKeys, user: User) -> bool:
    values = [_committed(user, f) for f in SEALED_FIELDS] + [_committed(user, "created_at")]
    try:
        expected = keys.mac(USERS, _user_text(values))
    except (TypeError, ValueError):
        return False
    return hmac.compare_digest(str(_committed(user, "mac") or ""), expected)


def install(sessions: sessionmaker[Session], keys: StationKeys) -> None:
    """Seal every user row these sessions write (ids are given first: the id is sealed too)."""

    def seal(session: Session, _context: object, _instances: object) -> None:
        for user in [u for u in session.dirty if isinstance(u, User)]:
            if session.is_modified(user) and not _was_intact(keys, user):
                raise TamperedUser(
                    f"user '{user.name}' was changed outside the station; "
                    "it is not sealed again (restore the row from a backup)"
                )
            user.mac = user_mac(keys, user)
        new = [u for u in session.new if isinstance(u, User)]
        if new:
            with session.no_autoflush:
                next_id = (session.scalar(select(func.max(User.id))) or 0) + 1
            for user in new:
                if user.id is None:
                    user.id, next_id = next_id, next_id + 1
                user.mac = user_mac(keys, user)

    event.listen(sessions, "before_flush", seal)


def open_keys(sessions: sessionmaker[Session], path: Path | None) -> tuple[StationKeys, bool]:
    """The store's keys, and whether they were just made (then `seal_existing` follows)."""
    if path is None:
        return ephemeral_keys(), True
    if path.exists():
        return read_keys(path), False
    with sessions() as session:
        sealed = session.scalar(select(func.count()).select_from(User).where(User.mac != ""))
        sealed = sealed or session.scalar(
            select(func.count()).select_from(AuditRecord).where(AuditRecord.mac != "")
        )
    if sealed:
        raise KeyFileError(
            f"this store's users and audit log are sealed with a key, but there is no key "
            f"file at {path}: restore the key file (or name it with --keys FILE)"
        )
    return create_keys(path), True


def seal_existing(session: Session, keys: StationKeys) -> list[str]:
    """Seal the users of a store that had no key yet; returns their names."""
    users = list(session.scalars(select(User).order_by(User.id)))
    for user in users:
        user.mac = user_mac(keys, user)
    return [u.name for u in users]
