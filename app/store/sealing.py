"""Opening a store's keys at start-up, and checking its sealed rows before the station
uses them (see app.store.seals, app.store.row_seals and app.store.integrity)."""

from __future__ import annotations

import json
from pathlib import Path

from sqlalchemy import func, select, text
from sqlalchemy.orm import Session

from app.store import audit, checkpoints, integrity, seals
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from app.store.keys import StationKeys
from app.store.row_seals import TABLES, USERS, Freshness, install, seal_rows
from app.store.tables import AuditRecord, User


def seal_store(store: Store, key_path: Path | None, station: str, now: float) -> StationKeys:
    """The store's keys on `store.keys`, its sealed rows sealed from now on.

    A key made just now (a new store, or one from before seals) seals the rows there are
    and writes a first sealed record, which covers the older chain: from then on none of it
    can be rewritten unseen.  A table this version seals for the first time is sealed as it
    is found, once (the record says so; later, an unsealed row in it is a tampered one).
    """
    keys, made = seals.open_keys(store.sessions, key_path)
    store.keys = keys
    sealed = set() if made else _sealed_tables(store)
    newly = [spec for spec in TABLES if spec.name not in sealed]
    if newly:

        def seal(session: Session) -> dict[str, object]:
            legacy = session.scalar(select(func.count()).select_from(AuditRecord)) or 0
            for spec in newly:
                seal_rows(session, keys, spec)
            detail: dict[str, object] = {
                "tables": [spec.name for spec in newly],
                "records_before": legacy,
                "key_file": str(key_path or ""),
            }
            if USERS in newly:
                detail["users"] = list(session.scalars(select(User.name).order_by(User.id)))
            return detail

        def recorded(detail: dict[str, object]) -> list[AuditEntry]:
            return [AuditEntry(AuditKind.AUDIT, "sealed", "", "", detail)]

        audit.write(store, station, recorded, now, also=seal)
    known = checkpoints.newest_rows(keys, station) if not made else {}
    store.freshness = Freshness(known)
    install(store.sessions, keys, store.freshness)
    return keys


def _sealed_tables(store: Store) -> set[str]:
    """The tables the log says were sealed (the first seals covered the users only)."""
    tables: set[str] = set()
    with store.sessions() as session:
        details = session.scalars(
            select(AuditRecord.detail).where(
                AuditRecord.kind == AuditKind.AUDIT, AuditRecord.subject == "sealed"
            )
        )
        for detail in details:
            try:
                data = json.loads(detail)
            except ValueError:
                continue
            named = data.get("tables", ["users"]) if isinstance(data, dict) else []
            tables.update(str(name) for name in named)
    return tables


def check_before_start(store: Store, station: str) -> integrity.RowCheck:
    """Every sealed row checked against its seal and the newest checkpoint; the counters of
    the rows found intact raise the store's freshness.  The findings that `steer` the
    station (its state, its alarms, its active model, the settings) must stop it."""
    keys, freshness = store.keys, store.freshness
    if keys is None or freshness is None:
        raise ValueError("check_before_start needs seal_store first")
    _generation, known = freshness.snapshot()
    with store.engine.connect() as connection:
        active = connection.execute(
            text('SELECT "active_version_id" FROM "stations" WHERE name = :n'), {"n": station}
        ).scalar()
    check = integrity.check_rows(store, keys, station, known, active)
    why = integrity.check_snapshot(store, station)
    if why:
        check.findings.append(integrity.Finding(f"stations:{station}", why, True))
    gone = [identity for identity in known if identity not in check.seqs]
    freshness.forget(i for i in gone if integrity.deletable(i))
    bad = {f.identity for f in check.findings}
    freshness.raise_to((i, s) for i, s in check.seqs.items() if i not in bad)
    return check
