"""A station's runs read back from its audit log: the engines it built, and what happened in
each (`app.history.runs`, `app.history.timeline`).

The runner's events (and the `run` records that say where runs begin and end) are in the
log as `app.station.records.event_entry` wrote them, with their station time in
`detail["station_time"]` and the wall time of their round in the record's `time`.  An
experiment played from the simulation panel is a record of its own (no station time): it
takes the time of the record before it.  People's records that repeat a runner's event (a
card done) carry no station time and are left out.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from sqlalchemy import select

from app.history.runs import Happening, Run, on_one_clock, runs
from app.history.timeline import KINDS
from app.store.audit import AuditKind, RecordKind, record_kind
from app.store.db import Store
from app.store.tables import AuditRecord

LIMIT = 20_000  # the newest records read: a few hours of a busy station


@dataclass(frozen=True)
class History:
    """The happenings read, on one clock, and the runs found in them, oldest first."""

    happenings: tuple[Happening, ...]
    runs: tuple[Run, ...]

    def run(self, first: int | None) -> Run | None:
        """The run that starts at record `first`; by default the newest."""
        if first is None:
            return self.runs[-1] if self.runs else None
        return next((r for r in self.runs if r.first == first), None)


def happenings(
    store: Store, station: str, limit: int = LIMIT, kinds: frozenset[RecordKind] = KINDS
) -> list[Happening]:
    """The station's newest `limit` records of `kinds` (those a timeline reads), oldest
    first, on one clock."""
    query = (
        select(AuditRecord)
        .where(AuditRecord.station == station, AuditRecord.kind.in_(sorted(kinds)))
        .order_by(AuditRecord.id.desc())
        .limit(limit)
    )
    with store.sessions() as session:
        rows = list(reversed(session.scalars(query).all()))
        found: list[Happening] = []
        last = 0.0
        for row in rows:
            kind = record_kind(row.kind)
            detail = json.loads(row.detail or "{}")
            time = detail.pop("station_time", None)
            if kind is None or (time is None and kind is not AuditKind.EXPERIMENT):
                continue
            last = last if time is None else float(time)
            found.append(
                Happening(last, kind, row.subject, detail, row.user, row.resource, row.id, row.time)
            )
    return on_one_clock(found)


def run_history(store: Store, station: str, limit: int = LIMIT) -> History:
    found = happenings(store, station, limit)
    return History(tuple(found), tuple(runs(found)))
