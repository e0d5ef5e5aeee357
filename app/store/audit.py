"""The append-only audit log: every event that matters, with a sealed hash chain.

Each record's hash covers its id, its fields and the hash of the record before it, so a
changed, inserted or removed record breaks the chain from that point on; its seal (an HMAC
of the hash under the station's key, app.store.seals) makes a chain recomputed by someone
without the key show (`sp audit verify`, app.store.verification).  There is deliberately no
update or delete function here; the database refuses both as well.

All writes of a process go through `write`: it holds the store's audit lock from choosing
the next id until the commit, so writers never race for an id; another process writing the
same database (a shared PostgreSQL) loses such a race at its commit and tries again.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, TypeVar

from sqlalchemy import Select, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.store.db import Store
from app.store.keys import StationKeys
from app.store.seals import record_mac
from app.store.tables import AuditRecord
from planner.runner.vocabulary import EventKind

T = TypeVar("T")
ATTEMPTS = 5  # commits lost to another process's writer before giving up

GENESIS = "0" * 64
PAGE_SIZE = 100
# the stored columns (the hash covers them), then the record in the screen's words
CSV_COLUMNS = (
    "id",
    "time",
    "station",
    "user",
    "kind",
    "subject",
    "resource",
    "detail",
    "hash",
    "in words",
)


class AuditKind(StrEnum):
    """The kinds of the records that are not the runner's events (`EventKind`): what people
    and the station process itself do.  A record's kind is one of the two enums."""

    ALARM = "alarm"  # an alarm changed state (the book's change, or a person's answer)
    AUDIT = "audit"  # the log itself: a checkpoint, a verification
    ERROR = "error"  # the station process failed in a round
    EXPERIMENT = "experiment"  # an engineer played an experiment (the station put back)
    LOGIN = "login"  # a sign-in, a token, a sign-out
    MODEL = "model"  # a model version saved or activated
    USER = "user"  # a user added, changed, disabled; a tampered row


RecordKind = EventKind | AuditKind


def record_kind(text: str) -> RecordKind | None:
    """The kind a stored record's text names (None for a kind this code does not know)."""
    for kinds in (EventKind, AuditKind):
        try:
            return kinds(text)
        except ValueError:
            continue
    return None


@dataclass(frozen=True)
class AuditEntry:
    """What is to be recorded; the id, previous hash and hash are added on append."""

    kind: RecordKind
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
    session: Session,
    station: str,
    entries: Sequence[AuditEntry],
    now: float,
    keys: StationKeys | None,
) -> list[AuditRecord]:
    """Add `entries` after the newest record, in the caller's transaction (use `write`,
    which holds the audit lock around it).  Ids are given here (the newest + 1) so that
    they are part of the hash."""
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
            user=entry.user[:64],
            kind=entry.kind,
            subject=subject,
            resource=entry.resource,
            detail=detail,
            previous=previous,
            hash=digest,
            mac=record_mac(keys, digest) if keys is not None else "",
        )
        session.add(record)
        records.append(record)
        next_id, previous = next_id + 1, digest
    return records


def head(session: Session) -> tuple[int, str]:
    last = session.execute(
        select(AuditRecord.id, AuditRecord.hash).order_by(AuditRecord.id.desc()).limit(1)
    ).first()
    return (int(last[0]), str(last[1])) if last is not None else (0, "")


def write(
    store: Store,
    station: str,
    entries: Sequence[AuditEntry] | Callable[[T], Sequence[AuditEntry]],
    now: float,
    also: Callable[[Session], T] | None = None,
    after: Callable[[Session, tuple[int, str]], None] | None = None,
) -> T | None:
    """One transaction: `also(session)` (the change the entries record, if any), then the
    entries (or what `entries` makes of also's result), then `after(session, head)` with the
    log's newest (id, hash) as it will be committed, all committed together.  An exception
    from `also` rolls both back and propagates."""
    for attempt in range(ATTEMPTS):
        try:
            with store.audit_lock, store.sessions.begin() as session:
                result = also(session) if also is not None else None
                made = entries(result) if callable(entries) else entries  # type: ignore[arg-type]
                appended = append(session, station, made, now, store.keys) if made else []
                if after is not None:
                    newest = appended[-1] if appended else None
                    after(session, (newest.id, newest.hash) if newest else head(session))
            return result
        except IntegrityError:
            store.audit_conflicts += 1
            if attempt == ATTEMPTS - 1:
                raise
    return None


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


def csv_lines(
    session: Session,
    where: AuditFilter,
    batch: int = 1000,
    said: Callable[[AuditRecord], str] = lambda record: "",
) -> Iterator[str]:
    """The filtered log as CSV, oldest first, streamed in batches; `said` is a record in
    people's words (the last column, outside the hash)."""
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
            text = (r.station, r.user, r.kind, r.subject, r.resource, r.detail)
            words = spreadsheet_safe(said(r))
            writer.writerow([r.id, _iso(r.time), *map(spreadsheet_safe, text), r.hash, words])
        last_id = rows[-1].id


FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def spreadsheet_safe(cell: str) -> str:
    """A cell a spreadsheet will not run as a formula: one that could start one (a user name
    such as `=HYPERLINK(...)`) gets a leading apostrophe, as OWASP advises for CSV."""
    return "'" + cell if cell.startswith(FORMULA_STARTS) else cell


def _iso(time: float) -> str:
    from datetime import UTC, datetime

    return datetime.fromtimestamp(time, UTC).isoformat(timespec="milliseconds")
