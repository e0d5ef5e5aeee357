"""Checking the sealed rows before the station uses them (and for `sp audit verify`).

Each row of the sealed tables (app.store.row_seals) must match its seal and must not be older
than the station last wrote it (its counter at least the one in the newest signed checkpoint);
a row the checkpoint names must still be there unless the station deletes such rows itself.
A model version's text must also match its hash, and the station's snapshot must follow the
audit record it names: that record has the hash it saw, and no runner event was recorded after
it (the runner's events and its snapshot are committed together, so an event after it means
the snapshot is older than the log).

Rows are read raw (untyped SQL), so that a value of the wrong type is seen as stored.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import bindparam, text

from app.store.db import Store
from app.store.keys import StationKeys
from app.store.row_seals import STATIONS, TABLES, VERSIONS, SealedTable, values_of
from app.store.tables import ModelVersion
from planner.runner import EventKind

RUNNER_KINDS = tuple(kind.value for kind in EventKind)


@dataclass(frozen=True)
class Finding:
    """A sealed row that cannot be trusted; `steers` when the station would act on it."""

    identity: str
    problem: str  # in plain words, naming the row
    steers: bool


@dataclass
class RowCheck:
    findings: list[Finding] = field(default_factory=list)
    seqs: dict[str, int] = field(default_factory=dict)  # the counters of the rows there are
    rows: int = 0

    @property
    def steering(self) -> list[Finding]:
        return [f for f in self.findings if f.steers]


def raw_rows(
    store: Store, table: str, columns: Sequence[str], order: str | None = None
) -> Iterator[dict[str, Any]]:
    """Raw rows, untyped: a value of the wrong type is seen as it is stored."""
    names = ", ".join(f'"{c}"' for c in columns)
    ordered = "" if order is None else f' ORDER BY "{order}"'
    with store.engine.connect() as connection:
        result = connection.execute(text(f'SELECT {names} FROM "{table}"{ordered}'))
        while batch := result.fetchmany(2000):
            for row in batch:
                yield dict(zip(columns, row, strict=True))


def check_rows(
    store: Store, keys: StationKeys, station: str, known: Mapping[str, int], active: int | None
) -> RowCheck:
    """Every sealed row against its seal and the counters the station last wrote (`known`);
    rows of `station` it acts on (its state, alarms, active version `active`) steer it."""
    check = RowCheck()
    for spec in TABLES:
        for values in raw_rows(store, spec.name, sorted({*spec.fields, "seq", "mac"})):
            check.rows += 1
            identity = spec.identity(values)
            problem = _problem(spec, keys, values, known.get(identity, 0))
            seq = values.get("seq")
            if isinstance(seq, int) and not isinstance(seq, bool):
                check.seqs[identity] = seq
            if problem:
                steers = _steers(spec, values, station, active)
                check.findings.append(Finding(identity, f"{spec.shown(values)}: {problem}", steers))
    for identity, seq in sorted(known.items()):
        owner = _spec_of(identity)
        if identity in check.seqs or owner is None or owner.deletable:
            continue
        check.findings.append(
            Finding(
                identity,
                f"{owner.name} row {identity.split(':', 1)[1]} (written {seq} times by the "
                "station) is gone: deleted outside the station",
                owner is STATIONS and identity == STATIONS.name + ":" + station,
            )
        )
    return check


def _problem(spec: SealedTable, keys: StationKeys, values: Mapping[str, Any], known: int) -> str:
    if not spec.intact(keys, values):
        return "the row does not match its seal (changed outside the station)"
    if int(values["seq"] or 0) < known:
        return (
            f"an older copy was written back (written {values['seq']} times, but the station "
            f"had written it {known} times)"
        )
    if spec is VERSIONS:
        digest = hashlib.sha256(str(values["text"]).encode()).hexdigest()
        if digest != values["sha256"]:
            return "its text does not match its hash"
    return ""


def _steers(spec: SealedTable, values: Mapping[str, Any], station: str, active: int | None) -> bool:
    if spec.name in ("stations", "alarms"):
        return bool(values.get("name", values.get("station")) == station)
    if spec is VERSIONS:
        return bool(values["id"] == active)
    return spec.name == "settings"


def _spec_of(identity: str) -> SealedTable | None:
    name = identity.split(":", 1)[0]
    return next((t for t in TABLES if t.name == name), None)


def check_snapshot(store: Store, station: str) -> str:
    """Why the station's snapshot does not follow the audit log ("" when it does)."""
    with store.engine.connect() as connection:
        row = connection.execute(
            text('SELECT "audit_id", "audit_hash", "snapshot" FROM "stations" WHERE name = :n'),
            {"n": station},
        ).first()
        if row is None or not row[2]:
            return ""
        audit_id, audit_hash = row[0], row[1]
        if not audit_id:
            return ""  # saved before snapshots named their record (sealed as they were found)
        record = connection.execute(
            text('SELECT "hash" FROM "audit" WHERE id = :i'), {"i": audit_id}
        ).first()
        if record is None or record[0] != audit_hash:
            return (
                f"the station's state names audit record {audit_id}, which is not in the log "
                "as it saw it: it does not belong to this log"
            )
        later = connection.execute(
            text(
                'SELECT "id", "kind" FROM "audit" WHERE id > :i AND station = :s '
                "AND kind IN :kinds ORDER BY id LIMIT 1"
            ).bindparams(bindparam("kinds", expanding=True)),
            {"i": audit_id, "s": station, "kinds": RUNNER_KINDS},
        ).first()
    if later is not None:
        return (
            f"the station's state is older than its audit log: record {later[0]} ({later[1]}) "
            f"was written by a later round than the one the state follows ({audit_id})"
        )
    return ""


def deletable(identity: str) -> bool:
    """Rows of this table are deleted by the station itself (a missing one is no sign)."""
    spec = _spec_of(identity)
    return spec is not None and spec.deletable


def version_problem(store: Store, row: ModelVersion) -> str:
    """Why a stored model version must not run ("" when it may): checked before activation."""
    keys, freshness = store.keys, store.freshness
    if keys is None or freshness is None:
        return ""
    values = values_of(row)
    if not VERSIONS.intact(keys, values):
        return f"model version {row.number} was changed outside the station (its seal)"
    if not freshness.fresh(VERSIONS, values):
        return f"model version {row.number} is an older copy written back outside the station"
    if hashlib.sha256(row.text.encode()).hexdigest() != row.sha256:
        return f"model version {row.number}: its text does not match its hash"
    return ""
