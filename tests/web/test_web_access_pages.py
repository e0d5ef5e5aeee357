"""The access points of issue 16: a refusal speaks plainly ("Your role (auditor) cannot see
this page.", for every role, without permission ids) and links only to pages the role may
open; a wrong password keeps the name; /favicon.ico answers."""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from app.people.auth import ROLES
from tests.support.stations import RunningStation, form_token, start_station

# a page each role may not open, and the pages it may (the top bar's order)
REFUSED = {
    "operator": ("/audit", ["/", "/alarms"]),
    "engineer": ("/users", ["/", "/alarms", "/station", "/model", "/audit"]),
    "auditor": ("/station", ["/alarms", "/audit"]),
}


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(tmp_path_factory.mktemp("access"))
    yield running
    running.stop()


def places(html: str) -> list[str]:
    found = re.search(r'<nav aria-label="Pages you can open">(.*?)</nav>', html, re.S)
    assert found, "no links to the pages the role may open"
    return re.findall(r'href="([^"]+)"', found.group(1))


@pytest.mark.parametrize("role", sorted(REFUSED))
def test_a_refused_page_says_so_plainly_and_links_to_the_roles_pages(
    station: RunningStation, role: str
) -> None:
    client = station.client()
    station.login(client, role)
    page, allowed = REFUSED[role]
    answer = client.get(page)
    assert answer.status_code == 403
    text = answer.text.replace("&#39;", "'")
    assert f"Your role ({role}) cannot see this page." in text
    assert "needs" not in text and "permission" not in text
    assert not re.search(r"\ba (admin|auditor|engineer|operator)\b", text)
    assert places(answer.text) == allowed
    for href in allowed:  # and each of them opens
        assert client.get(href, follow_redirects=False).status_code == 200, href


def test_a_refused_action_says_so_and_the_api_names_the_permission(
    station: RunningStation,
) -> None:
    client = station.client()
    token = station.login(client, "auditor")
    answer = client.post("/alarms/acknowledge", data={"key": "x", "csrf_token": token})
    assert answer.status_code == 403
    assert "Your role (auditor) cannot do this." in answer.text
    bearer = {"Authorization": f"Bearer {station.token(client, 'auditor')}"}
    api = station.client().get("/api/tasks", headers=bearer)
    assert api.status_code == 403
    assert api.json()["detail"] == (
        "your role (auditor) cannot do this (it needs the 'tasks' permission)"
    )
    assert set(REFUSED) | {"admin"} == set(ROLES)


def test_a_wrong_password_keeps_the_name_and_asks_for_the_password(
    station: RunningStation,
) -> None:
    client = station.client()
    form = {"name": "engineer", "password": "not-the-password"}
    form["csrf_token"] = form_token(client.get("/login").text)
    answer = client.post("/login", data=form)
    assert answer.status_code == 401 and "wrong user name or password" in answer.text
    name = re.search(r'<input id="name"[^>]*>', answer.text, re.S)
    password = re.search(r'<input id="password"[^>]*>', answer.text, re.S)
    assert name and password
    assert 'value="engineer"' in name.group(0) and "autofocus" not in name.group(0)
    assert "autofocus" in password.group(0)
    fresh = client.get("/login").text  # a first visit starts at the name
    first = re.search(r'<input id="name"[^>]*>', fresh, re.S)
    assert first and "autofocus" in first.group(0)


def test_the_favicon_answers(station: RunningStation) -> None:
    client: TestClient = station.client()
    icon = client.get("/favicon.ico")
    assert icon.status_code == 200
    assert icon.headers["content-type"] == "image/x-icon"
    assert icon.content[:4] == b"\x00\x00\x01\x00" and len(icon.content) < 4096  # an ICO
    assert '<link rel="icon" href="/favicon.ico"' in client.get("/login").text
