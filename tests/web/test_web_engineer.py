"""The engineer's pages in-process: the station view and its controls, the model editor, the
simulation panel; permissions, CSRF, and a 4xx with a message for every bad input."""

from __future__ import annotations

import json
import re
from typing import Any

from fastapi.testclient import TestClient
from sqlalchemy import select

from app.store import versions
from app.store.tables import AuditRecord
from tests.support.paths import REPOSITORY
from tests.support.stations import MODEL, RunningStation

FAULTS = sorted((REPOSITORY / "models" / "scenarios" / "faults").glob("*.yaml"))

HX = {"hx-request": "true"}


def signed_in(station: RunningStation, name: str = "engineer") -> tuple[TestClient, str]:
    client = station.client()
    return client, station.login(client, name)


def post(client: TestClient, token: str, url: str, htmx: bool = True, **data: Any) -> Any:
    return client.post(
        url, data={"csrf_token": token, **data}, headers=HX if htmx else {}, follow_redirects=False
    )


def audit(station: RunningStation, kind: str, user: str) -> list[AuditRecord]:
    with station.built.server.store.sessions() as session:
        query = select(AuditRecord).where(AuditRecord.kind == kind, AuditRecord.user == user)
        return list(session.scalars(query))


def test_station_page_shows_the_station_and_only_engineers_reach_it(station: RunningStation):
    client, _ = signed_in(station)
    overview = client.get("/station")
    assert overview.status_code == 200
    for html in ('data-resource="r2"', 'data-intention="tighten_bolts"', "/station/details"):
        assert html in overview.text
    assert "Robot 2" in overview.text and "Tighten every bolt pair" in overview.text
    assert 'data-variable="frame.state"' not in overview.text  # the details are elsewhere
    assert 'hx-get="/station/fragments/overview"' in overview.text
    assert client.get("/station/fragments/overview").status_code == 200
    page = client.get("/station/details")
    assert page.status_code == 200
    shown = (
        'data-resource="r1"',
        'data-resource="r2"',
        'data-intention="tighten_bolts"',
        'data-operation="place_bp1"',
        'data-variable="frame.state"',
        'id="set-variable"',
    )
    for html in shown:
        assert html in page.text
    assert 'hx-trigger="sse:station"' in page.text
    assert client.get("/station/details", params={"variable": "bp9.state"}).status_code == 404
    form = client.get("/station/fragments/set-variable", params={"variable": "bp2.state"})
    values = re.search(r'<select id="set-variable-value"[^>]*>(.*?)</select>', form.text, re.S)
    assert values is not None
    assert re.findall(r'value="(\w+)"', values.group(1)) == ["empty", "placed", "tightened"]
    assert "not placed yet" in values.group(1)  # shown in words

    # each live part alone; unchanged since the client's last copy: 204, nothing to swap
    for part in ("status", "plans", "variables"):
        fragment = client.get(f"/station/fragments/{part}")
        assert fragment.status_code == 200
        digest = re.search(r'data-digest="(\w+)"', fragment.text)
        assert digest, part
    status = client.get("/station/fragments/status")
    digest = re.search(r'data-digest="(\w+)"', status.text)
    assert digest is not None
    again = client.get("/station/fragments/status", params={"seen": digest.group(1)})
    assert again.status_code == 204

    operator, operator_token = signed_in(station, "operator")
    for url in ("/station", "/station/fragments/plans", "/model", "/simulation"):
        assert operator.get(url).status_code == 403, url
    for url, data in (
        ("/station/intentions/start", {"name": "tighten_bolts"}),
        ("/station/restart/enter", {"reason": "look"}),
        ("/model/validate", {"text": "x"}),
        ("/simulation/experiment", {"experiment": "e1_bolt_undone"}),
    ):
        assert post(operator, operator_token, url, **data).status_code == 403, url

    # no CSRF token: refused before anything reaches the runner
    forged = client.post("/station/intentions/start", data={"name": "tighten_bolts"})
    assert forged.status_code == 403
    assert "expired" in forged.text
    assert station.live.view.state.intentions["tighten_bolts"] == "i"
    assert "tighten_bolts" not in station.live.view.state.auto_start


