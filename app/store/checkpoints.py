"""Signed checkpoints of the audit log's head and of the sealed rows' counters, written
outside the database.

Seals show a record that was changed or forged, but not the newest records deleted all
together: what remains is a valid, shorter chain.  Nor do they show an older sealed copy of a
row written back.  So the station writes, every `period` seconds while the log or the sealed
rows change (at once after a change to people's rights, and when it stops), a checkpoint
(time, count, newest hash, and each sealed row's counter), signed with its key, as a line of
the checkpoints file beside the key file and into its log.  `sp audit verify` then finds a
log shorter than a checkpoint saw, one whose record at a checkpoint's count no longer has the
hash the checkpoint saw (history rewritten up to there), and rows older than it saw them;
the station, when it starts, does the same for the rows (app.store.integrity).
"""

from __future__ import annotations

import hmac
import json
import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from sqlalchemy import select

from app.store.db import Store
from app.store.keys import StationKeys
from app.store.tables import AuditRecord

log = logging.getLogger(__name__)
LABEL = "audit checkpoints"
PERIOD = 60.0
URGENT_POLL = 0.5  # how often the thread looks for stopping while it waits for a change


@dataclass(frozen=True)
class Checkpoint:
    time: float
    station: str
    count: int  # records in the log (ids run 1..count)
    head: str  # the hash of record `count`
    mac: str = ""
    rows: tuple[tuple[str, int], ...] = ()  # each sealed row's counter (app.store.row_seals)

    def text(self) -> str:
        fields: list[object] = [self.time, self.station, self.count, self.head]
        if self.rows:  # checkpoints from before sealed rows had none
            fields.append([list(row) for row in self.rows])
        return json.dumps(fields, separators=(",", ":"))

    def signed(self, keys: StationKeys) -> Checkpoint:
        return replace(self, mac=keys.mac(LABEL, self.text()))

    def valid(self, keys: StationKeys) -> bool:
        return hmac.compare_digest(self.mac, keys.mac(LABEL, self.text()))


def head_of(store: Store) -> tuple[int, str]:
    """The log's newest id and hash ((0, "") when it is empty)."""
    with store.sessions() as session:
        row = session.execute(
            select(AuditRecord.id, AuditRecord.hash).order_by(AuditRecord.id.desc()).limit(1)
        ).first()
    return (int(row[0]), str(row[1])) if row is not None else (0, "")


def append_line(path: Path, checkpoint: Checkpoint) -> None:
    """One JSON line, flushed to disk before returning."""
    data: dict[str, object] = {
        "time": checkpoint.time,
        "station": checkpoint.station,
        "count": checkpoint.count,
        "head": checkpoint.head,
        "mac": checkpoint.mac,
    }
    if checkpoint.rows:
        data["rows"] = dict(checkpoint.rows)
    line = json.dumps(data, separators=(",", ":")) + "\n"
    descriptor = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
    try:
        os.write(descriptor, line.encode())
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def read_lines(path: Path) -> tuple[list[tuple[int, Checkpoint]], list[str]]:
    """The checkpoints with their line numbers, and the lines that are not checkpoints."""
    found: list[tuple[int, Checkpoint]] = []
    damaged: list[str] = []
    with path.open("rb") as file:
        for number, raw in enumerate(file, 1):
            try:
                data = json.loads(raw)
                checkpoint = Checkpoint(
                    float(data["time"]),
                    str(data["station"]),
                    int(data["count"]),
                    str(data["head"]),
                    str(data["mac"]),
                    tuple((str(k), int(v)) for k, v in data.get("rows", {}).items()),
                )
            except (ValueError, KeyError, TypeError, AttributeError):
                damaged.append(f"line {number} of the checkpoints file is not a checkpoint")
                continue
            found.append((number, checkpoint))
    return found, damaged


def newest_rows(keys: StationKeys, station: str) -> dict[str, int]:
    """The sealed rows' counters in the newest valid checkpoint of `station` ({} if none)."""
    path = keys.checkpoints
    if path is None or not path.exists():
        return {}
    found, _damaged = read_lines(path)
    for _line, checkpoint in reversed(found):
        if checkpoint.station == station and checkpoint.valid(keys):
            return dict(checkpoint.rows)
    return {}


class Checkpointer:
    """Writes a checkpoint when the log or the sealed rows changed, at most every `period`
    seconds (at once after an urgent change), in a thread of its own (nothing of it runs in
    the station loop)."""

    def __init__(
        self,
        store: Store,
        station: str,
        *,
        period: float = PERIOD,
        clock: Callable[[], float] = time.time,
    ) -> None:
        if store.keys is None or store.keys.checkpoints is None:
            raise ValueError("checkpoints need the store's keys from a key file (seal_store)")
        self.store, self.keys, self.path = store, store.keys, store.keys.checkpoints
        self.station, self.period, self.clock = station, period, clock
        self.written: tuple[int, str, int] = (-1, "", -1)
        self.stopping = threading.Event()
        self.thread: threading.Thread | None = None

    def checkpoint(self) -> Checkpoint | None:
        """A checkpoint of the head and the rows now, unless the last one saw the same."""
        freshness = self.store.freshness
        generation, rows = freshness.snapshot() if freshness is not None else (0, {})
        count, head = head_of(self.store)
        if (count, head, generation) == self.written:
            return None
        seen = tuple(sorted(rows.items()))
        checkpoint = Checkpoint(self.clock(), self.station, count, head, rows=seen)
        checkpoint = checkpoint.signed(self.keys)
        append_line(self.path, checkpoint)
        self.written = (count, head, generation)
        log.info(
            "audit checkpoint: %d records, newest hash %s, signed %s", count, head, checkpoint.mac
        )
        return checkpoint

    def start(self) -> None:
        self.checkpoint()
        self.thread = threading.Thread(target=self._run, name="audit-checkpoints", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        freshness = self.store.freshness
        urgent = freshness.urgent if freshness is not None else threading.Event()
        next_at = time.monotonic() + self.period
        while not self.stopping.is_set():
            urgent.wait(min(URGENT_POLL, max(0.0, next_at - time.monotonic())))
            now = time.monotonic()
            if self.stopping.is_set() or (now < next_at and not urgent.is_set()):
                continue
            urgent.clear()
            if now >= next_at:
                next_at = now + self.period
            try:
                self.checkpoint()
            except Exception:  # a full disk must not end the checkpoints for good
                log.exception("writing an audit checkpoint failed")

    def stop(self) -> None:
        self.stopping.set()
        if self.thread is not None:
            self.thread.join(timeout=5)
        try:
            self.checkpoint()  # the last head before the station stops
        except Exception:
            log.exception("writing the last audit checkpoint failed")
