"""`sp store accept`: a person takes responsibility for rows changed outside the station.

A store restored from a backup older than the newest checkpoint, or repaired by hand, holds
rows the station no longer trusts, and it will not start on them.  Once a person has checked
what changed (`sp audit verify` names each row), this seals those rows again as they are, with
counters above any the station wrote, writes a signed checkpoint of them, and audits who
accepted what and why: the acceptance is itself in the sealed, checkpointed log.  It needs the
key file, so it is for whoever runs the station, not for whoever can write the database.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from app.store import audit, checkpoints, integrity
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from app.store.row_seals import BY_NAME, STATIONS, values_of

SHOWN = 50


@dataclass(frozen=True)
class Accepted:
    problems: list[str]
    checkpoint: bool  # a checkpoint of the accepted counters was written


def accept(store: Store, station: str, by: str, why: str) -> Accepted:
    """Seal the rows found changed as they are now; audited (`store.keys` must be set)."""
    keys = store.keys
    if keys is None:
        raise ValueError("accepting rows needs the station's key file")
    known = checkpoints.newest_rows(keys, station)
    check = integrity.check_rows(store, keys, station, known, None)
    snapshot = integrity.check_snapshot(store, station)
    problems = [f.problem for f in check.findings] + ([snapshot] if snapshot else [])
    if not problems:
        return Accepted([], False)
    now = time.time()
    changed = {f.identity for f in check.findings}
    if snapshot:
        changed.add(f"{STATIONS.name}:{station}")
    seqs: dict[str, int] = {}

    def reseal(session: Any) -> None:
        for identity in sorted(changed):
            table, _, key = identity.partition(":")
            spec = BY_NAME[table]
            ids = key.split("/")
            row: Any = session.get(spec.table, ids[0] if len(ids) == 1 else tuple(ids))
            if row is None:
                continue  # gone: accepting it means the checkpoints stop naming it
            row.seq = max(int(row.seq or 0), known.get(identity, 0)) + 1
            if spec is STATIONS:
                row.audit_id, row.audit_hash = audit.head(session)
            row.mac = spec.mac(keys, values_of(row))
            seqs[identity] = row.seq

    detail = {"by": by, "why": why, "problems": problems[:SHOWN], "count": len(problems)}
    entry = AuditEntry(AuditKind.AUDIT, "changed rows accepted", by, "", detail)
    audit.write(store, station, [entry], now, also=reseal)
    written = False
    if keys.checkpoints is not None:
        rows = {i: s for i, s in known.items() if i not in changed}
        rows.update(check.seqs)
        rows.update(seqs)
        for identity in changed - set(seqs):
            rows.pop(identity, None)
        count, head = checkpoints.head_of(store)
        checkpoint = checkpoints.Checkpoint(
            now, station, count, head, rows=tuple(sorted(rows.items()))
        )
        checkpoints.append_line(keys.checkpoints, checkpoint.signed(keys))
        written = True
    return Accepted(problems, written)
