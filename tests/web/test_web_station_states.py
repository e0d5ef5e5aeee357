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
