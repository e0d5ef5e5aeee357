"""An attacker who can write the station's database file (not its key file) cannot steer it.

Each test runs a real station on a real SQLite file, stops it, changes one table the way
the attacker would (with sqlite3, as any local writer of the file could), and starts it
again: a row it would act on stops it from starting (audited, a high alarm left for later),
a row it refuses one by one (a user, a session) is refused, and `sp audit verify` names
them.  An older sealed copy written back is caught by its counter.
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.serve import build, default_cache
from app.station import supervisor_cache
from app.station.tampering import REFUSED_KEY, StoreTampered
from app.store.db import sqlite_url
from planner.reading import load_station
from planner.runner.actions import StartIntention
from tests.support.attacks import poison_cache
from tests.support.paths import REPOSITORY
from tests.support.stations import MODEL, PASSWORDS, RunningStation, start_station

INTENTION = "assemble_engine"


def _start_again(db: Path) -> RunningStation:
    built = build(MODEL, sqlite_url(db), cache=default_cache(), period=0.05, speed=4.0)
    station = RunningStation(built, db)
    built.server.start()
    return station


def _refused(db: Path) -> StoreTampered:
    with pytest.raises(StoreTampered) as refused:
        build(MODEL, sqlite_url(db), cache=default_cache(), period=0.05)
    return refused.value


def _sql(db: Path, statement: str, *args: object) -> list[tuple[object, ...]]:
    with sqlite3.connect(db) as connection:
        rows = connection.execute(statement, args).fetchall()
    return rows


def _verify(db: Path) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "app.cli.main", "audit", "verify", "--db", sqlite_url(db)]
    return subprocess.run(command, capture_output=True, text=True, cwd=REPOSITORY, timeout=120)


def _saved(db: Path) -> bool:
    """The station committed a round: its snapshot is in the store."""
    return bool(_sql(db, "SELECT snapshot FROM stations WHERE snapshot != ''"))


def _audit_subjects(db: Path) -> list[str]:
    return [str(r[0]) for r in _sql(db, "SELECT subject FROM audit ORDER BY id")]


@pytest.fixture
def stopped(tmp_path: Path) -> Iterator[Path]:
    """A station that ran (its state, alarms, one signed-in admin) and stopped cleanly."""
    station = start_station(tmp_path)
    try:
        station.login(station.client(), "admin")
        station.wait(lambda: _saved(station.db))
    finally:
        station.stop()
    yield station.db


def test_an_untouched_store_starts_again(stopped: Path) -> None:
    station = _start_again(stopped)
    station.stop()
    result = _verify(stopped)
    assert result.returncode == 0, result.stdout


def test_the_active_model_text_changed_stops_the_start(stopped: Path) -> None:
    """The critical finding: one specification deleted from the stored text ran as version 1."""
    (text,) = _sql(stopped, "SELECT text FROM model_versions WHERE number = 1")[0]
    assert isinstance(text, str)
    lines = text.splitlines()
    first = next(i for i, line in enumerate(lines) if line.strip().startswith("- name:")
                 and "specifications" in "\n".join(lines[:i]))  # fmt: skip
    changed = "\n".join(lines[:first] + lines[first + 1 :])
    _sql(stopped, "UPDATE model_versions SET text = ? WHERE number = 1", changed)
    refused = _refused(stopped)
    assert any("model version 1" in p for p in refused.problems), refused.problems
    assert "start refused: store changed outside" in _audit_subjects(stopped)
    alarm = _sql(stopped, "SELECT data FROM alarms WHERE key = ?", REFUSED_KEY)
    assert alarm and json.loads(str(alarm[0][0]))["priority"] == "high"
    result = _verify(stopped)
    assert result.returncode == 1 and "model version 1 of demo_station" in result.stdout


def test_the_hash_recomputed_with_the_text_is_no_help(stopped: Path) -> None:
    import hashlib

    text = "station: demo_station\n# nothing\n"
    digest = hashlib.sha256(text.encode()).hexdigest()
    _sql(stopped, "UPDATE model_versions SET text = ?, sha256 = ? WHERE number = 1", text, digest)
    assert any("model version 1" in p for p in _refused(stopped).problems)


def test_a_recovery_plan_approved_in_the_snapshot_stops_the_start(stopped: Path) -> None:
    """The critical finding: a plan written into the snapshot ran past supervisor and
    operator at the next start."""
    (snapshot,) = _sql(stopped, "SELECT snapshot FROM stations")[0]
    data = json.loads(str(snapshot))
    data["recovery"] = {"steps": ["r1_to_engine", "r2_to_engine"], "approved": [0, 1]}
    data["restart_mode"] = False
    _sql(stopped, "UPDATE stations SET snapshot = ?", json.dumps(data))
    refused = _refused(stopped)
    assert any("state of station demo_station" in p for p in refused.problems), refused.problems


def test_an_older_sealed_snapshot_written_back_stops_the_start(tmp_path: Path) -> None:
    """A copy of the station's own sealed row, from before it ran on: the seal matches, the
    counter is older than the checkpoint written when it stopped."""
    station = start_station(tmp_path)
    try:
        station.wait(lambda: _saved(station.db))
        older = _sql(station.db, "SELECT snapshot, world, updated_at, audit_id, audit_hash, seq, "
                     "mac FROM stations")[0]  # fmt: skip
        client = station.client()
        station.login(client, "operator")
        before = _sql(station.db, "SELECT seq FROM stations")[0][0]
        station.live.act(StartIntention(user="operator", name=INTENTION)).result(timeout=30)
        station.wait(lambda: _sql(station.db, "SELECT seq FROM stations")[0][0] != before)
    finally:
        station.stop()
    _sql(
        station.db,
        "UPDATE stations SET snapshot=?, world=?, updated_at=?, audit_id=?, audit_hash=?, seq=?, "
        "mac=?",
        *older,
    )
    refused = _refused(station.db)
    assert any("older copy" in p or "older than its audit log" in p for p in refused.problems)


def test_an_alarm_shelved_to_2100_stops_the_start(tmp_path: Path) -> None:
    """A high alarm the station raised, shelved "by operator" until 2100 in the database."""
    station = start_station(tmp_path)
    try:
        station.live.report_tampering("a test row", "raised for the test").result(timeout=30)
        station.wait(lambda: bool(_sql(station.db, "SELECT key FROM alarms")))
    finally:
        station.stop()
    ((key, data),) = _sql(station.db, "SELECT key, data FROM alarms")
    alarm = json.loads(str(data))
    alarm.update(state="shelved", shelved_by="operator", shelved_until=4102444800.0)
    _sql(station.db, "UPDATE alarms SET data = ? WHERE key = ?", json.dumps(alarm), key)
    refused = _refused(station.db)
    assert any("alarm" in p for p in refused.problems), refused.problems


def test_a_setting_written_outside_stops_the_start(stopped: Path) -> None:
    _sql(stopped, "INSERT INTO settings (key, value, seq, mac) VALUES ('mode', 'x', 1, '')")
    assert any("setting 'mode'" in p for p in _refused(stopped).problems)


def test_accepting_the_changed_rows_lets_it_start_with_the_alarm(stopped: Path) -> None:
    _sql(stopped, "UPDATE stations SET world = ''")
    _refused(stopped)
    command = [sys.executable, "-m", "app.cli.main", "store", "accept", "--db", sqlite_url(stopped)]
    command += ["--by", "maria", "--why", "restored from last night"]
    accepted = subprocess.run(command, capture_output=True, text=True, cwd=REPOSITORY, timeout=60)
    assert accepted.returncode == 0, accepted.stdout + accepted.stderr
    assert "state of station demo_station" in accepted.stdout
    station = _start_again(stopped)
    try:
        keys = [a.key for a in station.live.book.alarms(include_normal=True)]
        assert REFUSED_KEY in keys
    finally:
        station.stop()
    assert "changed rows accepted" in _audit_subjects(stopped)
    assert _verify(stopped).returncode == 0


def test_sp_serve_says_why_and_exits(stopped: Path) -> None:
    _sql(stopped, "UPDATE model_versions SET note = 'mine' WHERE number = 1")
    command = [sys.executable, "-m", "app.cli.main", "serve", "--model", str(MODEL), "--db",
               sqlite_url(stopped), "--port", "1"]  # fmt: skip
    result = subprocess.run(command, capture_output=True, text=True, cwd=REPOSITORY, timeout=120)
    assert result.returncode == 3, result.stdout + result.stderr
    assert "will not start" in result.stderr and "model version 1" in result.stderr
    assert "Traceback" not in result.stderr
    assert PASSWORDS["admin"] not in result.stdout  # no seeding on a refused store


def test_a_poisoned_supervisor_cache_does_not_reach_the_station(tmp_path: Path) -> None:
    """Genuine model, genuine database, the cache rewritten to "no forbidden states": the
    station's supervisor still forbids every state synthesis forbids."""
    cache, text = tmp_path / "cache", MODEL.read_text()
    genuine = supervisor_cache.planner(load_station(text, str(MODEL)).model, text, "bdd", cache)
    forbidden = genuine.sym.count(genuine.bad)
    poison_cache(cache, text)
    built = build(MODEL, sqlite_url(tmp_path / "station.db"), cache=cache, period=0.05)
    station = RunningStation(built, tmp_path / "station.db")
    built.server.start()
    try:
        planner = built.server.live.model.transition_planner
        assert forbidden > 0 and planner.sym.count(planner.bad) == forbidden
    finally:
        station.stop()
