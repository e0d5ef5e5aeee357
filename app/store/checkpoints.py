"""Signed checkpoints of the audit log's head, written outside the database.

Seals show a record that was changed or forged, but not the newest records deleted all
together: what remains is a valid, shorter chain.  So the station writes, every `period`
seconds while the log grows, a checkpoint (time, count, newest hash), signed with its key,
as a line of the checkpoints file beside the key file and into its log.  `sp audit verify`
then finds a log shorter than a checkpoint saw, or one whose record at a checkpoint's count
no longer has the hash the checkpoint saw (history rewritten up to there).
"""

from __future__ import annotations

import hmac
import json
import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from sqlalchemy import select

from app.store.db import Store
from app.store.keys import StationKeys
from app.store.tables import AuditRecord

log = logging.getLogger(__name__)
LABEL = "audit checkpoints"
PERIOD = 60.0


@dataclass(frozen=True)
class Checkpoint:
    time: float
    station: str
    count: int  # records in the log (ids run 1..count)
    head: str  # the hash of record `count`
    mac: str = ""

    def text(self) -> str:
        return json.dumps([self.time, self.station, self.count, self.head], separators=(",", ":"))

    def signed(self, keys: StationKeys) -> Checkpoint:
        return Checkpoint(
            self.time, self.station, self.count, self.head, keys.mac(LABEL, self.text())
        )

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
    line = json.dumps(asdict(checkpoint), separators=(",", ":")) + "\n"
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
                )
            except (ValueError, KeyError, TypeError):
                damaged.append(f"line {number} of the checkpoints file is not a checkpoint")
                continue
            found.append((number, checkpoint))
    return found, damaged


class Checkpointer:
    """Writes a checkpoint when the log has grown, at most every `period` seconds, in a
    thread of its own (nothing of it runs in the station loop)."""

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
        self.written = (-1, "")
        self.stopping = threading.Event()
        self.thread: threading.Thread | None = None

    def checkpoint(self) -> Checkpoint | None:
        """A checkpoint of the head now, unless the last one saw the same head."""
        count, head = head_of(self.store)
        if (count, head) == self.written:
            return None
        checkpoint = Checkpoint(self.clock(), self.station, count, head).signed(self.keys)
        append_line(self.path, checkpoint)
        self.written = (count, head)
        log.info(
            "audit checkpoint: %d records, newest hash %s, signed %s", count, head, checkpoint.mac
        )
        return checkpoint

    def start(self) -> None:
        self.checkpoint()
        self.thread = threading.Thread(target=self._run, name="audit-checkpoints", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stopping.wait(self.period):
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
