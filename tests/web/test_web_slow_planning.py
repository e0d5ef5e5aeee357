"""The web station while planning is slow: requests are answered within a round or two,
never after the 30 s a 503 waits for, because queries run beside the loop."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.support.stations import RunningStation, start_station

DELAY = 2.0  # every planning query takes this long more


@pytest.fixture
def slow(tmp_path: Path) -> Iterator[RunningStation]:
    # E2's way out without the rejected step is a long recovery plan (30 steps, seconds of
    # planning on a busy machine): this test is about answers while it plans, not the budget
    running = start_station(tmp_path, planning_delay=DELAY, planning_budget=120.0)
    yield running
    running.stop()


def test_a_reject_is_answered_at_once_while_the_station_plans(slow: RunningStation) -> None:
    client = slow.client()
    operator = {"Authorization": f"Bearer {slow.token(client, 'operator')}"}
    engineer = {"Authorization": f"Bearer {slow.token(client, 'engineer')}"}
    played = client.post("/api/experiments/e2_oil_filter_early/play", headers=engineer)
    assert played.status_code == 200, played.text

    def approvals() -> list[dict[str, object]]:
        """The recovery steps a person may reject: approvals of the station's steps and the
        operator's own recovery instructions; the watch cards are confirmed on the way."""
        cards = client.get("/api/tasks", headers=operator).json()
        for card in cards:
            if card["kind"] == "command":
                client.post(f"/api/cards/{card['card']}/done", headers=operator)
        return [c for c in cards if c["kind"] == "approval" or c["rejectable"]]

    slow.wait(lambda: bool(approvals()), 120)
    step = approvals()[0]["step"]
    rejected = client.post(f"/api/approvals/{step}", headers=operator, json={"decision": "reject"})
    assert rejected.status_code == 200, rejected.text
    # the answers came before the new recovery plan (it takes DELAY more): the round that took
    # the reject did not wait for it, nor does the station's view meanwhile
    station = client.get("/api/station", headers=engineer)
    assert station.status_code == 200
    assert station.json()["plans"]["recovery"] is None  # the new plan is not there yet
    slow.wait(lambda: bool(approvals()), 60)  # then it is, with another step to approve
