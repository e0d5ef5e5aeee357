"""An older sealed copy of a row written back is refused: seals have freshness.

The attacker saved the users and sessions rows as the station had sealed them, let an admin
demote, disable or reset, or a person sign out, and wrote the saved copies back: each copy's
seal matches, but its counter is older than the one the station last wrote (kept in memory
while it runs, in the signed checkpoints between runs).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.serve import build, default_cache
from app.store.db import sqlite_url
from tests.support.stations import (
    MODEL,
    PASSWORDS,
    RunningStation,
    form_token,
    new_password,
    start_station,
)

USER_COLUMNS = "name, role, password_hash, must_change_password, disabled, seq, mac"


def _save(db: Path, name: str) -> tuple[object, ...]:
    with sqlite3.connect(db) as connection:
        row = connection.execute(f"SELECT {USER_COLUMNS} FROM users WHERE name = ?", (name,))
        found: tuple[object, ...] = row.fetchone()
    return found


def _write_back(db: Path, saved: tuple[object, ...]) -> None:
    columns = USER_COLUMNS.split(", ")[1:]
    assignments = ", ".join(f"{c} = ?" for c in columns)
    with sqlite3.connect(db) as connection:
        connection.execute(f"UPDATE users SET {assignments} WHERE name = ?", (*saved[1:], saved[0]))


def _sign_in(station: RunningStation, name: str, password: str) -> int:
    client = station.client()
    page = client.get("/login")
    form = {"name": name, "password": password, "csrf_token": form_token(page.text)}
    return client.post("/login", data=form, follow_redirects=False).status_code


def _api_role(station: RunningStation, name: str) -> int:
    """Status of an engineer's API call with a fresh token of `name`."""
    client = station.client()
    answer = client.post("/api/token", json={"name": name, "password": new_password(name)})
    if answer.status_code != 200:
        return answer.status_code
    token = answer.json()["token"]
    return client.get("/api/models", headers={"authorization": f"Bearer {token}"}).status_code


@pytest.fixture
def station(tmp_path: Path) -> Iterator[RunningStation]:
    running = start_station(tmp_path)
    yield running
    running.stop()


def _admin(station: RunningStation) -> tuple[object, str]:
    client = station.client()
    return client, station.login(client, "admin")


def test_a_demotion_undone_by_an_older_copy_is_refused_at_once(station: RunningStation) -> None:
    station.login(station.client(), "engineer")
    saved = _save(station.db, "engineer")
    assert _api_role(station, "engineer") == 200
    admin, token = _admin(station)
    form = {"name": "engineer", "role": "operator", "csrf_token": token}
    assert admin.post("/users/role", data=form).status_code in (200, 303)  # type: ignore[attr-defined]
    assert _api_role(station, "engineer") == 403
    _write_back(station.db, saved)  # the sealed engineer row, as before the demotion
    assert _api_role(station, "engineer") == 401  # neither engineer nor operator: refused


def _restarted(station: RunningStation) -> RunningStation:
    """The same database served again by a new station process."""
    built = build(MODEL, sqlite_url(station.db), cache=default_cache(), period=0.05)
    built.server.start()
    return RunningStation(built, station.db)


def test_a_disable_undone_is_refused_after_a_restart(tmp_path: Path) -> None:
    station = start_station(tmp_path)
    try:
        station.login(station.client(), "engineer")
        saved = _save(station.db, "engineer")
        admin, token = _admin(station)
        form = {"name": "engineer", "disabled": "1", "csrf_token": token}
        assert admin.post("/users/disable", data=form).status_code in (200, 303)  # type: ignore[attr-defined]
    finally:
        station.stop()
    _write_back(station.db, saved)
    again = _restarted(station)
    try:
        assert _sign_in(again, "engineer", new_password("engineer")) != 303
        assert _sign_in(again, "operator", PASSWORDS["operator"]) == 303  # others still can
    finally:
        again.stop()


def test_the_first_start_password_stops_working_once_changed(tmp_path: Path) -> None:
    """The first-start admin row (with the README's password) written back after the admin
    changed it: `admin-demo-1` must not sign anyone in, at once nor after a restart."""
    station = start_station(tmp_path)
    try:
        first = _save(station.db, "admin")
        station.login(station.client(), "admin")  # changes the first-login password
        _write_back(station.db, first)
        assert _sign_in(station, "admin", PASSWORDS["admin"]) != 303
    finally:
        station.stop()
    again = _restarted(station)
    try:
        assert _sign_in(again, "admin", PASSWORDS["admin"]) != 303
        assert _sign_in(again, "operator", PASSWORDS["operator"]) == 303  # others still can
    finally:
        again.stop()


def test_a_signed_out_session_does_not_come_back(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")
    with sqlite3.connect(station.db) as connection:
        (sid,) = connection.execute(
            "SELECT id FROM user_sessions WHERE revoked_at IS NULL AND kind = 'browser'"
        ).fetchone()
        live = connection.execute(
            "SELECT revoked_at, revoked_why, seq, mac FROM user_sessions WHERE id = ?", (sid,)
        ).fetchone()
    cookies = dict(client.cookies)
    assert client.post("/logout", data={"csrf_token": token}).status_code in (200, 303)
    # (1) the revocation simply undone: the row no longer matches its seal
    with sqlite3.connect(station.db) as connection:
        connection.execute(
            "UPDATE user_sessions SET revoked_at = NULL, revoked_why = '' WHERE id = ?", (sid,)
        )
    back = station.client()
    back.cookies.update(cookies)
    assert back.get("/alarms", follow_redirects=False).status_code in (303, 401)
    # (2) the sealed copy from before the sign-out written back: its counter is older
    with sqlite3.connect(station.db) as connection:
        connection.execute(
            "UPDATE user_sessions SET revoked_at = ?, revoked_why = ?, seq = ?, mac = ? "
            "WHERE id = ?",
            (*live, sid),
        )
    again = station.client()
    again.cookies.update(cookies)
    assert again.get("/alarms", follow_redirects=False).status_code in (303, 401)