def test_controls_act_through_the_runner_and_are_audited(station: RunningStation):
    client, token = signed_in(station)
    live = station.live

    def set_variable(value: str, reason: str, variable: str = "frame.state") -> Any:
        data = {"variable": variable, "value": value, "reason": reason}
        return post(client, token, "/station/variables/set", **data)

    # the frame is on the MiR: set it on the engine (restart mode, with a reason) first
    missing = set_variable("on_engine", "  ")
    assert missing.status_code == 422
    assert "reason" in missing.text
    refused = set_variable("on_engine", "checked by hand")
    assert refused.status_code == 409
    assert "estimated variables are set in restart mode" in refused.text
    assert [r for r in audit(station, "refused", "engineer") if r.subject == "frame.state"]
    assert set_variable("on_engine", "x", "frame.stat").status_code == 404
    wrong = set_variable("in_the_air", "x")
    assert wrong.status_code == 422
    assert "on_mir, on_engine" in wrong.text
    assert set_variable("home", "x", "r1.pos").status_code == 404  # measured: not settable

    reset = post(client, token, "/station/operations/reset", name="place_bp1")
    assert reset.status_code == 409
    assert "operations are reset in restart mode" in reset.text
    unknown = post(client, token, "/station/operations/reset", name="place_bp9")
    assert unknown.status_code == 404
    assert "did you mean" in unknown.text
    assert post(client, token, "/station/intentions/start", name="tighten").status_code == 404
    assert post(client, token, "/station/effects/reenable", name="nothing").status_code == 404
    not_timed_out = post(client, token, "/station/effects/reenable", name="operator.confirm")
    assert not_timed_out.status_code == 409
    assert post(client, token, "/station/restart/enter", reason="").status_code == 422
    assert post(client, token, "/station/intentions/start").status_code == 422  # no name
    assert not live.view.state.restart_mode

    entered = post(client, token, "/station/restart/enter", reason="frame put on by hand")
    assert entered.status_code == 200
    assert 'data-testid="restart-mode"' in entered.text
    assert "frame put on by hand" in entered.text
    assert live.view.state.restart_mode
    done = set_variable("on_engine", "frame put on by hand")
    assert done.status_code == 200
    assert live.view.state.values["frame.state"] == "on_engine"
    assert "The ladder frame is on the engine: set." in done.text
    assert "(now on the engine)" in done.text  # the form comes back with the new value

    # an estimate that makes the state forbidden: warned, not done, until confirmed
    early = {"variable": "oil_filter1.state", "value": "mounted", "reason": "seen mounted"}
    warned = post(client, token, "/station/variables/set", **early)
    assert warned.status_code == 200
    assert warned.headers.get("hx-retarget") == "#set-variable"
    assert "data-forbidden-warning" in warned.text
    assert "oil filters only after every bolt pair is tightened" in warned.text
    assert 'name="forbidden" value="confirmed"' in warned.text
    assert 'value="seen mounted"' in warned.text  # what was typed stays
    assert live.view.state.values["oil_filter1.state"] == "none"
    confirmed = post(client, token, "/station/variables/set", forbidden="confirmed", **early)
    assert confirmed.status_code == 200
    assert live.view.state.values["oil_filter1.state"] == "mounted"
    back = {**early, "value": "none", "reason": "a mistake"}
    assert post(client, token, "/station/variables/set", **back).status_code == 200
    assert live.view.state.values["oil_filter1.state"] == "none"
    resetting = post(client, token, "/station/operations/reset", name="home_r1")
    assert resetting.status_code == 200
    # a plain form (no htmx) gets a redirect back
    assert post(client, token, "/station/restart/leave", htmx=False).status_code == 303
    assert not live.view.state.restart_mode

    started = post(client, token, "/station/intentions/start", name="tighten_bolts")
    assert started.status_code == 200
    assert "Tighten every bolt pair: started." in started.text
    assert "data-waits-for" not in started.text.split('id="intention-tighten_bolts"')[1][:600]
    station.wait(lambda: live.view.state.intentions["tighten_bolts"] == "e")
    station.wait(lambda: live.view.state.transition_plan is not None)
    plans = client.get("/station/fragments/plans").text
    assert 'data-plan="operations"' in plans
    assert 'data-plan="transitions"' in plans
    steps = re.findall(r'<g class="plan-node[^"]*" data-step="([^"]+)" data-status="(\w+)"', plans)
    assert any(status in ("started", "done") for _, status in steps)  # the first is under way
    assert {"tighten_bp1", "tighten_bp4"} <= {name for name, _ in steps}
    assert 'class="plan-edge' in plans  # the partial order's arrows
    texts = re.findall(r">([^<>]+)<", plans)  # what a person reads: words, no model names
    assert [t for t in texts if re.search(r"\b(r1|r2|nr)[._]\w", t)] == []
    assert "Place bolt pair 1" in texts
    assert not re.search(r"\b1 steps\b", plans)
    assert re.search(r'data-label="Time">\d\d:\d\d:\d\d<', plans)  # the time of day

    records = audit(station, "operator", "engineer")
    subjects = {r.subject for r in records}
    assert {"start intention", "set estimated", "reset operation"} <= subjects
    assert [r for r in audit(station, "restart", "engineer") if r.subject == "entered"]

    cancelled = post(client, token, "/station/intentions/cancel", name="tighten_bolts")
    assert cancelled.status_code == 200
    assert live.view.state.intentions["tighten_bolts"] == "i"


