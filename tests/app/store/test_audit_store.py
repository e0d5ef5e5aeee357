"""The audit log's hash chain: intact after appends, and `sp audit verify` names what an
attacker with write access to the database changed, inserted or removed.  (Forgery,
re-chaining, truncation and the users table: tests/web/test_security_audit.py.)"""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from sqlalchemy.exc import DBAPIError

from app.store import audit
from app.store.audit import AuditEntry
from app.store.checkpoints import Checkpointer
from app.store.db import Store, open_store, sqlite_url
from app.store.sealing import seal_store
from app.store.verification import verify as verify_store
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY


def sealed_store(path: Path) -> Store:
    """A store as `sp serve` opens it: migrated, its key file beside it, sealed (one record)."""
    store = open_store(sqlite_url(path))
    store.upgrade()
    seal_store(store, path.with_name(path.name + ".key"), "demo", 1_700_000_000.0)
    return store


@pytest.fixture
def db(tmp_path: Path) -> Path:
    """A sealed log of 21 records: the seal, then 20 actions."""
    path = tmp_path / "audit.db"
    store = sealed_store(path)
    for k in range(20):
        audit.write(
            store,
            "demo",
            [AuditEntry("operator", f"action {k}", "engineer", "r1", {"k": k})],
            1_700_000_000.0 + k,
        )
    Checkpointer(store, "demo").checkpoint()  # as the station does every minute
    store.close()
    return path


def verify(db: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli.main", "audit", "verify", "--db", sqlite_url(db)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )


def tamper(db: Path, *statements: str) -> None:
    """What someone with the database file could do: drop the guards, then edit."""
    with sqlite3.connect(db) as connection:
        connection.execute("DROP TRIGGER audit_no_update")
        connection.execute("DROP TRIGGER audit_no_delete")
        for statement in statements:
            connection.execute(statement)


def test_an_intact_log_verifies(db: Path) -> None:
    result = verify(db)
    assert result.returncode == 0, result.stdout
    assert "audit log intact: 21 records" in result.stdout


def test_the_database_refuses_updates_and_deletes(db: Path) -> None:
    store = open_store(sqlite_url(db))
    for statement in ("UPDATE audit SET user = 'x' WHERE id = 3", "DELETE FROM audit WHERE id = 3"):
        with pytest.raises(DBAPIError, match="append-only"), store.engine.begin() as connection:
            connection.exec_driver_sql(statement)
    store.close()


@pytest.mark.parametrize(
    ("statement", "problem"),
    [
        ("UPDATE audit SET user = 'someone else' WHERE id = 7", "record 7: its content"),
        ("UPDATE audit SET detail = '{\"k\":99}' WHERE id = 12", "record 12: its content"),
        ("DELETE FROM audit WHERE id = 5", "record 5 missing"),
        ("UPDATE audit SET time = time + 1 WHERE id = 1", "record 1: its content"),
    ],
)
def test_verify_names_the_tampered_record(db: Path, statement: str, problem: str) -> None:
    tamper(db, statement)
    result = verify(db)
    assert result.returncode == 1
    assert problem in result.stdout, result.stdout
    assert "NOT intact" in result.stdout


def test_a_rewritten_record_with_a_fresh_hash_still_breaks_the_chain(db: Path) -> None:
    """Recomputing the changed record's own hash is not enough: the next one points at
    the old hash."""
    with sqlite3.connect(db) as connection:
        row = connection.execute("SELECT * FROM audit WHERE id = 9").fetchone()
    columns = ["id", "time", "station", "user", "kind", "subject", "resource", "detail"]
    record = dict(zip(columns, row[:8], strict=True))
    forged = audit.record_hash(
        record["id"], record["time"], record["station"], "nobody", record["kind"],
        record["subject"], record["resource"], record["detail"], row[8],
    )  # fmt: skip
    tamper(db, f"UPDATE audit SET user = 'nobody', hash = '{forged}' WHERE id = 9")
    result = verify(db)
    assert result.returncode == 1
    assert "record 10: does not follow the record before it" in result.stdout


def test_appends_chain_onto_the_newest_record(tmp_path: Path) -> None:
    store = open_store(sqlite_url(tmp_path / "a.db"))
    store.upgrade()
    with store.sessions.begin() as session:
        first = audit.append(session, "s", [AuditEntry("a"), AuditEntry("b")], 1.0, None)
    with store.sessions.begin() as session:
        (third,) = audit.append(session, "s", [AuditEntry("c")], 2.0, None)
    assert [r.id for r in first] == [1, 2] and third.id == 3
    assert first[0].previous == audit.GENESIS
    assert first[1].previous == first[0].hash and third.previous == first[1].hash
    assert verify_store(store, None).intact
    store.close()
