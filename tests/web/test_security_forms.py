"""Issue 26: the audit holds only what happened, and a reload sends no form again.  A page's
form sent without htmx is answered 303 to its page, carried out or refused, and the page
says the outcome once; a refusal past the gate is audited as refused (never as done), once:
the runner's own refusals are its `refused` events, not a second record."""

from __future__ import annotations

import html
import json
import re
from typing import Any

import pytest
from starlette.testclient import TestClient

from tests.support.stations import RunningStation

HX = {"HX-Request": "true"}


def records(station: RunningStation, kind: str) -> list[dict[str, Any]]:
    with station.built.server.store.engine.connect() as connection:
        rows = connection.exec_driver_sql(
            "SELECT user, subject, detail FROM audit WHERE kind = ? ORDER BY id", (kind,)
        ).all()
    return [{"user": u, "subject": s, **json.loads(d)} for u, s, d in rows]


def flashes(page: str, kind: str) -> list[str]:
    found = re.findall(rf'class="flash flash--{kind}" role="alert">([^<]*)<', page)
    return [html.unescape(f) for f in found]


def sent(client: TestClient, token: str, path: str, **form: str) -> tuple[str, str]:
    """A plain form: answered 303; where to, and the error the page then says once."""
    answer = client.post(path, data={**form, "csrf_token": token}, follow_redirects=False)
    assert answer.status_code == 303, (path, answer.status_code, answer.text[:300])
    location = answer.headers["location"]
    page = client.get(location).text
    assert not flashes(client.get(location).text, "error"), "said more than once"
    [said] = flashes(page, "error") or [""]
    return location, said


REFUSED = [
    # path, form, the page it returns to, what it says, the audit kind and subject
    (
        "/alarms/acknowledge",
        {"key": "resource:r9"},
        "/alarms",
        "no alarm resource:r9",
        "alarm",
        "acknowledge refused",
    ),
    (
        "/alarms/shelve",
        {"key": "resource:r9", "minutes": "9999"},
        "/alarms",
        "minutes:",
        "alarm",
        "shelve refused",
    ),
    (
        "/tasks/maintenance",
        {"transition": "no.such_step"},
        "/",
        "there is no maintenance transition",
        "refused",
        "maintenance refused",
    ),
    (
        "/station/intentions/start",
        {"name": "no_such_intention"},
        "/station",
        "there is no intention",
        "refused",
        "intentions/start refused",
    ),
    (
        "/simulation/experiment",
        {"experiment": "no_such_experiment"},
        "/simulation",
        "there is no experiment",
        "experiment",
        "experiment refused",
    ),
]


@pytest.mark.parametrize(("path", "form", "page", "says", "kind", "subject"), REFUSED)
def test_a_refused_form_redirects_says_why_once_and_is_audited_as_refused(
    station: RunningStation,
    path: str,
    form: dict[str, str],
    page: str,
    says: str,
    kind: str,
    subject: str,
) -> None:
    client = station.client()
    token = station.login(client, "admin")
    location, said = sent(client, token, path, **form)
    assert location == page and says in said
    [record] = [r for r in records(station, kind) if r["subject"] == subject]
    assert record["user"] == "admin" and record["request"] == f"POST {path}"
    assert says in record["why"] and record["status"] in (404, 409, 422)


def test_a_form_carried_out_redirects_and_says_so_once(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "engineer")
    answer = client.post(
        "/station/restart/leave", data={"csrf_token": token}, follow_redirects=False
    )
    assert (answer.status_code, answer.headers["location"]) == (303, "/station")
    assert flashes(client.get("/station").text, "message") == ["Restart mode left."]
    assert flashes(client.get("/station").text, "message") == []


def test_the_runners_refusal_is_audited_once(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")
    before = len(records(station, "refused"))
    location, said = sent(client, token, "/tasks/approve", step="9999")
    assert location == "/" and "no such recovery step" in said
    new = records(station, "refused")[before:]
    assert len(new) == 1, new  # the runner's refused event, not a second record
    assert new[0]["user"] == "operator"


def test_htmx_keeps_its_fragment_and_the_refusal_is_audited(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")
    form = {"key": "resource:r9", "csrf_token": token}
    answer = client.post("/alarms/unshelve", data=form, headers=HX, follow_redirects=False)
    assert answer.status_code == 409 and "no alarm resource:r9" in answer.text
    assert [r["subject"] for r in records(station, "alarm")] == ["unshelve refused"]


def test_refusals_at_the_gate_are_neither_redirected_nor_audited(
    station: RunningStation,
) -> None:
    client = station.client()
    token = station.login(client, "auditor")
    answer = client.post(
        "/alarms/acknowledge",
        data={"key": "resource:r9", "csrf_token": token},
        follow_redirects=False,
    )
    assert answer.status_code == 403
    forged = client.post(
        "/alarms/acknowledge", data={"key": "x", "csrf_token": "forged"}, follow_redirects=False
    )
    assert forged.status_code == 403
    assert not [r for r in records(station, "alarm") if r["subject"].endswith("refused")]


def test_an_api_refusal_is_audited_as_refused_and_answered_in_json(
    station: RunningStation,
) -> None:
    token = station.token(station.client(), "engineer")
    api = station.client()
    api.headers["Authorization"] = f"Bearer {token}"
    answer = api.post("/api/alarms/acknowledge", json={"key": "resource:r9"})
    assert answer.status_code == 404 and "detail" in answer.json()
    [record] = [r for r in records(station, "alarm") if r["subject"].endswith("refused")]
    assert record["subject"] == "acknowledge refused" and record["user"] == "engineer"
    assert record["request"] == "POST /api/alarms/acknowledge" and record["status"] == 404
