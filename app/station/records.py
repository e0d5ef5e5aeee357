"""What the live station writes to its store, and reads back when it starts again.

A round's audit records, the alarms that changed and the runner's snapshot (with the
simulated devices' state) go into the store in one transaction, so that what a person was
told has happened is on disk.  Audit records name the resource an event concerns, for the
auditor's filter.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.station.alarms import Alarm, AlarmBook, AlarmChange, AlarmState, Priority
from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from app.store.tables import AlarmRecord, StationRecord
from planner.runner import Event, Runner

# snapshot fields that change every round and are rebased on restore: not a change to save
CLOCK_FIELDS = ("heard", "effect_since", "next_recheck")


@dataclass(frozen=True)
class Saved:
    """A station's last committed round: the runner's snapshot, the devices' state, alarms."""

    snapshot: dict[str, Any] | None
    world: dict[str, Any] | None
    alarms: AlarmBook


def restore(store: Store, station: str) -> Saved:
    with store.sessions() as session:
        record = session.get(StationRecord, station)
        rows = session.scalars(select(AlarmRecord).where(AlarmRecord.station == station)).all()
        book = AlarmBook(alarm_from_json(row.data) for row in rows)
    if record is None or not record.snapshot:
        return Saved(None, None, book)
    world = json.loads(record.world) if record.world else None
    return Saved(json.loads(record.snapshot), world, book)


def commit(
    store: Store,
    station: str,
    version_id: int,
    round_: RoundRecord,
    book: AlarmBook,
    wall: float,
) -> None:
    """One round into the store, in one transaction (the audit writer's)."""

    def save(session: Session) -> None:
        record = session.get(StationRecord, station)
        if record is None:
            record = StationRecord(name=station, active_version_id=version_id)
            session.add(record)
        record.active_version_id = version_id  # a version activated this round, or as before
        record.snapshot = round_.snapshot
        record.world = round_.world
        record.updated_at = wall
        if round_.alarms_changed:
            for alarm in book.alarms(include_normal=True, include_shelved=True):
                row = session.get(AlarmRecord, (station, alarm.key))
                data = alarm_to_json(alarm)
                if row is None:
                    session.add(
                        AlarmRecord(station=station, key=alarm.key, data=data, updated_at=wall)
                    )
                elif row.data != data:
                    row.data, row.updated_at = data, wall

    def follows(session: Session, head: tuple[int, str]) -> None:
        record = session.get(StationRecord, station)
        if record is not None:  # the snapshot names the record it follows (app.store.integrity)
            record.audit_id, record.audit_hash = head

    audit.write(store, station, round_.entries, wall, also=save, after=follows)


@dataclass(frozen=True)
class RoundRecord:
    """What one round writes: audit entries, the snapshot and devices' state as JSON text."""

    entries: list[AuditEntry]
    snapshot: str
    world: str
    alarms_changed: bool


def without_clock(snapshot: dict[str, Any]) -> str:
    """The snapshot without its clock fields: equal text means nothing worth saving changed."""
    data = {k: v for k, v in snapshot.items() if k not in CLOCK_FIELDS}
    return json.dumps(data, sort_keys=True)


def event_entry(runner: Runner, event: Event) -> AuditEntry:
    detail = event.as_json()
    detail.pop("kind", None)
    detail.pop("subject", None)
    detail["station_time"] = detail.pop("time", round(event.time, 3))
    user = str(event.detail.get("user", ""))
    return AuditEntry(event.kind, event.subject, user, resource_of(runner, event), detail)


def resource_of(runner: Runner, event: Event) -> str:
    """The resource an event concerns, for the auditor's filter ("" if none or several): the
    resource itself, the owner of the transition or variable it is about (an approval's, a
    maintenance step's)."""
    station, subject = runner.station, event.subject
    if subject in runner.index.resource_transitions:
        return subject
    variable = str(event.detail.get("variable", ""))
    # a person's decision or step: the resource of the step it is about; a whole recovery
    # plan decided at once: its steps' resources, when they are one
    transition = str(event.detail.get("transition", ""))
    planned = event.detail.get("transitions")
    owners = {station.owner_of(str(n)) for n in planned} if isinstance(planned, list) else set()
    plan_owner = owners.pop() if len(owners) == 1 else ""
    return (
        station.owner_of(subject)
        or station.owner_of(variable)
        or station.owner_of(transition)
        or plan_owner
    )


def alarm_entry(change: AlarmChange) -> AuditEntry:
    alarm = change.alarm
    detail: dict[str, Any] = {
        "before": None if change.before is None else str(change.before),
        "after": str(change.after),
        "priority": str(alarm.priority),
        "message": alarm.message,
    }
    if alarm.consequences:
        detail["consequences"] = list(alarm.consequences)
    if change.note:
        detail["note"] = change.note
    return AuditEntry(AuditKind.ALARM, change.key, change.user or "", alarm.resource, detail)


def alarm_to_json(alarm: Alarm) -> str:
    return json.dumps(asdict(alarm), sort_keys=True, default=str)


def alarm_from_json(text: str) -> Alarm:
    data = json.loads(text)
    data["priority"] = Priority(data["priority"])
    data["state"] = AlarmState(data["state"])
    if data.get("shelved_state") is not None:
        data["shelved_state"] = AlarmState(data["shelved_state"])
    data["consequences"] = tuple(data.get("consequences", ()))
    data["grouped"] = tuple(data.get("grouped", ()))
    return Alarm(**data)


def audit_committed(store: Store, station: str, entries: list[AuditEntry], wall: float) -> None:
    """Audit records in a transaction of their own (when a round could not commit)."""
    audit.write(store, station, entries, wall)
