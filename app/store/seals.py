"""Seals: HMACs under the station's key (app.store.keys) over audit records (and, through
app.store.row_seals, over every row that steers the station).

A plain hash chain can be recomputed by anyone who can write the database; a seal cannot
without the key, which is not in the database.

`open_keys` starts a store's keys: the key file is read, or made on a store that nothing
was sealed in yet (a new store, or one from before seals), whose rows are then sealed and
whose audit log gets a first sealed record covering the older chain.
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import func, select
from sqlalchemy.orm import Session, sessionmaker

from app.store.keys import KeyFileError, StationKeys, create_keys, ephemeral_keys, read_keys
from app.store.row_seals import TABLES, USERS, Tampered, values_of
from app.store.tables import AuditRecord, User

RECORDS = "audit records"

TamperedUser = Tampered  # the name users' pages knew it by


def user_intact(keys: StationKeys, user: User) -> bool:
    """Was this row last written by the station? (False for any field of unexpected type.)"""
    return USERS.intact(keys, values_of(user))


def record_mac(keys: StationKeys, record_hash: str) -> str:
    """An audit record's seal: its hash covers its fields and the previous record's hash."""
    return keys.mac(RECORDS, record_hash)


def open_keys(sessions: sessionmaker[Session], path: Path | None) -> tuple[StationKeys, bool]:
    """The store's keys, and whether they were just made (then `seal_existing` follows)."""
    if path is None:
        return ephemeral_keys(), True
    if path.exists():
        return read_keys(path), False
    with sessions() as session:
        sealed = session.scalar(
            select(func.count()).select_from(AuditRecord).where(AuditRecord.mac != "")
        )
        for spec in TABLES:
            column = spec.table.__table__.columns["mac"]
            sealed = sealed or session.scalar(
                select(func.count()).select_from(spec.table).where(column != "")
            )
    if sealed:
        raise KeyFileError(
            f"this store's users and audit log are sealed with a key, but there is no key "
            f"file at {path}: restore the key file (or name it with --keys FILE)"
        )
    return create_keys(path), True
