"""Issue 15, point 2: audit integrity an auditor can rely on.  `sp audit verify` finds what
someone with write access to the database file (but not to the key file beside it) does:
the newest records deleted, all deleted, a forged record appended, the history re-chained,
a user's role raised, a user inserted or deleted, a value stored as binary data; it says so
in plain words and never shows a traceback.  Concurrent writers never collide on an id."""

from __future__ import annotations

import json
import sqlite3
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from app.store import audit
from app.store.audit import GENESIS, AuditEntry, record_hash
from app.store.checkpoints import Checkpointer
from app.store.db import open_store, sqlite_url
from app.store.keys import read_keys
from app.store.verification import verify
from tests.app.store.test_audit_store import sealed_store, tamper
from tests.app.store.test_audit_store import verify as sp_verify

T0 = 1_700_000_000.0
FORGED = "INSERT INTO audit VALUES (31, ?, 'demo', 'admin', 'user', 'enabled', '', '{}', ?, ?, "


@pytest.fixture
def db(tmp_path: Path) -> Path:
    """A sealed store with two users (added through the audit writer), 30 records and a
    checkpoint after record 25."""
    path = tmp_path / "station.db"
    store = sealed_store(path)

    def add(name: str, role: str) -> None:
        from app.people.auth import add_user

        def adding(session: object) -> None:
            add_user(session, name, role, f"{name}-password-1", must_change=False)  # type: ignore[arg-type]

        entry = AuditEntry("user", "added", "admin", "", {"name": name, "role": role})
        audit.write(store, "demo", [entry], T0, also=adding)

    add("anna", "operator")
    add("admin", "admin")
    for k in range(22):
        audit.write(store, "demo", [AuditEntry("operator", f"step {k}", "anna")], T0 + k)
    Checkpointer(store, "demo").checkpoint()  # 25 records
    for k in range(5):
        audit.write(store, "demo", [AuditEntry("operator", f"late {k}", "anna")], T0 + 50 + k)
    store.close()
    return path


def broken(db: Path, *expected: str) -> str:
    result = sp_verify(db)
    assert result.returncode == 1, result.stdout
    assert "Traceback" not in result.stdout + result.stderr
    assert "NOT intact" in result.stdout
    for words in expected:
        assert words in result.stdout, result.stdout
    return result.stdout


def rows(db: Path, where: str = "") -> list[tuple[object, ...]]:
    with sqlite3.connect(db) as connection:
        return connection.execute(f"SELECT * FROM audit {where} ORDER BY id").fetchall()


def test_the_untouched_store_is_intact(db: Path) -> None:
    result = sp_verify(db)
    assert result.returncode == 0, result.stdout
    assert "audit log intact: 30 records" in result.stdout
    assert "1 signed checkpoints, the newest covering 25 records" in result.stdout


def test_deleting_the_newest_records_is_found(db: Path) -> None:
    tamper(db, "DELETE FROM audit WHERE id > 20")
    broken(db, "the log has 20 records, but the checkpoint", "the newest 5 were deleted")


def test_deleting_every_record_is_found(db: Path) -> None:
    tamper(db, "DELETE FROM audit")
    broken(db, "the log has 0 records", "saw 25")


def recompute_from(db: Path, first: int, change: dict[int, str]) -> None:
    """Rewrite the chain from record `first` on with plain hashes, as someone without the
    key could: each record's hash and previous recomputed; `change` edits subjects."""
    with sqlite3.connect(db) as connection:
        connection.execute("DROP TRIGGER audit_no_update")
        previous = connection.execute(
            "SELECT hash FROM audit WHERE id = ?", (first - 1,)
        ).fetchone()
        previous = previous[0] if previous else GENESIS
        for row in connection.execute(
            "SELECT id, time, station, user, kind, subject, resource, detail FROM audit "
            "WHERE id >= ? ORDER BY id",
            (first,),
        ).fetchall():
            values = list(row)
            values[5] = change.get(values[0], values[5])
            digest = record_hash(*values, previous)
            connection.execute(
                "UPDATE audit SET subject = ?, previous = ?, hash = ? WHERE id = ?",
                (values[5], previous, digest, values[0]),
            )
            previous = digest


def test_a_re_chained_history_is_found(db: Path) -> None:
    recompute_from(db, 10, {12: "nothing happened"})
    # records 10 and 11 come out as they were; from the changed one on, no seal fits
    out = broken(db, "records 12-30: its seal does not match")
    assert "record 25 is not the one the checkpoint" in out


def test_a_forged_record_appended_is_found(db: Path) -> None:
    last = rows(db)[-1]
    digest = record_hash(31, T0 + 99, "demo", "admin", "user", "enabled", "", "{}", str(last[9]))
    with sqlite3.connect(db) as connection:
        connection.execute(
            FORGED + "?)",
            (T0 + 99, last[9], digest, "0" * 64),
        )
    broken(db, "record 31: its seal does not match")
    with sqlite3.connect(db) as connection:
        connection.execute("DROP TRIGGER audit_no_delete")
        connection.execute("DELETE FROM audit WHERE id = 31")
        connection.execute(
            FORGED + "'')",
            (T0 + 99, last[9], digest),
        )
    broken(db, "record 31: has no seal although sealed records come before it")


