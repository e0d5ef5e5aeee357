"""The operator's forms: maintenance steps checked by name, alarms acknowledged with a note,
shelved for a limited time and unshelved; each recorded with the operator's name."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select

from app.store.tables import AuditRecord
from tests.stations import RunningStation


def test_a_maintenance_step_must_exist_and_be_asked_for(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")

    def done(transition: str) -> Any:
        return client.post(
            "/tasks/maintenance", data={"transition": transition, "csrf_token": token}
        )

    unknown = done("operator.move_r2_hom")
    assert unknown.status_code == 404 and "operator.move_r2_home" in unknown.text
    not_asked = done("operator.move_r2_home")
    assert not_asked.status_code == 409 and "not a maintenance step asked for now" in not_asked.text
    assert station.live.view.state.values["r2.pos"] == "home"  # nothing happened


def test_alarms_are_acknowledged_with_a_note_shelved_and_unshelved(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")
    title, scenario = station.built.server.experiments["e5_r2_disconnects_clear"]
    station.live.play_experiment(scenario, title, "engineer").result(10)
    key = "resource:r2"
    station.wait(lambda: any(a.key == key for a in station.live.view.alarms), 60)
    page = client.get("/alarms")
    assert "r2 is not answering" in page.text and 'data-key="resource:r2"' in page.text

    form = {"key": key, "note": "r2 taken by the other station", "csrf_token": token}
    assert client.post("/alarms/acknowledge", data=form).status_code == 200
    alarm = next(a for a in station.live.view.alarms if a.key == key)
    assert str(alarm.state) == "acknowledged" and alarm.acked_by == "operator"
    again = client.post("/alarms/acknowledge", data=form)
    assert again.status_code == 409 and "already acknowledged" in again.text

    def shelve(minutes: str) -> Any:
        form = {"key": key, "minutes": minutes, "note": "known", "csrf_token": token}
        return client.post("/alarms/shelve", data=form)

    too_long = shelve("600")
    assert too_long.status_code == 422
    shelved = shelve("30")
    assert shelved.status_code == 200
    assert str(next(a for a in station.live.view.alarms if a.key == key).state) == "shelved"
    assert (
        client.post("/alarms/unshelve", data={"key": key, "csrf_token": token}).status_code == 200
    )
    assert str(next(a for a in station.live.view.alarms if a.key == key).state) != "shelved"

    with station.built.server.store.sessions() as session:
        rows = session.scalars(select(AuditRecord).where(AuditRecord.kind == "alarm")).all()
    by_operator = [(r.subject, r.user, r.detail) for r in rows if r.user == "operator"]
    assert any("r2 taken by the other station" in detail for _, _, detail in by_operator)
    assert len(by_operator) == 3  # acknowledged, shelved, unshelved
    # the station's own changes are audited too: the alarm was raised when r2 went silent
    raised = [r for r in rows if r.subject == key and not r.user]
    assert raised and "condition appeared" in raised[0].detail
