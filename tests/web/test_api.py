"""The JSON API as a line system (MES) uses it: bearer tokens, roles, actions and answers.

One demo station for the module (starting one takes seconds).  The tests that change the
station put it back (restart mode left, r2 reconnected); the one that starts production
comes last.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from hw.simulated import Fault
from tests.support.stations import RunningStation, start_station

ROLES = ("operator", "engineer", "auditor", "admin")
BROKEN_MODEL = """\
variables:
  - {name: x, domain: bool, initial: false}
transitions:
  - {name: t, guard: "x && y", actions: ["x := true"]}
"""


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(Path(tmp_path_factory.mktemp("api")))
    yield running
    running.stop()


@pytest.fixture(scope="module")
def client(station: RunningStation) -> TestClient:
    return station.client()


@pytest.fixture(scope="module")
def auth(station: RunningStation) -> dict[str, dict[str, str]]:
    """Bearer headers per role (each user signed in once, in a client of its own)."""
    tokens = {role: station.token(station.client(), role) for role in ROLES}
    return {role: {"Authorization": f"Bearer {token}"} for role, token in tokens.items()}


def kinds(answer: dict[str, Any]) -> list[tuple[str, str]]:
    return [(e["kind"], e["subject"]) for e in answer["events"]]


def station_state(client: TestClient, auth: dict[str, dict[str, str]]) -> dict[str, Any]:
    response = client.get("/api/station", headers=auth["engineer"])
    assert response.status_code == 200, response.text
    state: dict[str, Any] = response.json()
    return state


def test_without_a_valid_token_the_api_answers_401(client: TestClient) -> None:
    response = client.get("/api/station")
    assert response.status_code == 401
    assert "POST /api/token" in response.json()["detail"]
    response = client.post("/api/intentions/assemble_engine/start")
    assert response.status_code == 401
    bad = {"Authorization": "Bearer not-a-token"}
    response = client.get("/api/tasks", headers=bad)
    assert response.status_code == 401
    assert "invalid, expired or revoked" in response.json()["detail"]


def test_roles_limit_what_a_caller_may_do(
    client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    response = client.post("/api/models/1/activate", headers=auth["operator"])
    assert response.status_code == 403
    assert response.json()["detail"] == (
        "your role (operator) cannot do this (it needs the 'activate' permission)"
    )
    for path in ("/api/intentions/assemble_engine/start", "/api/restart"):
        response = client.post(path, headers=auth["auditor"], json={"mode": "leave"})
        assert response.status_code == 403, path
    response = client.post(
        "/api/alarms/acknowledge", headers=auth["auditor"], json={"key": "resource:r2"}
    )
    assert response.status_code == 403
    assert client.get("/api/station", headers=auth["auditor"]).status_code == 403
    assert client.get("/api/station", headers=auth["operator"]).status_code == 200
    assert client.get("/api/audit", headers=auth["operator"]).status_code == 403
    assert client.get("/api/audit", headers=auth["auditor"]).status_code == 200
    assert client.get("/api/models", headers=auth["operator"]).status_code == 403


def test_the_station_lists_version_resources_intentions_and_operations(
    client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    state = station_state(client, auth)
    assert state["model"]["number"] == 1
    assert state["restart"] is False
    resources = {r["name"]: r for r in state["resources"]}
    assert resources["r2"]["available"] is True and "r2.pos" in resources["r2"]["variables"]
    assert state["intentions"] == {"assemble_engine": "i", "tighten_bolts": "i"}
    assert set(state["operations"].values()) == {"i"} and "home_r1" in state["operations"]
    assert state["goals"] == {} and state["failures"] == {}
    assert state["plans"]["operations"] is None
    assert state["variables"]["r1.pos"] == "home"


def test_an_unknown_name_is_a_404_with_a_suggestion(
    client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    engineer = auth["engineer"]
    response = client.post("/api/intentions/assemble_engin/start", headers=engineer)
    assert response.status_code == 404
    detail = response.json()["detail"]
    assert detail == "there is no intention 'assemble_engin'; did you mean 'assemble_engine'?"
    response = client.post("/api/operations/home_r3/reset", headers=engineer)
    assert response.status_code == 404 and "did you mean 'home_r" in response.json()["detail"]
    response = client.post("/api/effects/r1.goto.arive/reenable", headers=engineer)
    assert "did you mean 'r1.goto.arrive'" in response.json()["detail"]
    response = client.post("/api/maintenance/operator.reset_r1_t/done", headers=auth["operator"])
    assert response.status_code == 404
    assert "did you mean 'operator.reset_r1_tc'" in response.json()["detail"]
    response = client.post(
        "/api/estimated",
        headers=engineer,
        json={"variable": "bp1.stat", "value": "placed", "reason": "checked"},
    )
    assert response.status_code == 404 and "'bp1.state'" in response.json()["detail"]
    response = client.get("/api/models/99", headers=engineer)
    assert response.status_code == 404
    response = client.post(
        "/api/alarms/acknowledge", headers=auth["operator"], json={"key": "resource:r9"}
    )
    assert response.status_code == 404


def test_a_refused_action_is_a_409_with_the_runners_reason(
    client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    engineer = auth["engineer"]
    response = client.post("/api/operations/home_r1/reset", headers=engineer)
    assert response.status_code == 409
    assert response.json()["detail"] == "home_r1: operations are reset in restart mode"
    response = client.post("/api/effects/r1.goto.arrive/reenable", headers=engineer)
    assert response.status_code == 409
    assert response.json()["detail"] == "r1.goto.arrive: the effect is not timed out"
    response = client.post(
        "/api/approvals/0", headers=auth["operator"], json={"decision": "approve"}
    )
    assert response.status_code == 409 and "no such recovery step" in response.json()["detail"]
    response = client.post(
        "/api/recovery-plan",
        headers=auth["operator"],
        json={"decision": "approve", "steps": ["r1.goto_bp2"]},
    )
    assert response.status_code == 409
    assert "there is no recovery plan to decide on" in response.json()["detail"]
    response = client.post("/api/maintenance/operator.reset_r1_tc/done", headers=auth["operator"])
    assert response.status_code == 409
    assert "not a maintenance step asked for now" in response.json()["detail"]
    response = client.post("/api/cards/place_bolts/done", headers=auth["operator"])
    assert response.status_code == 409 and "no longer shown" in response.json()["detail"]


def test_bodies_that_do_not_fit_are_422(
    client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    engineer, operator = auth["engineer"], auth["operator"]
    response = client.post("/api/restart", headers=engineer, json={"mode": "enter"})
    assert response.status_code == 422 and "reason" in response.json()["detail"]
    response = client.post("/api/restart", headers=engineer, json={"mode": "pause"})
    assert response.status_code == 422 and response.json()["errors"][0]["loc"][-1] == "mode"
    response = client.post("/api/approvals/0", headers=operator, json={"decision": "maybe"})
    assert response.status_code == 422
    response = client.post("/api/approvals/-1", headers=operator, json={"decision": "approve"})
    assert response.status_code == 422
    for bad in ({"decision": "approve"}, {"decision": "approve", "steps": []}, {"steps": ["a"]}):
        response = client.post("/api/recovery-plan", headers=operator, json=bad)
        assert response.status_code == 422, bad
    response = client.post(
        "/api/alarms/shelve", headers=operator, json={"key": "resource:r2", "minutes": 0}
    )
    assert response.status_code == 422 and "minutes" in response.json()["detail"]
    response = client.post("/api/restart", headers=engineer, content=b"{not json")
    assert response.status_code == 422
    response = client.post(
        "/api/estimated",
        headers=engineer,
        json={"variable": "bp1.state", "value": "glued", "reason": "checked"},
    )
    assert response.status_code == 422
    assert "use one of empty, placed, tightened" in response.json()["detail"]


def test_restart_mode_reset_and_estimated_values(
    client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    engineer = auth["engineer"]
    response = client.post(
        "/api/restart", headers=engineer, json={"mode": "enter", "reason": "jam at r1"}
    )
    assert response.status_code == 200, response.text
    assert ("restart", "entered") in kinds(response.json())
    entered = next(e for e in response.json()["events"] if e["kind"] == "restart")
    assert entered["detail"] == {"user": "engineer", "reason": "jam at r1"}
    assert station_state(client, auth)["restart"] is True
    response = client.post("/api/operations/home_r1/reset", headers=engineer)
    assert response.status_code == 200, response.text
    assert ("operator", "reset operation") in kinds(response.json())
    response = client.post(
        "/api/estimated",
        headers=engineer,
        json={"variable": "bp1.state", "value": "placed", "reason": "placed by hand"},
    )
    assert response.status_code == 200, response.text
    assert ("operator", "set estimated") in kinds(response.json())
    assert station_state(client, auth)["variables"]["bp1.state"] == "placed"
    response = client.post(
        "/api/estimated",
        headers=engineer,
        json={"variable": "bp1.state", "value": "empty", "reason": "removed again"},
    )
    assert response.status_code == 200
    response = client.post("/api/restart", headers=engineer, json={"mode": "leave"})
    assert response.status_code == 200
    assert ("restart", "left") in kinds(response.json())
    assert station_state(client, auth)["restart"] is False


def test_models_are_saved_listed_and_a_broken_one_is_a_422_with_located_problems(
    station: RunningStation, client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    engineer = auth["engineer"]
    response = client.post("/api/models", headers=engineer, json={"text": BROKEN_MODEL})
    assert response.status_code == 422
    answer = response.json()
    assert answer["problems"] == [
        {"line": 4, "column": 28, "message": "in the guard of transition 't': unknown variable 'y'"}
    ]
    assert "line 4, column 28" in answer["detail"]
    text = station.live.view.model.text
    response = client.post(
        "/api/models", headers=engineer, json={"text": text + "\n# a comment\n", "note": "copy"}
    )
    assert response.status_code == 201, response.text
    assert response.json() == {"number": 2, "saved": True, "message": ""}
    listed = client.get("/api/models", headers=engineer).json()
    assert [(v["number"], v["active"], v["author"]) for v in listed] == [
        (2, False, "engineer"),
        (1, True, "sp serve"),
    ]
    one = client.get("/api/models/2", headers=engineer).json()
    assert one["note"] == "copy" and one["text"].endswith("# a comment\n")


def test_alarms_are_acknowledged_shelved_and_unshelved_by_key(
    station: RunningStation, client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    operator = auth["operator"]
    station.live.inject(Fault("disconnect", resource="r2"), "test: r2 off", "admin").result(10)

    def alarm() -> dict[str, Any] | None:
        alarms = client.get("/api/alarms", headers=operator).json()
        return next((a for a in alarms if a["key"] == "resource:r2"), None)

    try:
        station.wait(lambda: alarm() is not None, 15)
        raised = alarm()
        assert raised is not None
        assert raised["priority"] == "high" and raised["state"] == "unacknowledged"
        assert raised["resource"] == "r2" and raised["active"] is True
        assert not next(r for r in station_state(client, auth)["resources"] if r["name"] == "r2")[
            "available"
        ]
        response = client.post(
            "/api/alarms/acknowledge",
            headers=operator,
            json={"key": "resource:r2", "note": "r2 is at the next station"},
        )
        assert response.status_code == 200, response.text
        change = response.json()
        assert (change["before"], change["after"]) == ("unacknowledged", "acknowledged")
        assert change["user"] == "operator" and change["alarm"]["acked_by"] == "operator"
        again = client.post(
            "/api/alarms/acknowledge", headers=operator, json={"key": "resource:r2"}
        )
        assert again.status_code == 409 and "already acknowledged" in again.json()["detail"]
        response = client.post(
            "/api/alarms/shelve",
            headers=operator,
            json={"key": "resource:r2", "minutes": 5, "note": "known"},
        )
        assert response.status_code == 200, response.text
        assert response.json()["after"] == "shelved"
        assert response.json()["alarm"]["shelved_until"] is not None
        response = client.post(
            "/api/alarms/unshelve", headers=operator, json={"key": "resource:r2"}
        )
        assert response.status_code == 200, response.text
        assert response.json()["before"] == "shelved"
    finally:
        station.live.inject(Fault("reconnect", resource="r2"), "test: r2 on", "admin").result(10)
    station.wait(lambda: "r2" not in station.live.view.state.unavailable, 15)


def test_the_audit_log_shows_api_actions_with_the_callers_name(
    client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    response = client.get(
        "/api/audit", headers=auth["auditor"], params={"user": "engineer", "kind": "restart"}
    )
    assert response.status_code == 200, response.text
    page = response.json()
    assert [r["subject"] for r in page["records"]] == ["left", "entered"]
    assert page["records"][1]["detail"]["reason"] == "jam at r1"
    assert (page["total"], page["page"], page["pages"], page["page_size"]) == (2, 1, 1, 100)
    beyond = client.get("/api/audit", headers=auth["auditor"], params={"page": 7}).json()
    assert beyond["page"] == beyond["pages"]
    response = client.get("/api/audit", headers=auth["auditor"], params={"page": 0})
    assert response.status_code == 422


def test_start_an_intention_confirm_the_operators_card_and_cancel(
    station: RunningStation, client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    engineer, operator = auth["engineer"], auth["operator"]
    response = client.post("/api/intentions/assemble_engine/start", headers=engineer)
    assert response.status_code == 200, response.text
    events = kinds(response.json())
    assert ("operator", "start intention") in events
    assert ("intention", "assemble_engine") in events
    started = next(e for e in response.json()["events"] if e["kind"] == "intention")
    assert started["detail"]["after"] == "e"
    # the plan is made beside the loop (a planning worker): it comes a few rounds later
    station.wait(lambda: "e" in station_state(client, auth)["operations"].values(), 30)
    state = station_state(client, auth)
    assert state["intentions"]["assemble_engine"] == "e"
    executing = [name for name, st in state["operations"].items() if st == "e"]
    assert executing and set(executing) <= state["goals"].keys()
    steps = state["plans"]["operations"]
    assert steps and all(set(s["after"]) <= set(range(s["index"])) for s in steps)
    assert any(s["after"] for s in steps)
    # a model cannot be swapped under a running intention
    response = client.post("/api/models/2/activate", headers=engineer)
    assert response.status_code == 409
    assert "activate when it is idle or in restart mode" in response.json()["detail"]

    def command_cards() -> list[dict[str, Any]]:
        cards = client.get("/api/tasks", headers=operator).json()
        return [c for c in cards if c["kind"] == "command"]

    station.wait(lambda: bool(command_cards()), 30)
    card = command_cards()[0]["card"]
    response = client.post(f"/api/cards/{card}/done", headers=operator)
    assert response.status_code == 200, response.text
    assert response.json()["events"][0]["detail"] == {"user": "operator", "card": card}
    response = client.post("/api/intentions/assemble_engine/cancel", headers=engineer)
    assert response.status_code == 200, response.text
    assert ("operator", "cancel intention") in kinds(response.json())


def test_a_line_system_drives_a_forbidden_state_recovery_through_the_task_cards(
    station: RunningStation, client: TestClient, auth: dict[str, dict[str, str]]
) -> None:
    """E2: oil filters mounted too early.  Whatever card shows, the caller does it: confirms
    command cards, approves recovery steps, reports maintenance steps done."""
    operator, engineer = auth["operator"], auth["engineer"]
    listed = client.get("/api/experiments", headers=engineer).json()
    assert [x["group"] for x in listed[:10]] == [""] * 9 + ["faults"]  # E1-E9 first
    assert listed[1]["id"] == "e2_oil_filter_early"
    assert listed[1]["intentions"] == ["tighten_bolts"]
    assert client.get("/api/experiments", headers=operator).status_code == 403
    response = client.post("/api/experiments/e2_oil_filter/play", headers=engineer)
    assert response.status_code == 404
    assert "did you mean 'e2_oil_filter_early'" in response.json()["detail"]
    response = client.post("/api/experiments/e2_oil_filter_early/play", headers=engineer)
    assert response.status_code == 200, response.text
    assert response.json()["title"].startswith("E2:")
    answered: list[tuple[str, str]] = []

    def finished() -> bool:
        for card in client.get("/api/tasks", headers=operator).json():
            if card["kind"] == "command":
                response = client.post(f"/api/cards/{card['card']}/done", headers=operator)
            elif card["kind"] == "approval":
                response = client.post(
                    f"/api/approvals/{card['step']}", headers=operator, json={"decision": "approve"}
                )
            else:
                response = client.post(
                    f"/api/maintenance/{card['transition']}/done", headers=operator
                )
            assert response.status_code in (200, 409), response.text
            if response.status_code == 200:
                answered.append((card["kind"], card["transition"] or card["card"]))
        return bool(station_state(client, auth)["intentions"]["tighten_bolts"] == "f")

    station.wait(finished, 45)
    # the way out is the operator's own step: an instruction, with nothing to approve
    assert ("approval", "operator.remove_oil_filters") not in answered
    assert ("instruction", "operator.remove_oil_filters") in answered
    assert ("command", "place_bp1") in answered
    records = client.get(
        "/api/audit", headers=auth["auditor"], params={"user": "operator", "kind": "operator"}
    ).json()["records"]
    assert {"maintenance done", "card done"} <= {r["subject"] for r in records}
