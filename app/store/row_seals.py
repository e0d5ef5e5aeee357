"""Seals on every row that steers the station, with a version counter for freshness.

Whoever can write the database file could otherwise change what the station acts on: the
model it runs, the recovery plan in its snapshot, an alarm's shelving, a revoked session.
Each such row carries `seq`, a counter raised on every write, and `mac`, an HMAC under the
station's key (app.store.keys) of its fields and its counter.  A row changed outside the
station no longer matches its seal; an older sealed copy written back matches, but its
counter is lower than the one the station last wrote (`Freshness`, kept in memory while the
station runs and in the signed checkpoints between runs, app.store.checkpoints).

Every sealed row written through the store's sessions is sealed as it is flushed
(`install`); a row found changed outside the station is never sealed again by an ordinary
change (`Tampered`), so tampering cannot be laundered by the next legitimate edit.  The
users' seals from before counters (`seq` 0) keep their old text.
"""

from __future__ import annotations

import hmac
import json
import threading
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Boolean, Float, Integer, event, func, inspect, select
from sqlalchemy.orm import Session, sessionmaker

from app.store.keys import StationKeys
from app.store.tables import (
    AlarmRecord,
    Base,
    ModelVersion,
    Setting,
    StationRecord,
    User,
    UserSession,
)


class Tampered(RuntimeError):
    """A sealed row changed (or put back) outside the station was about to be sealed again."""


@dataclass(frozen=True)
class SealedTable:
    """A table whose rows are sealed: the fields the seal covers, in order."""

    table: type[Base]
    label: str  # the HMAC label (app.store.keys): a seal of one table is no seal of another
    fields: tuple[str, ...]
    what: str  # a row, for people, from its fields as text: "user '{name}'"
    urgent: bool  # a change is checkpointed at once (people's rights), not with the period
    deletable: bool  # the station deletes rows of it (a missing row is no tampering)
    # a field that, once set, ends the row for good (a session revoked): a changed row may
    # still be ended (sealed again as ended: harmless), never changed otherwise
    ends: str = ""
    # fields added to a sealed table later: sealed (with their name) only when not empty, so
    # that the rows sealed before them keep their seals
    later: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return str(self.table.__tablename__)

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(str(c.name) for c in inspect(self.table).primary_key)

    def identity(self, values: Mapping[str, Any]) -> str:
        """The row's name in the freshness map and in checkpoints: table:key[/key]."""
        return self.name + ":" + "/".join(str(values[k]) for k in self.keys)

    def shown(self, values: Mapping[str, Any]) -> str:
        """The row in people's words (from whatever its fields hold)."""
        return self.what.format(**{k: str(v)[:80] for k, v in values.items()})

    def text(self, values: Mapping[str, Any]) -> str:
        """What the seal covers; TypeError or ValueError for a value of the wrong type."""
        columns = self.table.__table__.columns
        fields = [
            _canonical(columns[f].type, values[f]) for f in self.fields if f not in self.later
        ]
        for f in self.later:
            if values[f] not in ("", None):
                fields.append([f, _canonical(columns[f].type, values[f])])
        seq = values.get("seq") or 0
        if not isinstance(seq, int) or isinstance(seq, bool) or seq < 0:
            raise TypeError("the counter is not a number")
        if self.table is not User or seq:  # a user sealed before counters has none
            fields.append(seq)
        return json.dumps(fields, separators=(",", ":"), ensure_ascii=True)

    def mac(self, keys: StationKeys, values: Mapping[str, Any]) -> str:
        return keys.mac(self.label, self.text(values))

    def intact(self, keys: StationKeys, values: Mapping[str, Any]) -> bool:
        """Was this row last written by the station? (False for a value of the wrong type.)"""
        try:
            expected = self.mac(keys, values)
        except (TypeError, ValueError, KeyError):
            return False
        return hmac.compare_digest(str(values.get("mac") or ""), expected)


def _canonical(kind: object, value: Any) -> Any:
    """A value as its column's type says, strictly: text in a number column is no number."""
    if value is None:
        return None
    if isinstance(kind, Boolean):
        if isinstance(value, bool) or (isinstance(value, int) and value in (0, 1)):
            return bool(value)
        raise TypeError("not a flag")
    if isinstance(kind, Float):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TypeError("not a number")
        return repr(float(value))
    if isinstance(kind, Integer):
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError("not a whole number")
        return value
    if not isinstance(value, str):
        raise TypeError("not text")
    return value