def bad_guard(text: str) -> tuple[str, int, int]:
    """The model with `r1.pos` misspelt in one guard, and where (line, column)."""
    needle = 'guard: "enabled && r1.pos == scan'
    at = text.index(needle) + needle.index("r1.pos")
    line = text.count("\n", 0, at) + 1
    column = at - (text.rfind("\n", 0, at) + 1) + 1
    return text[:at] + "r1.poss" + text[at + len("r1.pos") :], line, column


def test_model_editor_validates_saves_compares_and_activates(station: RunningStation):
    client, token = signed_in(station)
    live = station.live
    text = MODEL.read_text(encoding="utf-8")
    page = client.get("/model")
    assert page.status_code == 200
    assert 'id="model-text"' in page.text
    assert 'data-version="1"' in page.text

    bad, line, column = bad_guard(text)
    checked = post(client, token, "/model/validate", text=bad)
    assert checked.status_code == 200
    assert f'data-line="{line}" data-column="{column}"' in checked.text
    assert f"line {line}, column {column}: " in checked.text
    assert "unknown variable &#39;r1.poss&#39;" in checked.text
    assert "The model is valid" in post(client, token, "/model/validate", text=text).text
    assert 'data-line="1"' in post(client, token, "/model/validate", text="").text

    refused = post(client, token, "/model/save", text=bad, note="typo")
    assert refused.status_code == 422
    assert refused.headers["hx-retarget"] == "#model-errors"
    assert f'data-line="{line}"' in refused.text
    with station.built.server.store.sessions() as session:
        assert [v.number for v in versions.versions(session, live.name)] == [1]

    old = "description: the whole engine, every tool hung back and the robots parked"
    new = "description: the whole engine, every tool hung back, both robots parked"
    assert old in text
    saved = post(client, token, "/model/save", text=text.replace(old, new), note="wording")
    assert saved.status_code == 200
    assert 'data-version="2"' in saved.text
    assert "Saved as version 2" in saved.text
    with station.built.server.store.sessions() as session:
        row = versions.version(session, live.name, 2)
        assert row is not None and row.author == "engineer" and row.note == "wording"

    compared = client.get("/model/diff", params={"version": 2}, headers=HX)
    assert compared.status_code == 200
    assert re.search(r'<span class="del">-\s+' + re.escape(old), compared.text)
    assert re.search(r'<span class="add">\+\s+' + re.escape(new), compared.text)
    assert client.get("/model/diff", params={"version": 9}).status_code == 404
    assert client.get("/model/diff", params={"version": "two"}).status_code == 422
    assert client.get("/model", params={"version": 2}).text.count("both robots parked") == 1

    # activation waits for an idle station (or restart mode)
    started = post(client, token, "/station/intentions/start", name="assemble_engine")
    assert started.status_code == 200
    station.wait(lambda: live.view.state.intentions["assemble_engine"] == "e")
    busy = post(client, token, "/model/activate", version=2)
    assert busy.status_code == 409
    assert "running" in busy.text and "restart mode" in busy.text
    assert "Activation waits" in client.get("/model/fragments/station").text
    assert post(client, token, "/model/activate", version=9).status_code == 404
    assert post(client, token, "/model/activate", version="x").status_code == 422
    assert live.view.model.number == 1

    assert post(client, token, "/station/restart/enter", reason="new model").status_code == 200
    activated = post(client, token, "/model/activate", version=2)
    assert activated.status_code == 200, activated.text
    assert "Version 2 is active now" in activated.text
    assert live.view.model.number == 2
    assert [r for r in audit(station, "model", "engineer") if r.subject == "activated"]
    assert post(client, token, "/model/activate", version=2).status_code == 409  # already