def test_a_role_raised_in_the_users_table_is_found(db: Path) -> None:
    with sqlite3.connect(db) as connection:
        connection.execute("UPDATE users SET role = 'admin' WHERE name = 'anna'")
    broken(db, "user 'anna': the row does not match its seal")


def test_a_user_inserted_or_deleted_outside_the_station_is_found(db: Path) -> None:
    with sqlite3.connect(db) as connection:
        connection.execute(
            "INSERT INTO users (name, role, password_hash, must_change_password, disabled, "
            "created_at, mac) SELECT 'mallory', 'admin', password_hash, 0, 0, created_at, mac "
            "FROM users WHERE name = 'admin'"
        )
    broken(db, "user 'mallory'", "never added by the station")
    with sqlite3.connect(db) as connection:
        connection.execute("DELETE FROM users WHERE name IN ('mallory', 'anna')")
    broken(db, "user 'anna', added in record", "deleted outside the station")


def test_binary_data_is_named_not_a_traceback(db: Path) -> None:
    tamper(db, "UPDATE audit SET detail = x'00ff10' WHERE id = 7")
    broken(db, "record 7: its detail is binary data, not text")
    tamper_users = "UPDATE users SET role = x'61646d696e' WHERE name = 'anna'"
    with sqlite3.connect(db) as connection:
        connection.execute(tamper_users)
    broken(db, "user 'anna': the row does not match its seal")


def test_a_forged_or_damaged_checkpoint_is_found(db: Path) -> None:
    checkpoints = db.with_name(db.name + ".key.checkpoints")
    line = json.loads(checkpoints.read_text().splitlines()[0])
    line["count"] = 3
    with checkpoints.open("a") as file:
        file.write(json.dumps(line) + "\n")
        file.write("not json at all\n")
    broken(db, "(line 2) is not signed with the station's key", "line 3 of the checkpoints file")


def test_without_its_key_a_sealed_log_is_not_called_intact(db: Path) -> None:
    db.with_name(db.name + ".key").rename(db.with_name("elsewhere.key"))
    broken(db, "the log is sealed, but without its key file")


def test_an_unreadable_store_is_said_plainly(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.db"
    garbage.write_bytes(b"this is not a database" * 100)
    result = sp_verify(garbage)
    assert result.returncode == 2
    assert result.stdout.startswith("cannot verify:") and "Traceback" not in result.stderr


def test_concurrent_writers_never_collide_on_an_id(tmp_path: Path) -> None:
    store = sealed_store(tmp_path / "busy.db")

    def write(k: int) -> None:
        for j in range(25):
            audit.write(store, "demo", [AuditEntry("operator", f"{k}.{j}")], T0 + j)

    with ThreadPoolExecutor(max_workers=8) as pool:
        list(pool.map(write, range(8)))
    assert store.audit_conflicts == 0  # one writer: nobody lost a commit and had to retry
    report = verify(store, store.keys)
    assert report.records == 1 + 8 * 25
    assert not [p for p in report.problems if "checkpoints" not in p], report.problems
    store.close()


def test_each_record_hash_covers_the_hash_before_it() -> None:
    """Without it, a record could be re-linked to another predecessor unseen."""
    fields = (5, T0, "demo", "anna", "operator", "step", "", "{}")
    assert record_hash(*fields, "a" * 64) != record_hash(*fields, "b" * 64)


def test_the_key_is_outside_the_database(db: Path) -> None:
    keys = read_keys(db.with_name(db.name + ".key"))
    files = [f for f in (db, Path(f"{db}-wal")) if f.exists()]
    raw = b"".join(f.read_bytes() for f in files)
    for secret in (keys.master, keys.master.hex().encode(), keys.cookie_secret.encode()):
        assert secret not in raw


def test_a_store_from_before_seals_is_sealed_and_its_history_covered(tmp_path: Path) -> None:
    """An older store (schema 0001: plain chain, no key) upgraded: its users are sealed, a
    first sealed record covers the old chain, and rewriting that old history shows."""
    from alembic import command
    from alembic.config import Config

    from app.store.db import MIGRATIONS

    path = tmp_path / "old.db"
    store = open_store(sqlite_url(path))
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.set_main_option("sqlalchemy.url", sqlite_url(path))
    with store.engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, "0001")
    with sqlite3.connect(path) as connection:
        connection.execute(
            "INSERT INTO users (name, role, password_hash, must_change_password, disabled, "
            "created_at) VALUES ('old', 'engineer', 'x', 0, 0, 1.0)"
        )
        previous = GENESIS
        for k in range(1, 6):
            digest = record_hash(
                k, T0 + k, "demo", "old", "operator", f"old {k}", "", "{}", previous
            )
            connection.execute(
                "INSERT INTO audit VALUES (?, ?, 'demo', 'old', 'operator', ?, '', '{}', ?, ?)",
                (k, T0 + k, f"old {k}", previous, digest),
            )
            previous = digest
    store.close()
    store = sealed_store(path)  # upgrade to the newest schema, make the key, seal
    Checkpointer(store, "demo").checkpoint()
    report = verify(store, store.keys)
    assert report.intact, report.problems
    assert report.records == 6 and report.sealed_from == 6 and report.users == 1
    store.close()
    recompute_from(path, 3, {3: "rewritten"})  # the old part, recomputed without the key
    broken(path, "record 6: its seal does not match")