USERS = SealedTable(
    User,
    "user rows",
    ("id", "name", "role", "password_hash", "must_change_password", "disabled", "created_at"),
    "user '{name}'",
    urgent=True,
    deletable=False,
)
SESSIONS = SealedTable(
    UserSession,
    "session rows",
    (
        "id",
        "user_id",
        "kind",
        "created_at",
        "expires_at",
        "revoked_at",
        "revoked_why",
        "address",
        "issued_by",
    ),
    "the session or API token {id:.12}...",
    urgent=True,
    deletable=True,  # sessions ended a day ago are deleted
    ends="revoked_at",
    later=("issued_by",),  # a token's browser session: it ends with it (migration 0004)
)
VERSIONS = SealedTable(
    ModelVersion,
    "model versions",
    ("id", "station", "number", "text", "sha256", "author", "note", "created_at"),
    "model version {number} of {station}",
    urgent=True,
    deletable=False,
)
STATIONS = SealedTable(
    StationRecord,
    "station rows",
    ("name", "active_version_id", "snapshot", "world", "updated_at", "audit_id", "audit_hash"),
    "the state of station {name}",
    urgent=False,  # written every round that changed something: checkpointed with the period
    deletable=False,
)
ALARMS = SealedTable(
    AlarmRecord,
    "alarm rows",
    ("station", "key", "data", "updated_at"),
    "alarm '{key}' of station {station}",
    urgent=False,
    deletable=False,
)
SETTINGS = SealedTable(Setting, "settings", ("key", "value"), "setting '{key}'", True, False)

TABLES = (USERS, SESSIONS, VERSIONS, STATIONS, ALARMS, SETTINGS)
BY_CLASS: dict[type[Base], SealedTable] = {t.table: t for t in TABLES}
BY_NAME = {t.name: t for t in TABLES}


def values_of(row: Base) -> dict[str, Any]:
    spec = BY_CLASS[type(row)]
    return {f: getattr(row, f) for f in (*spec.fields, "seq", "mac")}


def row_intact(keys: StationKeys, row: Base) -> bool:
    return BY_CLASS[type(row)].intact(keys, values_of(row))


class Freshness:
    """The counter the station last wrote for each sealed row (table:key -> seq).

    Raised after each commit (never before: a transaction that rolls back wrote nothing), read
    by the checks and written into each checkpoint; `generation` grows with every change so
    that the checkpointer knows when there is something new, and `urgent` is set by a change
    to people's rights, to be checkpointed at once.
    """

    def __init__(self, known: Mapping[str, int] | None = None) -> None:
        self._seqs: dict[str, int] = dict(known or {})
        self._lock = threading.Lock()
        self.generation = 0
        self.urgent = threading.Event()

    def known(self, identity: str) -> int:
        with self._lock:
            return self._seqs.get(identity, 0)

    def fresh(self, spec: SealedTable, values: Mapping[str, Any]) -> bool:
        """Not older than the station last wrote it (an older sealed copy written back)."""
        seq = values.get("seq") or 0
        return isinstance(seq, int) and seq >= self.known(spec.identity(values))

    def raise_to(self, seen: Iterable[tuple[str, int]], *, urgent: bool = False) -> None:
        with self._lock:
            for identity, seq in seen:
                if seq > self._seqs.get(identity, 0):
                    self._seqs[identity] = seq
            self.generation += 1
        if urgent:
            self.urgent.set()

    def forget(self, identities: Iterable[str]) -> None:
        with self._lock:
            for identity in identities:
                self._seqs.pop(identity, None)
            self.generation += 1

    def snapshot(self) -> tuple[int, dict[str, int]]:
        with self._lock:
            return self.generation, dict(self._seqs)


def trusted(keys: StationKeys, freshness: Freshness, row: Base) -> bool:
    """Sealed by the station, and not older than it last wrote it."""
    spec = BY_CLASS[type(row)]
    values = values_of(row)
    return spec.intact(keys, values) and freshness.fresh(spec, values)