def test_simulation_panel_plays_an_experiment(station: RunningStation):
    client, token = signed_in(station)
    live = station.live
    page = client.get("/simulation")
    assert page.status_code == 200
    experiments = sorted(station.built.server.experiments)
    assert len([k for k in experiments if re.fullmatch(r"e\d_\w+", k)]) == 9
    assert len(experiments) == 9 + len(FAULTS) - 2  # no fault scenario that plans slowly
    for key in experiments:
        assert f'data-experiment="{key}"' in page.text
    faults = page.text[page.text.index('id="fault-scenarios-title"') :]
    assert 'data-experiment="both_connectors_broken"' in faults
    assert 'data-experiment="e1_bolt_undone"' not in faults
    assert "stops quietly and waits for the engineer" in faults  # both locks broken
    assert "robot 2 stops answering" in page.text  # the fault in words
    assert "on the simulated world" in page.text and "emulated devices" not in page.text
    assert ">SIM</span>" in page.text and ">EMU</span>" not in page.text

    unknown = post(client, token, "/simulation/experiment", experiment="e6_r2_disconnect")
    assert unknown.status_code == 404
    assert "did you mean" in unknown.text
    assert post(client, token, "/simulation/experiment").status_code == 422

    e6 = next(key for key in experiments if key.startswith("e6"))
    played = post(client, token, "/simulation/experiment", experiment=e6)
    assert played.status_code == 200
    assert live.view.experiment.startswith("E6")
    assert any("disconnect" in fault for fault in live.view.armed_faults)
    assert "robot 2 stops answering" in played.text  # the armed fault in words
    assert [r for r in audit(station, "experiment", "engineer") if r.subject.startswith("E6")]
    station.wait(lambda: live.view.state.intentions["tighten_bolts"] == "e")

    # a station on real devices has no simulation panel
    live.simulated = False
    try:
        assert client.get("/simulation").status_code == 404
        assert post(client, token, "/simulation/experiment", experiment=e6).status_code == 404
    finally:
        live.simulated = True


def test_plan_drawing_puts_independent_steps_side_by_side():
    from app.pages import plans

    after = [frozenset(), frozenset(), frozenset({0}), frozenset({0, 1, 2})]
    assert plans.levels(after) == [0, 0, 1, 2]
    # 3 waits for 0 through 2: only the direct arrows are drawn
    assert plans.direct(after) == [frozenset(), frozenset(), frozenset({0}), {1, 2}]
    steps = [plans.Step(f"s{k}", "waiting", "", "") for k in range(4)]
    drawing = plans.layout("test", steps, after)
    s0, s1, s2, s3 = drawing.nodes
    assert s0.y == s1.y < s2.y < s3.y and s0.x < s1.x  # 0 and 1 may run in parallel
    assert (drawing.levels, drawing.widest) == (3, 2)
    assert [(e.source, e.target) for e in drawing.edges] == [(0, 2), (1, 3), (2, 3)]
    # the arrow from s1 skips a level: it runs down the gap between the columns
    skip = drawing.edges[1].path
    assert f"L{s0.x + plans.NODE_WIDTH + plans.GAP_X // 2}," in skip


