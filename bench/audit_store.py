"""Audit write throughput on SQLite (WAL, synchronous=FULL), as the station writes it.

    python -m bench.audit_store [--records 5000]

Appends records through `app.store.audit.write` (hash chain and seals included) in transactions of
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
from app.store.sealing import seal_store
from app.store.verification import verify
from bench.planning import machine


def run(records: int, batch: int, directory: Path) -> tuple[float, float, float]:
    path = directory / f"audit-{batch}.db"
    store = open_store(sqlite_url(path))
    store.upgrade()
    seal_store(store, path.with_name(path.name + ".key"), "bench", time.time())
    entry = AuditEntry(
        "effect", "r1.goto.arrive", "", "r1", {"station_time": 12.3, "type": "effect"}
    )
    times = []
    started = time.perf_counter()
    for _ in range(records // batch):
        begin = time.perf_counter()
        audit.write(store, "bench", [entry] * batch, time.time())
        times.append(time.perf_counter() - begin)
    total = time.perf_counter() - started
    check = verify(store, store.keys)
    assert check.records == records // batch * batch + 1  # and the seal's own record
    assert not [p for p in check.problems if "checkpoints" not in p], check.problems
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
