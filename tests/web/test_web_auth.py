"""Signing in: first-login password change, failed sign-ins audited and throttled, CSRF on
every form, roles on every page."""

from __future__ import annotations

import json

from sqlalchemy import select

from app.store.tables import AuditRecord
from tests.support.stations import PASSWORDS, RunningStation, form_token


def audit_kinds(station: RunningStation, kind: str) -> list[AuditRecord]:
    with station.built.server.store.sessions() as session:
        return list(session.scalars(select(AuditRecord).where(AuditRecord.kind == kind)))


def test_first_sign_in_requires_a_new_password(station: RunningStation) -> None:
    client = station.client()
    page = client.get("/login")
    form = {"name": "operator", "password": PASSWORDS["operator"]}
    form["csrf_token"] = form_token(page.text)
    answer = client.post("/login", data=form, follow_redirects=False)
    assert answer.headers["location"] == "/password"
    # nothing else is reachable before the password is changed
    assert client.get("/", follow_redirects=False).headers["location"] == "/password"
    page = client.get("/password")
    weak = client.post(
        "/password",
        data={
            "current_password": PASSWORDS["operator"],
            "new_password": "short",
            "repeat": "short",
            "csrf_token": form_token(page.text),
        },
    )
    assert weak.status_code == 422 and "at least 10 characters" in weak.text
    same = client.post(
        "/password",
        data={
            "current_password": PASSWORDS["operator"],
            "new_password": PASSWORDS["operator"],
            "repeat": PASSWORDS["operator"],
            "csrf_token": form_token(page.text),
        },
    )
    assert same.status_code == 422 and "other than the current one" in same.text
    station.login(client, "operator")
    assert client.get("/").status_code == 200
    kinds = {(r.subject, r.user) for r in audit_kinds(station, "login")}
    assert ("password changed", "operator") in kinds and ("signed in", "operator") in kinds


def test_failed_sign_ins_are_audited_and_throttled(station: RunningStation) -> None:
    client = station.client()
    token = form_token(client.get("/login").text)
    statuses = []
    for _ in range(7):
        answer = client.post(
            "/login", data={"name": "engineer", "password": "guess-guess", "csrf_token": token}
        )
        statuses.append(answer.status_code)
    assert statuses[:5] == [401] * 5
    assert statuses[5:] == [429, 429]
    # the right password is refused too while throttled
    answer = client.post(
        "/login",
        data={"name": "engineer", "password": PASSWORDS["engineer"], "csrf_token": token},
    )
    assert answer.status_code == 429 and "try again in" in answer.text
    station.built.server.failure_writer.flush(everything=True)
    records = [r for r in audit_kinds(station, "login") if r.subject in ("failed", "throttled")]
    # one record per window and address block, with how many (app.people.failures)
    counts = {(r.subject, r.user): json.loads(r.detail)["count"] for r in records}
    assert counts == {("failed", "engineer"): 5, ("throttled", ""): 3}


def test_forms_without_the_csrf_token_are_refused(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")
    assert client.post("/tasks/done", data={"card": "place_bp1"}).status_code == 403
    wrong = client.post("/tasks/done", data={"card": "place_bp1", "csrf_token": "forged"})
    assert wrong.status_code == 403
    # with the token the request reaches the station (which has no such card showing)
    right = client.post(
        "/tasks/done", data={"card": "place_bp1", "csrf_token": token}, follow_redirects=False
    )
    assert right.status_code == 303  # refused: back to the page, which says why
    assert "no longer shown" in client.get(right.headers["location"]).text


def test_roles_guard_every_area(station: RunningStation) -> None:
    operator, auditor = station.client(), station.client()
    station.login(operator, "operator")
    token = station.login(auditor, "auditor")
    assert operator.get("/audit").status_code == 403
    assert operator.get("/model").status_code == 403
    assert auditor.get("/", follow_redirects=False).headers["location"] == "/audit"
    assert auditor.get("/fragments/tasks").status_code == 403
    acted = auditor.post("/alarms/acknowledge", data={"key": "x", "csrf_token": token})
    assert acted.status_code == 403
    anonymous = station.client()
    assert anonymous.get("/station", follow_redirects=False).status_code == 303
    assert anonymous.get("/api/station").status_code == 401


def test_sign_out_ends_the_session(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "engineer")
    client.post("/logout", data={"csrf_token": token})
    assert client.get("/station", follow_redirects=False).status_code == 303
    assert ("signed out", "engineer") in {
        (r.subject, r.user) for r in audit_kinds(station, "login")
    }


def test_an_admin_adds_and_disables_users(station: RunningStation) -> None:
    admin, engineer = station.client(), station.client()
    token = station.login(admin, "admin")
    station.login(engineer, "engineer")
    assert engineer.get("/users").status_code == 403
    weak = admin.post(
        "/users",
        data={"name": "anna", "role": "operator", "password": "short", "csrf_token": token},
    )
    assert weak.status_code == 200 and "at least 10" in weak.text  # after the redirect
    form = {"name": "anna", "role": "operator", "password": "anna-first-pw", "csrf_token": token}
    assert "Added anna" in admin.post("/users", data=form).text
    assert "already a user" in admin.post("/users", data=form).text
    page = admin.get("/users")
    assert 'data-user="anna"' in page.text
    off = admin.post(
        "/users/disable", data={"name": "engineer", "disabled": "true", "csrf_token": token}
    )
    assert off.status_code == 200
    assert engineer.get("/station", follow_redirects=False).status_code == 303  # signed out
    subjects = {(r.subject, r.user) for r in audit_kinds(station, "user")}
    assert ("added", "admin") in subjects and ("disabled", "admin") in subjects


def test_each_role_has_exactly_its_permissions_and_an_unknown_role_none() -> None:
    from app.people.auth import ROLES, Permission, allowed

    may = {role: {p.value for p in Permission if allowed(role, p)} for role in ROLES}
    operator = {"tasks", "alarms", "acknowledge"}
    engineer = operator | {"station", "control", "model", "activate", "simulate", "audit"}
    assert may == {
        "operator": operator,
        "engineer": engineer,
        "auditor": {"alarms", "audit"},
        "admin": engineer | {"users"},
    }
    assert not any(allowed("superuser", p) for p in Permission)