def test_plan_steps_are_words_wrapped_never_cut_and_counted_in_good_english():
    from app.pages import plans
    from app.web.routes.station import steps

    long = "find the hanging tools with robot 1's camera and wait for the operator to answer"
    lines = plans.wrap(long)
    assert " ".join(lines) == long and all(len(line) <= plans.LABEL_CHARS for line in lines)
    drawing = plans.layout("test", [plans.Step("s", "ready", "next", "", long)], [()])
    (node,) = drawing.nodes
    assert node.label_lines == lines and node.label == long
    assert drawing.node_height >= plans.NODE_HEIGHT + (len(lines) - 1) * plans.LINE
    assert (steps(1), steps(5)) == ("1 step", "5 steps")


def test_timeline_page_shows_the_run_from_the_audit_log(station: RunningStation):
    from app.history.run_history import run_history

    client, token = signed_in(station)
    empty = client.get("/station/timeline")
    assert empty.status_code == 200
    assert "No run yet" in empty.text
    assert (
        post(client, token, "/station/intentions/start", name="assemble_engine").status_code == 200
    )
    store, name = station.built.server.store, station.live.name
    station.wait(lambda: bool(run_history(store, name).runs), 20)
    # operations in parallel: the overview names them, the timeline counts them
    station.wait(lambda: len(station.live.view.state.executing()) >= 2, 30)
    overview = client.get("/station/fragments/overview")
    at_once = re.search(r'data-running="(\d+)">\d+ operations at once: ', overview.text)
    assert at_once is not None and int(at_once.group(1)) >= 2, overview.text
    running = client.get("/station/timeline")
    assert 'data-outcome="running"' in running.text
    assert '<svg class="timeline-chart"' in running.text
    assert "assemble the engine" in running.text  # the intention in words
    assert (
        post(client, token, "/station/intentions/cancel", name="assemble_engine").status_code == 200
    )
    station.wait(lambda: run_history(store, name).runs[-1].outcome == "cancelled", 20)
    (run,) = run_history(store, name).runs
    page = client.get("/station/timeline", params={"run": run.first})
    assert 'data-outcome="cancelled"' in page.text
    assert re.search(r"<span data-at-once>up to [2-9] operations at once, for ", page.text)
    assert re.search(r"cycle time <span data-cycle-time>\d+\.\d s</span>", page.text)
    assert f'href="/station/timeline?run={run.first}"' in page.text
    assert client.get("/station/timeline", params={"run": run.first + 10_000}).status_code == 404
    operator, _ = signed_in(station, "operator")
    assert operator.get("/station/timeline", follow_redirects=False).status_code == 403


def test_start_says_which_part_of_the_precondition_does_not_hold(station: RunningStation):
    client, token = signed_in(station)
    row = 'id="intention-tighten_bolts"'
    before = client.get("/station").text.split(row)[1][:1500]
    assert "Cannot start until the ladder frame is on the engine" in before
    assert "the engine is in the station" not in before  # that part holds: not listed
    assert "It waits until the ladder frame is on the engine." in before  # the confirm
    after = post(client, token, "/station/intentions/start", name="tighten_bolts").text
    assert "starts once its precondition holds; not yet: the ladder frame is on the engine" in after
    assert "Starts once the ladder frame is on the engine" in after.split(row)[1][:1500]
    assert (
        post(client, token, "/station/intentions/cancel", name="tighten_bolts").status_code == 200
    )


def test_in_restart_mode_only_operations_a_reset_changes_get_a_reset_button(
    station: RunningStation,
):
    client, token = signed_in(station)
    live = station.live
    post(client, token, "/station/intentions/start", name="assemble_engine")
    station.wait(lambda: bool(live.view.state.operations_in("e")))
    post(client, token, "/station/restart/enter", reason="checking the reset buttons")
    station.wait(lambda: live.view.state.restart_mode)
    page = client.get("/station/fragments/status").text
    running = set(live.view.state.operations_in("e")) | set(live.view.state.operations_in("error"))
    rows = re.findall(r'<tr id="operation-(\w+)".*?</tr>', page, re.S)
    blocks = dict(zip(rows, re.split(r'<tr id="operation-\w+"', page)[1:], strict=True))
    with_reset = {n for n, html in blocks.items() if "/station/operations/reset" in html}
    assert running and with_reset == running, (with_reset, running)
    assert len(blocks) == len(live.view.model.station.operations)
    post(client, token, "/station/restart/leave")
    post(client, token, "/station/intentions/cancel", name="assemble_engine")


