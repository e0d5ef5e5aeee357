"""Audit write throughput on SQLite (WAL, synchronous=FULL), as the station writes it.

    python -m bench.audit_store [--records 5000]

Appends records through `app.store.audit.append` (hash chain included) in transactions of
1, 10 and 100 records — a runner round commits all of its events in one transaction — and
prints records per second and milliseconds per transaction as a Markdown table.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from app.store import audit
from app.store.audit import AuditEntry
from app.store.db import open_store, sqlite_url
from bench.planning import machine


def run(records: int, batch: int, directory: Path) -> tuple[float, float, float]:
    store = open_store(sqlite_url(directory / f"audit-{batch}.db"))
    store.upgrade()
    entry = AuditEntry(
        "effect", "r1.goto.arrive", "", "r1", {"station_time": 12.3, "type": "effect"}
    )
    times = []
    started = time.perf_counter()
    for _ in range(records // batch):
        begin = time.perf_counter()
        with store.sessions.begin() as session:
            audit.append(session, "bench", [entry] * batch, time.time())
        times.append(time.perf_counter() - begin)
    total = time.perf_counter() - started
    with store.sessions() as session:
        check = audit.verify(audit.all_records(session))
    assert check.intact and check.count == records // batch * batch
    store.close()
    times.sort()
    return records / total, statistics.median(times) * 1000, times[int(len(times) * 0.99)] * 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--records", type=int, default=5000)
    args = parser.parse_args()
    print(f"Audit writes on SQLite (WAL, synchronous=FULL); {machine()}\n")
    print("| records per transaction | records/s | ms per transaction, median | p99 |")
    print("| --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as directory:
        for batch in (1, 10, 100):
            rate, median, p99 = run(args.records, batch, Path(directory))
            print(f"| {batch} | {rate:,.0f} | {median:.2f} | {p99:.2f} |")


if __name__ == "__main__":
    main()
