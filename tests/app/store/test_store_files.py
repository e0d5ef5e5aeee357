"""The store's files are the station's own: password hashes, models and the audit log are
readable by no other local user (issue 26)."""

from __future__ import annotations

import stat
from pathlib import Path

from sqlalchemy import text

from app.store.db import open_store, sqlite_url


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_a_new_store_and_its_wal_are_readable_by_the_owner_only(tmp_path: Path) -> None:
    db = tmp_path / "plant" / "station.db"  # a folder we create too
    store = open_store(sqlite_url(db))
    store.upgrade()
    with store.engine.begin() as connection:
        connection.execute(text("CREATE TABLE probe (x INTEGER)"))
        connection.execute(text("INSERT INTO probe VALUES (1)"))
        files = [db, db.with_name("station.db-wal"), db.with_name("station.db-shm")]
        assert all(f.exists() for f in files)
        assert {f.name: mode(f) for f in files} == {f.name: 0o600 for f in files}
    assert mode(db.parent) == 0o700
    store.close()


def test_an_existing_store_open_to_others_is_narrowed(tmp_path: Path) -> None:
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o755)
    shared.chmod(0o755)
    db = shared / "station.db"
    open_store(sqlite_url(db)).close()
    db.chmod(0o644)
    store = open_store(sqlite_url(db))
    store.upgrade()
    assert mode(db) == 0o600
    assert mode(shared) == 0o755  # a folder we did not create is left as it was
    store.close()
