"""Opening a store's keys at start-up (see app.store.seals and app.store.keys)."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.store import audit, seals
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from app.store.keys import StationKeys
from app.store.tables import AuditRecord


def seal_store(store: Store, key_path: Path | None, station: str, now: float) -> StationKeys:
    """The store's keys on `store.keys`, its user rows sealed from now on.

    A key made just now (a new store, or one from before seals) seals the users there are
    and writes a first sealed record, which covers the older chain: from then on none of it
    can be rewritten unseen.
    """
    keys, made = seals.open_keys(store.sessions, key_path)
    store.keys = keys
    if made:

        def seal(session: Session) -> list[str]:
            return seals.seal_existing(session, keys)

        with store.sessions() as session:
            legacy = session.scalar(select(func.count()).select_from(AuditRecord)) or 0
        users = audit.write(store, station, [], now, also=seal) or []
        detail = {"users": users, "records_before": legacy, "key_file": str(key_path or "")}
        entry = AuditEntry(AuditKind.AUDIT, "sealed", "", "", detail)
        audit.write(store, station, [entry], now)
    seals.install(store.sessions, keys)
    return keys
