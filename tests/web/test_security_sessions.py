"""Issue 15, point 4: sessions can be revoked.  A cookie copied before logout, a session
on another device after a password change, an API token after a password change or a
disable, and a disabled user's old cookie all stop working at once; changing a password
needs the current one; a session row pointed at another user inside the database, or a
user row changed there, is refused."""

from __future__ import annotations

import sqlite3

from starlette.testclient import TestClient

from tests.support.stations import PASSWORDS, RunningStation, form_token, new_password


def copy_of(client: TestClient, station: RunningStation) -> TestClient:
    """Another browser holding a copy of `client`'s cookie (stolen, or a second tab)."""
    other = station.client()
    other.cookies.update(client.cookies)
    return other


def signed_in(client: TestClient) -> bool:
    return client.get("/station", follow_redirects=False).status_code == 200


def change_password(client: TestClient, current: str, new: str) -> int:
    page = client.get("/password")
    form = {"current_password": current, "new_password": new, "repeat": new}
    form["csrf_token"] = form_token(page.text)
    return client.post("/password", data=form, follow_redirects=False).status_code


def test_a_cookie_copied_before_logout_no_longer_works(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "engineer")
    stolen = copy_of(client, station)
    assert signed_in(stolen)
    client.post("/logout", data={"csrf_token": token})
    assert not signed_in(client)
    assert not signed_in(stolen)
    assert stolen.get("/api/station").status_code == 401


def test_a_password_change_ends_every_other_session_and_token(station: RunningStation) -> None:
    laptop, watch = station.client(), station.client()
    station.login(laptop, "engineer")
    station.login(watch, "engineer")
    token = station.token(station.client(), "engineer")
    bearer = {"Authorization": f"Bearer {token}"}
    assert station.client().get("/api/station", headers=bearer).status_code == 200
    newer = new_password("engineer") + "-2"
    assert change_password(laptop, new_password("engineer"), newer) == 303
    assert signed_in(laptop)  # the browser that changed it goes on, with a new session
    assert not signed_in(watch)
    answer = station.client().get("/api/station", headers=bearer)
    assert answer.status_code == 401 and "revoked" in answer.json()["detail"]
    # and the old password is of no use
    fresh = station.client()
    form = {"name": "engineer", "password": new_password("engineer")}
    form["csrf_token"] = form_token(fresh.get("/login").text)
    assert fresh.post("/login", data=form).status_code == 401


def test_changing_a_password_needs_the_current_one(station: RunningStation) -> None:
    client = station.client()
    station.login(client, "operator")
    assert change_password(client, "not-my-password", "a-new-password-1") == 401
    assert change_password(client, new_password("operator"), "a-new-password-1") == 303
    # the first-login change asks for the first-login password too
    admin = station.client()
    page = admin.get("/login")
    form = {"name": "admin", "password": PASSWORDS["admin"], "csrf_token": form_token(page.text)}
    assert admin.post("/login", data=form, follow_redirects=False).status_code == 303
    assert change_password(admin, "guessed-wrong-1", "admin-new-pw-1") == 401
    assert change_password(admin, PASSWORDS["admin"], "admin-new-pw-1") == 303


def test_disabling_a_user_ends_their_sessions_and_tokens(station: RunningStation) -> None:
    admin, operator = station.client(), station.client()
    token = station.login(admin, "admin")
    station.login(operator, "operator")
    api = station.token(station.client(), "operator")
    form = {"name": "operator", "disabled": "true", "csrf_token": token}
    assert admin.post("/users/disable", data=form).status_code == 200
    assert operator.get("/", follow_redirects=False).status_code == 303
    bearer = {"Authorization": f"Bearer {api}"}
    assert station.client().get("/api/tasks", headers=bearer).status_code == 401
    # the old cookie cannot set a new password either
    status = change_password(operator, new_password("operator"), "taken-over-pw-1")
    assert status == 303  # sent back to sign in, nothing changed
    with station.built.server.store.engine.connect() as connection:
        changed = connection.exec_driver_sql(
            "SELECT count(*) FROM audit WHERE kind = 'login' AND subject = 'password changed' "
            "AND user = 'operator'"
        ).scalar()
    assert changed == 1  # only the first-login change of station.login
    # enabled again, the user signs in anew: what was signed in before stays ended
    form["disabled"] = "false"
    assert admin.post("/users/disable", data=form).status_code == 200
    assert station.client().get("/api/tasks", headers=bearer).status_code == 401
    assert operator.get("/", follow_redirects=False).status_code == 303


def test_a_session_pointed_at_another_user_in_the_database_is_refused(
    station: RunningStation,
) -> None:
    station.login(station.client(), "admin")  # an admin past the first-login change
    client = station.client()
    station.login(client, "operator")
    with sqlite3.connect(station.db) as db:
        admin_id = db.execute("SELECT id FROM users WHERE name = 'admin'").fetchone()[0]
        db.execute("UPDATE user_sessions SET user_id = ?", (admin_id,))
    assert client.get("/users", follow_redirects=False).status_code == 303
    assert not signed_in(client)


def test_a_role_raised_in_the_database_grants_nothing(station: RunningStation) -> None:
    client = station.client()
    station.login(client, "operator")
    with sqlite3.connect(station.db) as db:
        db.execute("UPDATE users SET role = 'admin' WHERE name = 'operator'")
    assert client.get("/users", follow_redirects=False).status_code == 303  # signed out
    fresh = station.client()
    form = {"name": "operator", "password": new_password("operator")}
    form["csrf_token"] = form_token(fresh.get("/login").text)
    assert fresh.post("/login", data=form).status_code == 401
    with station.built.server.store.engine.connect() as connection:
        said = connection.exec_driver_sql(
            "SELECT count(*) FROM audit WHERE kind = 'user' "
            "AND subject = 'row changed outside the station'"
        ).scalar()
    assert said == 1
