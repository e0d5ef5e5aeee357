"""Model versions: every saved text is a new version; one is active per station."""

from __future__ import annotations

import hashlib
import time

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.store.tables import ModelVersion, StationRecord
from planner.reading import load_station


def versions(session: Session, station: str) -> list[ModelVersion]:
    query = select(ModelVersion).where(ModelVersion.station == station)
    return list(session.scalars(query.order_by(ModelVersion.number.desc())))


def newest(session: Session, station: str) -> ModelVersion | None:
    query = select(ModelVersion).where(ModelVersion.station == station)
    return session.scalars(query.order_by(ModelVersion.number.desc()).limit(1)).first()


def version(session: Session, station: str, number: int) -> ModelVersion | None:
    query = select(ModelVersion).where(
        ModelVersion.station == station, ModelVersion.number == number
    )
    return session.scalars(query).first()


def active(session: Session, station: str) -> ModelVersion | None:
    record = session.get(StationRecord, station)
    if record is None or record.active_version_id is None:
        return None
    return session.get(ModelVersion, record.active_version_id)


def add(session: Session, station: str, text: str, author: str, note: str = "") -> ModelVersion:
    """Save `text` as the next version (the caller validated it); returns the new row."""
    newest = session.scalar(
        select(func.max(ModelVersion.number)).where(ModelVersion.station == station)
    )
    row = ModelVersion(
        station=station,
        number=(newest or 0) + 1,
        text=text,
        sha256=hashlib.sha256(text.encode()).hexdigest(),
        author=author,
        note=note,
        created_at=time.time(),
    )
    session.add(row)
    session.flush()
    return row


def ensure_active(session: Session, station: str, text: str, author: str) -> ModelVersion:
    """The station's active version; on first start, `text` (the model file) becomes version 1."""
    current = active(session, station)
    if current is not None:
        return current
    load_station(text, "the model file")  # refuse to start on a broken model
    row = add(session, station, text, author, "imported from the model file")
    record = session.get(StationRecord, station)
    if record is None:
        session.add(
            StationRecord(
                name=station,
                active_version_id=row.id,
                snapshot="",
                world="",
                updated_at=time.time(),
            )
        )
    else:
        record.active_version_id = row.id
    return row
