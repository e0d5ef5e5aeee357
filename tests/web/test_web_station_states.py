"""The station pages never contradict what the station waits for: each resource's activity
from the same facts as `waiting_for`, progress counted over the whole run, queued starts
listed, and restart mode shown with its way out (issue 29, consistent states)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from app.pages.activity import Activity, resource_activities
from app.station.view import StationView
from app.web.routes.station import overview_context, progress_words, status_context
from planner.runner import IntentionState
from planner.runner.state import OperationPlan
from planner.runner.waiting import Waiting, Who, waiting_for
from tests.support.stations import RunningStation
from tests.web.test_web_engineer import post, signed_in


def activities(view: StationView) -> dict[str, Activity]:
    rows = overview_context(view)["resources"]
    return {r.name: r.activity for r in rows}


def test_a_silent_robot_is_never_idle_and_a_timed_out_tool_changer_is_faulted(
    station: RunningStation,
) -> None:
    view = station.live.view
    state = view.state.copy()
    state.unavailable.add("r2")
    state.last_heard["r2"] = view.now - 7
    state.timed_out.add("r1_tc.unlock.release")
    changed = replace(view, state=state)
    shown = activities(changed)
    assert shown["r2"] is Activity.SILENT and shown["r1_tc"] is Activity.FAULTED
    assert shown["r1"] is Activity.IDLE
    rows = {r.name: r for r in overview_context(changed)["resources"]}
    assert not rows["r2"].available and "Silent for 7 s" in rows["r2"].detail
    assert not rows["r1_tc"].available and rows["r1_tc"].waiting_on.endswith("(the engineer)")
    # the same rows on both pages
    assert status_context(changed)["resources"] == overview_context(changed)["resources"]

    client, _ = signed_in(station)
    before = client.get("/station").text
    assert 'data-resource="r2" data-activity="idle"' in before
    with pytest.MonkeyPatch.context() as patch:  # the pages read this round's view
        patch.setattr(type(station.live), "view", property(lambda _: changed))
        html = client.get("/station").text
        details = client.get("/station/fragments/status").text
    r2 = html.split('data-resource="r2"')[1].split("</li>")[0]
    assert 'data-activity="silent"' in r2 and "not answering" in r2 and "Idle" not in r2
    tool_changer = html.split('data-resource="r1_tc"')[1].split("</li>")[0]
    assert "faulted" in tool_changer and "available" not in tool_changer
    row = details.split('id="resource-r2"')[1].split("</tr>")[0]
    assert 'data-activity="silent"' in row and "Idle" not in row


def test_a_person_asked_to_mend_a_tool_changer_makes_it_faulted_and_the_operator_waited_for(
    station: RunningStation,
) -> None:
    view = station.live.view
    words, station_model = view.model.words, view.model.station
    step = Waiting(Who.OPERATOR, "operator.reset_r1_tc", "reset it, then report it done")
    rows = {
        r.name: r for r in resource_activities(station_model, view.state, [step], view.now, words)
    }
    assert rows["r1_tc"].activity is Activity.FAULTED
    assert rows["r1_tc"].detail.startswith("To be mended by hand: ")
    assert rows["r1_tc"].waiting_on == "waiting for the operator"
    assert rows["operator"].activity is Activity.WAITED_FOR
    assert rows["r2"].activity is Activity.IDLE
    # with nothing waited for, the same resources are idle: the facts decide, nothing else
    idle = resource_activities(station_model, view.state, [], view.now, words)
    assert {r.activity for r in idle} == {Activity.IDLE}
    assert waiting_for(view.runner, view.state) == []  # an idle station waits for nothing


def test_progress_counts_the_operations_done_before_a_replan_and_ends_n_of_n(
    station: RunningStation,
) -> None:
    state = station.live.view.state.copy()
    assert progress_words(state) == ""
    state.run_finished = ("place_bp1", "place_bp2", "place_bp3")
    steps = tuple(f"op{k}" for k in range(8))
    after = tuple(frozenset() for _ in steps)
    state.operation_plan = OperationPlan(steps, after)  # made again after three were done
    assert progress_words(state) == "3 of 11 operations done"
    state.operation_plan = OperationPlan(steps, after, set(range(8)), set(range(8)))
    state.run_finished += steps
    assert progress_words(state) == "11 of 11 operations done"
    state.operation_plan = None  # the intention finished: the count stays whole
    assert progress_words(state) == "11 of 11 operations done"


def test_a_queued_start_is_listed_and_restart_mode_shows_its_way_out(
    station: RunningStation,
) -> None:
    client, token = signed_in(station)
    live = station.live
    entered = post(client, token, "/station/restart/enter", reason="frame put on by hand")
    assert entered.status_code == 200
    assert "In restart mode since " in entered.text and "by engineer" in entered.text
    assert "Enter restart mode" not in entered.text  # the out-of-band control: the way out
    assert 'id="restart-control" hx-swap-oob="true"' in entered.text
    page = client.get("/station/details").text
    assert "Leave restart mode" in page and "Enter restart mode" not in page
    assert "frame put on by hand" in page
    again = post(client, token, "/station/restart/enter", reason="another reason")
    assert again.status_code == 409 and "already in restart mode" in again.text
    assert live.view.state.restart_reason == "frame put on by hand"  # not replaced

    started = post(client, token, "/station/intentions/start", name="tighten_bolts")
    assert started.status_code == 200
    assert live.view.state.intentions["tighten_bolts"] is IntentionState.INITIAL
    overview = client.get("/station").text
    assert 'data-queued="tighten_bolts"' in overview
    queued = overview.split('data-queued="tighten_bolts"')[1].split("</li>")[0]
    assert "restart mode" in queued
    left = post(client, token, "/station/restart/leave")
    assert left.status_code == 200 and "Enter restart mode" in left.text
    assert "Enter restart mode" in client.get("/station/details").text


def test_the_runner_counts_the_operations_of_a_run_across_its_replans() -> None:
    """E6 replans after r2 went silent: the count goes on and ends N of N."""
    from app.station import supervisor_cache
    from app.station.player import Planners, play
    from app.station.scenario import load_scenario
    from planner.planning.operation_planner import OperationPlanner
    from planner.reading import load_station
    from planner.runner.state import RunnerState
    from tests.support.stations import MODEL, ROOT

    text = MODEL.read_text()
    station = load_station(text, str(MODEL))
    transition = supervisor_cache.planner(
        station.model, text, "bdd", supervisor_cache.default_directory()
    )
    path = ROOT / "models" / "scenarios" / "e6_r2_disconnects_above_engine.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    states: list[RunnerState] = []
    planners = Planners(transition, OperationPlanner(station))
    events = list(play(station, scenario, planners, watch=states.append))
    finished = [
        e.subject for e in events if e.kind == "operation" and e.detail.get("why") == "goal reached"
    ]
    plans = [e for e in events if e.kind == "plan" and e.detail.get("level") == "OP"]
    assert len(plans) > 1  # made again after the error
    last = states[-1]
    assert list(last.run_finished) == finished and finished
    shown = {progress_words(s) for s in states}
    assert f"{len(finished)} of {len(finished)} operations done" in shown
    assert progress_words(last) == f"{len(finished)} of {len(finished)} operations done"


def test_an_identical_save_says_nothing_changed_and_activation_makes_the_heading_current(
    station: RunningStation,
) -> None:
    from app.store import versions

    client, token = signed_in(station)
    live = station.live
    text = live.model.text

    def numbers() -> list[int]:
        with station.built.server.store.sessions() as session:
            return [v.number for v in versions.versions(session, live.name)]

    page = client.get("/model").text
    assert "Editing version 1 (active)" in page and 'name="based_on" value="1"' in page
    same = post(client, token, "/model/save", text=text.replace("\n", "\r\n"), based_on=1)
    assert same.status_code == 200 and "Nothing changed" in same.text
    assert numbers() == [1]
    plain = post(client, token, "/model/save", htmx=False, text=text, based_on=1)
    assert plain.status_code == 303 and numbers() == [1]  # a plain form: the same, said once
    assert "Nothing changed" in client.get(plain.headers["location"]).text

    changed = text + "\n# checked\n"
    saved = post(client, token, "/model/save", text=changed, based_on=1)
    assert saved.status_code == 200 and numbers() == [2, 1]
    assert 'id="model-editing" hx-swap-oob="true" data-editing="2"' in saved.text
    assert "Editing version 2 (version 1 is active)" in saved.text
    assert "Nothing changed" in post(client, token, "/model/save", text=changed, based_on=2).text
    assert numbers() == [2, 1]

    activated = post(client, token, "/model/activate", version=2, editing=1)
    assert activated.status_code == 200, activated.text
    assert live.view.model.number == 2
    assert "Editing version 1 (version 2 is active)" in activated.text  # not "(active)"
    assert 'id="model-diff"' in activated.text and "against the active version 2" in activated.text
    assert "Editing version 2 (active)" in client.get("/model").text

    api = {"Authorization": f"Bearer {station.token(station.client(), 'engineer')}"}
    again = client.post("/api/models", headers=api, json={"text": changed, "based_on": 2})
    assert again.status_code == 200
    assert again.json() == {
        "number": 2,
        "saved": False,
        "message": "nothing changed: the text is that of version 2",
    }
    newest = client.post("/api/models", headers=api, json={"text": changed})  # the newest
    assert newest.status_code == 200 and newest.json()["saved"] is False
    other = client.post("/api/models", headers=api, json={"text": text, "based_on": 2})
    assert other.status_code == 201 and other.json()["number"] == 3
    assert numbers() == [3, 2, 1]


def test_a_plan_box_clips_its_text_with_an_ellipsis_and_keeps_it_whole_in_its_title() -> None:
    from app.pages import plans

    word = "tool-changer-connector-reset-and-lock-check"
    lines = plans.wrap(f"reset the {word} now")
    assert all(len(line) <= plans.LABEL_CHARS for line in lines)
    assert lines[1].endswith("…") and lines[1].startswith("tool-changer")
    drawing = plans.layout("test", [plans.Step("s", "ready", "next", f"whole: {word}", word)], [()])
    (node,) = drawing.nodes
    assert node.title == f"whole: {word}" and node.label == word
    from jinja2 import Environment, FileSystemLoader

    from tests.support.stations import ROOT

    env = Environment(loader=FileSystemLoader(str(ROOT / "templates")), autoescape=True)
    macros = env.get_template("_station_macros.html").module  # type: ignore[attr-defined]
    svg = str(macros.plan_graph(drawing))
    assert 'clip-path="url(#plan-test-clip)"' in svg and '<clipPath id="plan-test-clip">' in svg
