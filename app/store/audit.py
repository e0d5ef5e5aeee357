"""The append-only audit log: every event that matters, with a hash chain.

Each record's hash covers its id, its fields and the hash of the record before it, so a
changed, inserted or removed record breaks the chain from that point on (`sp audit verify`).
There is deliberately no update or delete function here; the database refuses both as well.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import Select, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.store.tables import AuditRecord

GENESIS = "0" * 64
PAGE_SIZE = 100
CSV_COLUMNS = ("id", "time", "station", "user", "kind", "subject", "resource", "detail", "hash")


@dataclass(frozen=True)
class AuditEntry:
    """What is to be recorded; the id, previous hash and hash are added on append."""

    kind: str
    subject: str = ""
    user: str = ""
    resource: str = ""
    detail: Mapping[str, Any] = field(default_factory=dict)


def canonical(detail: Mapping[str, Any]) -> str:
    return json.dumps(detail, sort_keys=True, separators=(",", ":"), default=str)


def record_hash(
    id: int,
    time: float,
    station: str,
    user: str,
    kind: str,
    subject: str,
    resource: str,
    detail: str,
    previous: str,
) -> str:
    fields = [id, repr(float(time)), station, user, kind, subject, resource, detail, previous]
    text = json.dumps(fields, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode()).hexdigest()


def append(
    session: Session, station: str, entries: Sequence[AuditEntry], now: float
) -> list[AuditRecord]:
    """Add `entries` after the newest record, in the caller's transaction.

    Ids are given here (the newest + 1) so that they are part of the hash; two writers that
    race for the same id collide on the primary key, and the loser's commit fails rather than
    forking the chain.
    """
    last = session.execute(
        select(AuditRecord.id, AuditRecord.hash).order_by(AuditRecord.id.desc()).limit(1)
    ).first()
    next_id, previous = (last[0] + 1, last[1]) if last is not None else (1, GENESIS)
    records = []
    for entry in entries:
        detail = canonical(entry.detail)
        subject = entry.subject[:200]
        digest = record_hash(
            next_id, now, station, entry.user, entry.kind, subject, entry.resource, detail, previous
        )
        record = AuditRecord(
            id=next_id,
            time=now,
            station=station,
            user=entry.user,
            kind=entry.kind,
            subject=subject,
            resource=entry.resource,
            detail=detail,
            previous=previous,
            hash=digest,
        )
        session.add(record)
        records.append(record)
        next_id, previous = next_id + 1, digest
    return records


def append_committed(
    sessions: Any, station: str, entries: Sequence[AuditEntry], now: float, attempts: int = 5
) -> list[AuditRecord]:
    """Append in a transaction of its own, retrying when another writer took the same id."""
    for attempt in range(attempts):
        try:
            with sessions.begin() as session:
                return append(session, station, entries, now)
        except IntegrityError:
            if attempt == attempts - 1:
                raise
    return []


@dataclass(frozen=True)
class AuditFilter:
    """What an auditor narrows the log to; empty fields do not filter."""

    since: float | None = None
    until: float | None = None
    user: str = ""
    kind: str = ""
    resource: str = ""
    station: str = ""
    text: str = ""  # in the subject

    def apply(self, query: Select[Any]) -> Select[Any]:
        if self.since is not None:
            query = query.where(AuditRecord.time >= self.since)
        if self.until is not None:
            query = query.where(AuditRecord.time <= self.until)
        if self.user:
            query = query.where(AuditRecord.user == self.user)
        if self.kind:
            query = query.where(AuditRecord.kind == self.kind)
        if self.resource:
            query = query.where(AuditRecord.resource == self.resource)
        if self.station:
            query = query.where(AuditRecord.station == self.station)
        if self.text:
            query = query.where(AuditRecord.subject.contains(self.text, autoescape=True))
        return query


@dataclass(frozen=True)
class AuditPage:
    records: list[AuditRecord]
    total: int
    page: int
    pages: int


def page_of(session: Session, where: AuditFilter, page: int = 1) -> AuditPage:
    """One page of `PAGE_SIZE` records, newest first."""
    total = session.scalar(where.apply(select(func.count()).select_from(AuditRecord))) or 0
    pages = max(1, -(-total // PAGE_SIZE))
    page = min(max(1, page), pages)
    query = where.apply(select(AuditRecord)).order_by(AuditRecord.id.desc())
    records = list(session.scalars(query.offset((page - 1) * PAGE_SIZE).limit(PAGE_SIZE)))
    return AuditPage(records, total, page, pages)


def distinct_values(session: Session, column: str) -> list[str]:
    """The users, kinds or resources present, for the filter's choices."""
    attribute = getattr(AuditRecord, column)
    return [v for v in session.scalars(select(attribute).distinct().order_by(attribute)) if v]


def csv_lines(session: Session, where: AuditFilter, batch: int = 1000) -> Iterator[str]:
    """The filtered log as CSV, oldest first, streamed in batches."""
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(CSV_COLUMNS)
    last_id = 0
    while True:
        yield out.getvalue()
        out.seek(0)
        out.truncate()
        query = where.apply(select(AuditRecord)).where(AuditRecord.id > last_id)
        rows = list(session.scalars(query.order_by(AuditRecord.id).limit(batch)))
        if not rows:
            return
        for r in rows:
            writer.writerow(
                [
                    r.id,
                    _iso(r.time),
                    r.station,
                    r.user,
                    r.kind,
                    r.subject,
                    r.resource,
                    r.detail,
                    r.hash,
                ]
            )
        last_id = rows[-1].id


def _iso(time: float) -> str:
    from datetime import UTC, datetime

    return datetime.fromtimestamp(time, UTC).isoformat(timespec="milliseconds")


@dataclass(frozen=True)
class Verification:
    count: int
    problems: list[str]
    head: str  # the newest hash: write it down to detect a cut-off tail later

    @property
    def intact(self) -> bool:
        return not self.problems


def verify(records: Iterable[AuditRecord]) -> Verification:
    """Recompute the chain over `records` in id order; name each record that does not fit."""
    previous, expected_id, count, problems = GENESIS, 1, 0, []
    for r in records:
        count += 1
        if r.id != expected_id:
            problems.append(f"record {r.id}: expected id {expected_id} (records missing)")
        if r.previous != previous:
            problems.append(f"record {r.id}: its previous hash does not match record {r.id - 1}")
        digest = record_hash(
            r.id, r.time, r.station, r.user, r.kind, r.subject, r.resource, r.detail, r.previous
        )
        if digest != r.hash:
            problems.append(f"record {r.id}: its content does not match its hash (changed)")
        previous, expected_id = r.hash, r.id + 1
    return Verification(count, problems, previous)


def all_records(session: Session, batch: int = 5000) -> Iterator[AuditRecord]:
    last_id = 0
    while True:
        query = select(AuditRecord).where(AuditRecord.id > last_id).order_by(AuditRecord.id)
        rows = list(session.scalars(query.limit(batch)))
        if not rows:
            return
        yield from rows
        session.expunge_all()
        last_id = rows[-1].id