def _committed(row: Base, field: str) -> Any:
    history = inspect(row).attrs[field].history
    return history.deleted[0] if history.deleted else getattr(row, field)


def _committed_values(spec: SealedTable, row: Base) -> dict[str, Any]:
    return {f: _committed(row, f) for f in (*spec.fields, "seq", "mac")}


PENDING = "sealed rows"


def install(sessions: sessionmaker[Session], keys: StationKeys, freshness: Freshness) -> None:
    """Seal every sealed row these sessions write; raise the counters once committed."""

    def seal(session: Session, _context: object, _instances: object) -> None:
        pending = session.info.setdefault(PENDING, [])
        for row in [r for r in session.dirty if type(r) in BY_CLASS]:
            if not session.is_modified(row):
                continue
            spec = BY_CLASS[type(row)]
            before = _committed_values(spec, row)
            trusted = spec.intact(keys, before) and freshness.fresh(spec, before)
            ending = bool(spec.ends) and getattr(row, spec.ends) is not None
            if not trusted and not ending:
                raise Tampered(
                    f"{spec.shown(before)} was changed outside the station; "
                    "it is not sealed again (restore it from a backup, or `sp store accept`)"
                )
            seq = before["seq"] if isinstance(before["seq"], int) else 0
            _seal(spec, row, keys, max(seq, freshness.known(spec.identity(before))) + 1, pending)
        new = [r for r in session.new if type(r) in BY_CLASS]
        _give_ids(session, new)
        for row in new:
            spec = BY_CLASS[type(row)]
            identity = spec.identity(values_of(row))
            _seal(spec, row, keys, max(row.seq or 0, freshness.known(identity)) + 1, pending)
        for row in [r for r in session.deleted if type(r) in BY_CLASS]:
            pending.append((BY_CLASS[type(row)], BY_CLASS[type(row)].identity(values_of(row)), -1))

    def committed(session: Session) -> None:
        pending = session.info.pop(PENDING, [])
        if not pending:
            return
        kept = [(identity, seq) for _, identity, seq in pending if seq >= 0]
        gone = [identity for _, identity, seq in pending if seq < 0]
        urgent = any(spec.urgent for spec, _, _ in pending)
        freshness.raise_to(kept, urgent=urgent)
        if gone:
            freshness.forget(gone)

    def rolled_back(session: Session) -> None:
        session.info.pop(PENDING, None)

    event.listen(sessions, "before_flush", seal)
    event.listen(sessions, "after_commit", committed)
    event.listen(sessions, "after_soft_rollback", lambda session, _previous: rolled_back(session))


def _seal(spec: SealedTable, row: Any, keys: StationKeys, seq: int, pending: list[Any]) -> None:
    columns = spec.table.__table__.columns
    for name in spec.fields:  # defaults are given at the INSERT, after this: give them now
        default = columns[name].default
        if getattr(row, name) is None and default is not None and default.is_scalar:
            setattr(row, name, default.arg)
    row.seq = seq
    values = values_of(row)
    row.mac = spec.mac(keys, values)
    pending.append((spec, spec.identity(values), seq))


def _give_ids(session: Session, new: list[Base]) -> None:
    """Integer ids are given here, before sealing: the id is sealed too."""
    tables: tuple[Any, ...] = (User, ModelVersion)
    for table in tables:
        rows: list[Any] = [r for r in new if isinstance(r, table) and r.id is None]
        if not rows:
            continue
        with session.no_autoflush:
            next_id = (session.scalar(select(func.max(table.id))) or 0) + 1
        for row in rows:
            row.id, next_id = next_id, next_id + 1


def seal_rows(session: Session, keys: StationKeys, spec: SealedTable) -> list[tuple[str, int]]:
    """Seal the rows of a table nothing was sealed in yet (a new key, or a table newly
    sealed by this version); returns their names and counters."""
    sealed = []
    rows: list[Any] = list(session.scalars(select(spec.table)))
    for row in rows:
        seq = max(int(row.seq or 0), 1 if spec.table is not User else 0)
        row.seq = seq
        row.mac = spec.mac(keys, values_of(row))
        sealed.append((spec.identity(values_of(row)), seq))
    return sealed
