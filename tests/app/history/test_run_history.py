"""Runs as the live station records them and the history reads them back: an experiment
played on a running station, the operator working through its cards."""

from __future__ import annotations

import dataclasses
import json

from sqlalchemy import select

from app.history.done_today import done_today
from app.history.run_history import run_history
from app.station.runs import Outcome
from app.store.tables import AuditRecord
from planner.runner import EventKind
from tests.support.stations import RunningStation
from tests.web.test_web_alarms import work_through


def run_records(station: RunningStation) -> list[AuditRecord]:
    store = station.built.server.store
    with store.sessions() as session:
        query = select(AuditRecord).where(AuditRecord.kind == EventKind.RUN)
        return list(session.scalars(query.order_by(AuditRecord.id)))


def test_a_played_experiment_is_one_recorded_run_from_its_start_to_its_finish(
    station: RunningStation,
) -> None:
    client = station.client()
    token = station.login(client, "operator")
    live = station.live
    title, scenario = station.built.server.experiments["e1_bolt_undone"]
    live.play_experiment(scenario, title, "engineer").result(10)
    station.wait(lambda: live.view.state.intentions.get("tighten_bolts") != "f", 10)
    work_through(station, client, token, "tighten_bolts")
    station.wait(lambda: len(run_records(station)) >= 2, 10)

    started, ended = run_records(station)[-2:]
    assert (started.subject, ended.subject) == ("started", "ended")
    why = json.loads(started.detail)["why"]
    assert why == "engineer started tighten every bolt pair on an idle station"
    assert json.loads(ended.detail)["outcome"] == "finished"
    assert started.resource == ended.resource == ""

    history = run_history(station.built.server.store, live.name)
    newest = history.run(None)
    assert newest is not None
    assert (newest.first, newest.last) == (started.id, ended.id)
    assert (newest.intentions, newest.outcome) == (("tighten_bolts",), Outcome.FINISHED)
    kinds = [h.kind for h in history.happenings if newest.first <= h.key <= newest.last]
    assert EventKind.INTENTION in kinds and EventKind.PLAN in kinds

    today = done_today(
        station.built.server.store, live.name, "operator", live.model.station, live.model.words,
        live.wall(),
    )  # fmt: skip
    # the demo model marks assembling the engine as its product: tightening alone is none
    assert today.engines == ()
    unmarked = dataclasses.replace(
        live.model.station,
        intentions=tuple(
            dataclasses.replace(i, product=False) for i in live.model.station.intentions
        ),
    )  # a model that marks no product: every finished run counts, as before
    today = done_today(
        station.built.server.store, live.name, "operator", unmarked, live.model.words, live.wall()
    )
    assert [item.text for item in today.engines] == ["Tighten every bolt pair: complete"]
