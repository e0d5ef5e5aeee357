"""Issue 15, point 8 (sizes): what the editor allows, the server takes.  A model of 1.5 MB
saves through the editor's form (the form parser's 1 MB field limit refused it before); a
text past the editor's limit gets the editor's located message; every other request body
is held to 1 MiB, and a larger one is refused before it is parsed (413), never a 500."""

from __future__ import annotations

from bench.cells import station_text
from tests.support.stations import RunningStation


def test_a_model_of_one_and_a_half_megabytes_saves_through_the_form(
    station: RunningStation,
) -> None:
    client = station.client()
    token = station.login(client, "engineer")
    text = station_text(560)
    assert len(text.encode()) > 1_400_000
    form = {"text": text, "note": "big", "csrf_token": token}
    answer = client.post("/model/save", data=form, headers={"HX-Request": "true"})
    assert answer.status_code == 200, answer.text[:300]
    assert "Saved as version 2" in answer.text


def test_a_text_past_the_editors_limit_is_said_so(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "engineer")
    text = "# " + "x" * 2_000_000
    form = {"text": text, "csrf_token": token}
    answer = client.post("/model/validate", data=form, headers={"HX-Request": "true"})
    assert answer.status_code == 422
    assert "at most 2000000 characters" in answer.text
    answer = client.post("/model/validate", data=form, follow_redirects=False)
    assert answer.status_code == 303  # a form without htmx: redirected, the refusal shown once
    assert "at most 2000000 characters" in client.get(answer.headers["location"]).text


def test_other_bodies_are_held_to_a_megabyte(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "engineer")
    note = {"key": "resource:r1", "note": "n" * 2_000_000, "csrf_token": token}
    answer = client.post("/alarms/acknowledge", data=note)
    assert answer.status_code == 413, answer.text[:300]
    api = station.token(station.client(), "engineer")
    big = client.post(
        "/api/intentions/assemble_engine/start",
        content=b"{" + b" " * 2_000_000 + b"}",
        headers={"Authorization": f"Bearer {api}", "Content-Type": "application/json"},
    )
    assert big.status_code == 413
