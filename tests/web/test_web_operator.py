"""The operator's forms: maintenance steps checked by name, alarms acknowledged with a note,
shelved for a limited time and unshelved; each recorded with the operator's name."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select

from app.store.tables import AuditRecord
from tests.support.stations import RunningStation


def test_a_maintenance_step_must_exist_and_be_asked_for(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")

    def done(transition: str) -> Any:
        return client.post(
            "/tasks/maintenance", data={"transition": transition, "csrf_token": token}
        )

    # refused: back to the page (a redirect, followed), which says why
    unknown = done("operator.move_r2_hom")
    assert unknown.status_code == 200 and "operator.move_r2_home" in unknown.text
    not_asked = done("operator.move_r2_home")
    assert not_asked.status_code == 200 and "not a maintenance step asked for now" in not_asked.text
    assert station.live.view.state.values["r2.pos"] == "home"  # nothing happened


def test_alarms_are_acknowledged_with_a_note_shelved_and_unshelved(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "operator")
    title, scenario = station.built.server.experiments["e5_r2_disconnects_clear"]
    station.live.play_experiment(scenario, title, "engineer").result(10)
    key = "resource:r2"
    station.wait(lambda: any(a.key == key for a in station.live.view.alarms), 60)
    page = client.get("/alarms")
    assert "robot 2 is not answering" in page.text and 'data-key="resource:r2"' in page.text

    form = {"key": key, "note": "r2 taken by the other station", "csrf_token": token}
    assert client.post("/alarms/acknowledge", data=form).status_code == 200
    alarm = next(a for a in station.live.view.alarms if a.key == key)
    assert str(alarm.state) == "acknowledged" and alarm.acked_by == "operator"
    again = client.post("/alarms/acknowledge", data=form, follow_redirects=False)
    assert again.status_code == 303 and "already acknowledged" in client.get("/alarms").text

    def shelve(minutes: str) -> Any:
        form = {"key": key, "minutes": minutes, "note": "known", "csrf_token": token}
        return client.post("/alarms/shelve", data=form)

    too_long = shelve("600")
    assert too_long.status_code == 200 and "less than or equal to" in too_long.text
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
    changes = [r for r in by_operator if not r[0].endswith(" refused")]
    assert len(changes) == 3  # acknowledged, shelved, unshelved
    refusals = sorted(r[0] for r in by_operator if r[0].endswith(" refused"))
    assert refusals == ["acknowledge refused", "shelve refused"]  # as refused, never as done
    # the station's own changes are audited too: the alarm was raised when r2 went silent
    raised = [r for r in rows if r.subject == key and not r.user]
    assert raised and "condition appeared" in raised[0].detail


def test_a_tap_that_came_too_late_gets_the_fresh_card_and_a_word_not_an_error(
    station: RunningStation,
) -> None:
    """From htmx (another device was faster), a 409 or 404 of the task routes becomes the
    fresh card with a message in the card area; a plain form keeps its error."""
    client = station.client()
    token = station.login(client, "operator")
    htmx = {"HX-Request": "true", "X-CSRF-Token": token}
    idle = client.get("/fragments/tasks")
    assert 'data-activity="idle"' in idle.text and "Nothing to do" in idle.text
    late = client.post("/tasks/done", data={"card": "place_bp1"}, headers=htmx)
    assert late.status_code == 200 and "Already done on another device." in late.text
    assert 'data-testid="task-now"' in late.text
    gone = client.post(
        "/tasks/maintenance", data={"transition": "operator.move_r2_home"}, headers=htmx
    )
    assert gone.status_code == 200 and "This step is no longer needed." in gone.text
    decided = client.post("/tasks/approve", data={"step": "0"}, headers=htmx)
    assert decided.status_code == 200 and "Already decided on another device." in decided.text
    plan = client.post("/tasks/approve-plan", data={"steps": ["r1.goto_bp2"]}, headers=htmx)
    assert plan.status_code == 200 and "The plan changed or was decided meanwhile." in plan.text
    odd = {"steps": ["r1.goto_bp2"], "decision": "maybe"}
    assert client.post("/tasks/approve-plan", data=odd, headers=htmx).status_code == 422
    plain = client.post(
        "/tasks/done", data={"card": "place_bp1", "csrf_token": token}, follow_redirects=False
    )
    assert plain.status_code == 303  # a plain form: back to its page, which says why


def test_one_card_at_a_time_with_the_count_of_the_others(station: RunningStation) -> None:
    from app.pages.cards import CardKind, TaskCard
    from app.web.routes.operator import card_context

    shown = card_context(station.live.view)
    cards = [
        TaskCard(CardKind.APPROVAL, "approval-0", "Robot 1: move", "why", step=0, abnormal=True),
        TaskCard(CardKind.INSTRUCTION, "maintenance-x", "Move it", "why", step=1, of=2),
        TaskCard(CardKind.COMMAND, "card-a", "Place it", "why", card="a"),
    ]
    template = station.built.server.templates.get_template("_tasks.html")
    values = {**shown, "cards": cards, "view": station.live.view, "csrf_token": "t"}
    html = template.render(values)
    assert html.count('class="card waits') == 1 and 'id="approval-0"' in html
    assert "Abnormal \u2014 approve?" in html and "· 2 more" in html
    assert 'data-count="3"' in html and 'data-title="Approve: Robot 1: move"' in html


def test_a_card_goes_when_the_engineer_cancels_its_intention(station: RunningStation) -> None:
    from app.pages.cards import task_cards
    from planner.runner import CancelIntention

    client = station.client()
    station.login(client, "operator")
    title, scenario = station.built.server.experiments["e1_bolt_undone"]
    station.live.play_experiment(scenario, title, "engineer").result(10)
    station.wait(lambda: bool(task_cards(station.live.view)), 60)
    assert 'data-kind="command"' in client.get("/fragments/tasks").text
    station.live.act(CancelIntention(user="engineer", name="tighten_bolts")).result(10)
    station.wait(lambda: not task_cards(station.live.view), 10)
    assert 'data-testid="no-tasks"' in client.get("/fragments/tasks").text