def test_one_activation_at_a_time_however_many_engineers_press_it(
    station: RunningStation,
) -> None:
    """Three engineers activate the same new version at once: one activation runs (each
    builds a runner and a planning worker), the others are told another is under way or
    that the version is active already."""
    import threading

    text = MODEL.read_text(encoding="utf-8")
    old = "description: the whole engine, every tool hung back and the robots parked"
    client, token = signed_in(station)
    saved = post(client, token, "/model/save", text=text.replace(old, old + " again"), note="x")
    assert saved.status_code == 200
    engineers = [signed_in(station) for _ in range(3)]
    ready = threading.Barrier(3)
    answers: list[Any] = [None] * 3

    def press(k: int) -> None:
        other, other_token = engineers[k]
        ready.wait()
        answers[k] = post(other, other_token, "/model/activate", version=2)

    threads = [threading.Thread(target=press, args=(k,)) for k in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    statuses = sorted(a.status_code for a in answers)
    assert statuses == [200, 409, 409], [a.text[:200] for a in answers]
    refusals = " ".join(a.text for a in answers if a.status_code == 409)
    assert "another activation is under way" in refusals or "already active" in refusals
    assert station.live.view.model.number == 2
    assert len([r for r in audit(station, "model", "engineer") if r.subject == "activated"]) == 1


def test_a_hands_free_play_is_answered_by_the_station_in_its_own_name(station: RunningStation):
    """E2 hands-free: the station approves the recovery and taps the cards as the scenario's
    operator, recorded as "simulated operator", never as a person; the play is audited as
    hands-free."""
    client, token = signed_in(station)
    played = post(
        client, token, "/simulation/experiment", experiment="e2_oil_filter_early", hands_free="on"
    )
    assert played.status_code == 200 and "the station plays the operator too" in played.text
    state = lambda: station.live.view.state.intentions.get("tighten_bolts")  # noqa: E731
    station.wait(lambda: state() == "e", 30)
    station.wait(lambda: state() == "f", 120)
    experiment = audit(station, "experiment", "engineer")[-1]
    assert json.loads(experiment.detail)["hands_free"] is True
    with station.built.server.store.sessions() as session:
        query = select(AuditRecord).where(
            AuditRecord.kind == "operator", AuditRecord.id > experiment.id
        )
        acted = list(session.scalars(query))
    assert {r.user for r in acted if r.subject != "start intention"} == {"simulated operator"}
    # E2's recovery is a maintenance step: the filters taken off, then the cards tapped
    assert {"maintenance done", "card done"} <= {r.subject for r in acted}, acted


def test_the_experiments_come_back_with_a_model_they_fit(station: RunningStation) -> None:
    """A model that fits no experiment leaves the simulation panel empty; activating the
    demo model again brings E1-E9 back."""
    from tests.support.paths import REPOSITORY

    mini = (REPOSITORY / "tests" / "support" / "models" / "mini_station.yaml").read_text()
    client, token = signed_in(station)
    server = station.built.server
    playable = len(server.experiments)
    assert playable > 9
    assert post(client, token, "/model/save", text=mini, note="mini").status_code == 200
    assert post(client, token, "/model/activate", version=2).status_code == 200
    assert server.experiments == {}
    assert post(client, token, "/model/activate", version=1).status_code == 200
    assert len(server.experiments) == playable
    assert "e6_r2_disconnects_above_engine" in server.experiments


def test_a_resource_that_cannot_act_shows_its_cause_not_a_silence(station: RunningStation):
    """A protective stop: the robot answers, so the tile says what a person must do."""
    from dataclasses import replace

    from app.web.routes.station import overview_context

    view = station.live.view
    state = view.state.copy()
    state.unavailable.add("r1")
    state.cannot_act["r1"] = "r1 is in a protective stop: release it on r1's teach pendant"
    state.last_heard.pop("r2", None)
    state.unavailable.add("r2")
    rows = {r.name: r for r in overview_context(replace(view, state=state))["resources"]}
    assert not rows["r1"].available and rows["r1"].cannot_act == (
        "Robot 1 is in a protective stop: release it on robot 1's teach pendant"
    )
    assert not rows["r2"].available and rows["r2"].cannot_act == ""
