"""An admin's work on the users page (issue 16): reset a password (the user chooses their own
at the next sign-in), change a role, see each user's last sign-in.  Each change is audited,
ends the user's sessions, and the last admin can neither step down nor be disabled."""

from __future__ import annotations

import html
import json
import re

from sqlalchemy import select
from starlette.testclient import TestClient

from app.store.tables import AuditRecord
from tests.support.stations import RunningStation, form_token, new_password

RESET = "a-fresh-start-42"


def signed_in(client: TestClient) -> bool:
    return client.get("/alarms", follow_redirects=False).status_code == 200


def user_records(station: RunningStation, subject: str) -> list[dict[str, object]]:
    with station.built.server.store.sessions() as session:
        query = select(AuditRecord).where(AuditRecord.kind == "user")
        rows = session.scalars(query.where(AuditRecord.subject == subject))
        return [{"by": r.user, **json.loads(r.detail)} for r in rows]


def row(page: str, name: str) -> str:
    found = re.search(rf'<tr data-user="{name}">(.*?)</tr>', page, re.S)
    assert found, f"no row for {name}"
    return found.group(1)


def refusal(client: TestClient, url: str, form: dict[str, str]) -> str:
    """A refused form: answered 303 back to the users page (a reload does not send it
    again), which says why once; returns what it says."""
    answer = client.post(url, data=form, follow_redirects=False)
    assert (answer.status_code, answer.headers.get("location")) == (303, "/users"), answer.text
    page = client.get("/users").text
    said = re.findall(r'class="flash flash--error" role="alert">([^<]*)<', page)
    assert len(said) == 1, page
    assert not re.findall(r"flash--error", client.get("/users").text), "said more than once"
    return html.unescape(said[0])


def sign_in(client: TestClient, name: str, password: str) -> str:
    """The login form; returns where it sends the user ("refused" for a wrong password)."""
    form = {"name": name, "password": password, "csrf_token": form_token(client.get("/login").text)}
    answer = client.post("/login", data=form, follow_redirects=False)
    if answer.status_code == 401:
        return "refused"
    assert answer.status_code == 303, answer.text
    return str(answer.headers["location"])


def test_a_reset_password_ends_the_sessions_and_must_be_changed(station: RunningStation) -> None:
    admin, watch = station.client(), station.client()
    token = station.login(admin, "admin")
    station.login(watch, "operator")
    assert signed_in(watch)
    page = admin.get("/users").text
    assert "never" not in row(page, "operator")  # signed in just now: its time is shown
    assert re.search(r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", row(page, "operator"))
    assert "never" in row(page, "auditor")

    form = {"name": "operator", "password": RESET, "csrf_token": token}
    answer = admin.post("/users/password", data=form)
    assert answer.status_code == 200 and "new first-login password" in answer.text
    assert not signed_in(watch)
    (record,) = user_records(station, "password reset")
    assert record == {"by": "admin", "name": "operator", "sessions_ended": 1}
    assert "first-login password" in row(answer.text, "operator")

    fresh = station.client()
    assert sign_in(fresh, "operator", new_password("operator")) == "refused"  # the old one
    assert sign_in(fresh, "operator", RESET) == "/password"  # the reset one, to be changed
    assert "at least 10" in refusal(admin, "/users/password", {**form, "password": "short"})
    assert "Change password" in refusal(admin, "/users/password", {**form, "name": "admin"})


def test_a_new_role_ends_the_sessions_and_holds_from_the_next_sign_in(
    station: RunningStation,
) -> None:
    admin, laptop = station.client(), station.client()
    token = station.login(admin, "admin")
    station.login(laptop, "engineer")
    assert laptop.get("/station").status_code == 200
    answer = admin.post(
        "/users/role", data={"name": "engineer", "role": "auditor", "csrf_token": token}
    )
    assert answer.status_code == 200 and "engineer is now an auditor" in answer.text
    assert '<td data-label="Role">auditor</td>' in row(answer.text, "engineer")
    assert not signed_in(laptop)
    (record,) = user_records(station, "role changed")
    assert record == {
        "by": "admin",
        "name": "engineer",
        "role": "auditor",
        "previous": "engineer",
        "sessions_ended": 1,
    }
    sign_in(laptop, "engineer", new_password("engineer"))
    assert laptop.get("/station", follow_redirects=False).status_code == 403
    assert laptop.get("/audit").status_code == 200
    same = {"name": "engineer", "role": "auditor", "csrf_token": token}
    assert "already an auditor" in refusal(admin, "/users/role", same)
    unknown = {"name": "engineer", "role": "boss", "csrf_token": token}
    assert "unknown role 'boss'" in refusal(admin, "/users/role", unknown)


def test_the_last_admin_can_neither_step_down_nor_be_disabled(station: RunningStation) -> None:
    admin = station.client()
    token = station.login(admin, "admin")
    down = {"name": "admin", "role": "engineer", "csrf_token": token}
    assert "the last admin" in refusal(admin, "/users/role", down)
    disabled = {"name": "admin", "disabled": "true", "csrf_token": token}
    assert "cannot disable yourself" in refusal(admin, "/users/disable", disabled)
    assert signed_in(admin) and not user_records(station, "role changed")

    # with a second admin the first may step down, and is signed out with it
    second = {"name": "auditor", "role": "admin", "csrf_token": token}
    assert admin.post("/users/role", data=second).status_code == 200
    stepped = admin.post("/users/role", data=down, follow_redirects=False)
    assert stepped.status_code == 303 and stepped.headers["location"] == "/login"
    assert not signed_in(admin)
    changes = [(r["name"], r["role"]) for r in user_records(station, "role changed")]
    assert changes == [("auditor", "admin"), ("admin", "engineer")]


def test_a_refused_change_is_audited_as_refused_and_a_done_one_redirects(
    station: RunningStation,
) -> None:
    """The audit holds only what happened: an "add" of a name that exists is a refusal, not
    a second "user added"; after a change the page is reached by a redirect, so a reload
    does not send the form again."""
    admin = station.client()
    token = station.login(admin, "admin")
    form = {"name": "berit", "role": "auditor", "password": "berit-first-pw", "csrf_token": token}
    done = admin.post("/users", data=form, follow_redirects=False)
    assert done.status_code == 303 and done.headers["location"] == "/users"
    page = admin.get("/users")
    assert "Added berit (auditor)" in page.text and 'data-user="berit"' in page.text
    assert "Added berit" not in admin.get("/users").text  # said once
    assert refusal(admin, "/users", form) == "there is already a user 'berit'"
    assert [r["name"] for r in user_records(station, "added")].count("berit") == 1
    [refused] = [r for r in user_records(station, "add refused") if r["name"] == "berit"]
    assert refused["why"] == "there is already a user 'berit'" and refused["by"] == "admin"

    # refusals inside the change (the row as it is decides) are audited as refused too
    role = {"name": "berit", "role": "auditor", "csrf_token": token}
    assert refusal(admin, "/users/role", role) == "berit is already an auditor"
    assert not [r for r in user_records(station, "role changed") if r["name"] == "berit"]
    [why] = [r["why"] for r in user_records(station, "role changed refused")]
    assert why == "berit is already an auditor"
    mine = {"name": "admin", "disabled": "true", "csrf_token": token}
    assert refusal(admin, "/users/disable", mine) == "you cannot disable yourself"
    assert [r["why"] for r in user_records(station, "disabled refused")] == [
        "you cannot disable yourself"
    ]
