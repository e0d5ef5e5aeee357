"""Opening the store: the engine (SQLite in WAL mode by default), sessions and migrations."""

from __future__ import annotations

import os
import sqlite3
import stat
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine, create_engine, event, make_url
from sqlalchemy.orm import Session, sessionmaker

if TYPE_CHECKING:
    from app.store.keys import StationKeys
    from app.store.row_seals import Freshness

MIGRATIONS = Path(__file__).resolve().parents[2] / "migrations"


def sqlite_url(path: str | Path) -> str:
    return f"sqlite:///{Path(path).resolve()}"


@dataclass
class Store:
    """The engine and a session factory; `upgrade()` brings the schema to the newest version.

    `keys`: the station's keys once `app.store.sealing.seal_store` has opened them (audit
    records and the rows that steer the station are sealed with them); `freshness`: the
    counters the station last wrote to those rows (app.store.row_seals); `audit_lock`: held
    by the one audit writer of the process (`app.store.audit.write`) from choosing the next
    id until the commit.
    """

    url: str
    engine: Engine
    sessions: sessionmaker[Session]
    keys: StationKeys | None = None
    freshness: Freshness | None = None
    audit_lock: threading.Lock = field(default_factory=threading.Lock)
    audit_conflicts: int = 0  # commits lost to another writer (of another process) and retried

    def upgrade(self) -> None:
        config = Config()
        config.set_main_option("script_location", str(MIGRATIONS))
        config.set_main_option("sqlalchemy.url", self.url.replace("%", "%%"))
        with self.engine.begin() as connection:
            config.attributes["connection"] = connection
            command.upgrade(config, "head")

    def close(self) -> None:
        self.engine.dispose()


def open_store(url: str) -> Store:
    """An engine for `url`.  SQLite files run in WAL mode with full fsync on commit, so a
    reader never blocks the runner's writes and a committed record survives a crash."""
    connect_args: dict[str, Any] = {}
    if url.startswith("sqlite"):
        connect_args = {"check_same_thread": False, "timeout": 30}
        private_file(make_url(url).database)
    engine = create_engine(url, connect_args=connect_args)
    if engine.dialect.name == "sqlite":
        event.listen(engine, "connect", _sqlite_pragmas)
    return Store(url, engine, sessionmaker(engine, expire_on_commit=False))


def private_file(database: str | None) -> None:
    """The SQLite file readable by its owner only (0600), created so before SQLite opens it
    (its -wal and -shm files take the database file's mode), in a folder of mode 0700 where
    we create that too: the store holds password hashes, models and the whole audit log.  An
    existing file with wider permissions is narrowed; one we do not own is left alone."""
    if not database or database == ":memory:" or database.startswith("file:"):
        return
    path = Path(database)
    if not path.parent.exists():
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    try:
        descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        mode = path.stat().st_mode
        if mode & (stat.S_IRWXG | stat.S_IRWXO) and path.stat().st_uid == os.getuid():
            path.chmod(stat.S_IMODE(mode) & 0o700)
        return
    os.close(descriptor)


def _sqlite_pragmas(connection: sqlite3.Connection, _record: object) -> None:
    cursor = connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=FULL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA busy_timeout=30000")
    cursor.close()
