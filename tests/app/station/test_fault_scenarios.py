"""The fault scenarios of `models/scenarios/faults/`: situations beyond seed 000 Table 1, of
every class of issue 13 (slow planning, endless retries, errors that do not clear, dead ends,
rejected recovery, people treated as devices).  Each says in its `expect` how a good station
ends: done, or stopped with a `waiting_for` that names who must do what.  None may hang, and
a stop is quiet: nothing is planned again while nothing changes."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest

from app.station.player import Planners, play
from app.station.scenario import Scenario, load_scenario
from planner.model.station import Station
from planner.planning.query import PlanResult
from planner.runner import Event, EventKind, PlanLevel, RunnerState
from tests.support import plays as shared_plays
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
FAULTS = sorted((ROOT / "models" / "scenarios" / "faults").glob("*.yaml"))
CLASSES = {
    "slow planning",
    "endless retries",
    "errors that do not clear",
    "dead ends",
    "rejected recovery",
    "people are not devices",
}


@pytest.fixture(scope="module")
def demo() -> tuple[Station, Planners]:
    return shared_plays.demo()


@pytest.fixture(scope="module")
def plays() -> Iterator[dict[str, tuple[Scenario, list[Event]]]]:
    """Each scenario played once per test process, lazily (tests/support/plays.py)."""

    class Plays(dict[str, tuple[Scenario, list[Event]]]):
        def __missing__(self, name: str) -> tuple[Scenario, list[Event]]:
            once = shared_plays.played(name)
            return once.scenario, once.events

    yield Plays()


def test_every_class_of_fault_has_scenarios_that_say_how_they_end(
    demo: tuple[Station, Planners],
) -> None:
    station, _ = demo
    seen: dict[str, int] = {}
    for path in FAULTS:
        expect = load_scenario(path.read_text(), str(path), station).expect
        assert expect.get("class") in CLASSES, path.name
        assert expect.get("ends") in ("done", "stopped"), path.name
        assert (expect["ends"] == "stopped") == bool(expect.get("waiting_for")), path.name
        seen[expect["class"]] = seen.get(expect["class"], 0) + 1
    assert set(seen) == CLASSES and min(seen.values()) >= 2, seen


@pytest.mark.parametrize("path", FAULTS, ids=lambda p: p.stem)
def test_a_fault_scenario_ends_as_a_good_station_would(
    plays: dict[str, tuple[Scenario, list[Event]]], path: Path
) -> None:
    scenario, events = plays[path.stem]
    expect: dict[str, Any] = dict(scenario.expect)
    last = events[-1]
    assert last.kind.value == expect["ends"], (last.subject, last.detail)
    if last.kind is EventKind.STOPPED:
        waiting = last.detail["waiting_for"]
        wanted = expect["waiting_for"]
        assert len(waiting) == len(wanted), waiting
        for item, want in zip(waiting, wanted, strict=True):
            assert (item["who"], item["subject"]) == (want["who"], want["subject"]), item
            assert want["says"] in item["what"], item["what"]
        # nothing is waited on that timed out: that is the engineer's, said once
        late = {w["subject"] for w in waiting if "did not happen in time" in w["what"]}
        assert not [w for w in waiting if w["who"] != "engineer" and w["subject"] in late]
        # quiet: the station settled long before the time limit and asked nothing since
        activity = (EventKind.PLAN, EventKind.OPERATION, EventKind.INTENTION)
        settled = max(e.time for e in events if e.kind in activity)
        assert last.time - settled > 30, settled
    # one root alarm per fault that needs a person (app.station.alarm_grouping), in order
    assert shared_plays.played(path.stem).alarms == expect["alarms"]
    # nothing a plan takes may enter a forbidden state: every recovery ends or holds
    forbidden = [e for e in events if e.kind is EventKind.FORBIDDEN]
    assert len(forbidden) <= 3, [e.time for e in forbidden]


def test_while_planning_is_slow_people_are_answered_at_once_and_devices_watched(
    plays: dict[str, tuple[Scenario, list[Event]]],
) -> None:
    """Every query takes 6 s: the operator's reject at 82 s is taken in that tick, effects
    are taken while the station plans, and the run still finishes."""
    _, events = plays["slow_planning_while_operator_rejects"]
    [reject] = [e for e in events if e.kind is EventKind.OPERATOR and e.subject == "reject"]
    assert reject.time == 82.0
    plans = [e.time for e in events if e.kind is EventKind.PLAN]
    gaps = [(a, b) for a, b in pairwise(plans) if b - a >= 5.9]
    assert gaps, plans  # planning took its 6 s
    waiting_effects = [
        e for e in events if e.kind is EventKind.EFFECT and any(a < e.time < b for a, b in gaps)
    ]
    assert waiting_effects  # the world was watched meanwhile
    # the forbidden state is said in the tick it is seen, once, before its plan is ready
    seen = next(e.time for e in events if e.kind is EventKind.OBSERVED)
    assert [e.time for e in events if e.kind is EventKind.FORBIDDEN] == [seen]
    assert events[-1].kind is EventKind.DONE


def test_a_query_over_its_budget_is_its_own_status_and_cause(
    plays: dict[str, tuple[Scenario, list[Event]]],
) -> None:
    _, events = plays["planning_over_budget"]
    plans = [e for e in events if e.kind is EventKind.PLAN]
    assert plans and all(e.detail["status"] == "over_budget" for e in plans)
    assert plans[0].time == 10.0  # answered when the budget was used up, not after 30 s
    [error] = [e for e in events if e.kind is EventKind.INTENTION and e.detail["after"] == "error"]
    assert "planning budget" in error.detail["why"]


def test_people_get_reminders_never_time_outs(
    plays: dict[str, tuple[Scenario, list[Event]]],
) -> None:
    for name in ("operator_away_for_minutes", "slow_operator_places_bolts"):
        _, events = plays[name]
        timeouts = [e.subject for e in events if e.kind is EventKind.TIMEOUT]
        assert not [t for t in timeouts if t.startswith("operator.")], (name, timeouts)
        errors = [
            e for e in events if e.kind is EventKind.OPERATION and e.detail["after"] == "error"
        ]
        assert errors == [], name
    _, events = plays["operator_away_for_minutes"]
    reminders = [e for e in events if e.kind is EventKind.REMINDER]
    assert reminders and all(e.detail["waited"] >= 120 for e in reminders)
    assert all(e.detail["what"] for e in reminders)


def test_a_late_device_effect_is_taken_and_the_operation_goes_on_where_it_was(
    plays: dict[str, tuple[Scenario, list[Event]]],
) -> None:
    """r1's moves take 8 s against a 5 s time-out: each times out and arrives late.  The
    late arrival takes back the failure, and the operation it interrupted goes on instead
    of starting over (which timed out again, for ever)."""
    _, events = plays["slow_r1_moves_arrive_late"]
    late = [e for e in events if e.kind is EventKind.EFFECT and e.detail.get("late")]
    assert late and all(e.subject == "r1.goto.arrive" for e in late)
    resumed = [
        e
        for e in events
        if e.kind is EventKind.OPERATION
        and (e.detail["before"], e.detail["after"]) == ("error", "e")
    ]
    assert resumed and {e.time for e in resumed} <= {e.time for e in late}
    assert events[-1].kind is EventKind.DONE


def test_a_flapping_network_holds_nothing_against_the_robot(
    demo: tuple[Station, Planners], plays: dict[str, tuple[Scenario, list[Event]]]
) -> None:
    """r2 drops out three times: each time it answers again, what its silence made fail is
    forgotten, and the bolts are finished with r2."""
    _, events = plays["flapping_r2_network"]
    kinds = [e.kind for e in events if e.subject == "r2"]
    assert kinds.count(EventKind.UNAVAILABLE) == 3 and kinds.count(EventKind.AVAILABLE) == 3
    assert events[-1].kind is EventKind.DONE


def test_a_reminder_is_sent_once_per_while(demo: tuple[Station, Planners]) -> None:
    """The operator confirms just after 180 s; with reminders every 60 s that is three of
    them, and the count is forgotten once the step is done."""
    station, planners = demo
    path = next(p for p in FAULTS if p.stem == "operator_away_for_minutes")
    text = path.read_text().replace("effect_timeout: 5.0", "effect_timeout: 5.0, reminder: 60")
    scenario = load_scenario(text.replace("until: 2400", "until: 250"), str(path), station)
    states: list[RunnerState] = []
    events = list(play(station, scenario, planners, watch=states.append))
    reminders = [e for e in events if e.kind is EventKind.REMINDER]
    confirm = [round(e.detail["waited"]) for e in reminders if e.subject == "operator.confirm"]
    assert confirm == [60, 120, 180]
    assert {"operator.confirm": 3} in [s.reminded for s in states]
    assert "operator.confirm" not in states[-1].reminded


def test_a_recovery_plan_does_not_wait_for_what_already_happened(
    plays: dict[str, tuple[Scenario, list[Event]]],
) -> None:
    """The operator's watch cleared before the recovery plan's step that expected it came:
    the plan remembers that it happened early and goes on (it used to wait for it for ever,
    and later planned again once it saw it would never come)."""
    _, events = plays["reject_while_operator_places_bolts"]
    reject = next(k for k, e in enumerate(events) if e.subject == "reject")
    plan = next(e for e in events[reject:] if e.kind is EventKind.PLAN)
    assert plan.detail["status"] == "found" and "operator.clear" in plan.detail["plan"]
    cleared = next(
        e.time
        for e in events[reject:]
        if e.kind is EventKind.EFFECT and e.subject == "operator.clear"
    )
    taken = [e.time for e in events[reject:] if e.kind is EventKind.TAKEN]
    assert taken and cleared < taken[-1]  # before the plan had come to it
    stuck = [e for e in events if e.kind is EventKind.BLOCKED and e.subject == "recovery plan"]
    assert stuck == []
    assert [e.kind for e in events].count(EventKind.RECOVERED) == 1
    assert events[-1].kind is EventKind.DONE


@pytest.mark.parametrize(
    ("name", "operation"),
    [("endless_camera_misses", "locate_tool_r"), ("endless_torque_nok", "tighten_bp")],
)
def test_a_device_that_always_fails_is_tried_a_bounded_number_of_times(
    plays: dict[str, tuple[Scenario, list[Event]]], name: str, operation: str
) -> None:
    """Each failed attempt counts ("a different effect than planned" too): the operations go
    to error with their count, and the planners are asked a bounded number of times (53 and
    26 plans before, for as long as the run lasted)."""
    _, events = plays[name]
    errors = [
        e
        for e in events
        if e.kind is EventKind.OPERATION and e.detail["after"] == "error" and operation in e.subject
    ]
    assert errors and all("failed attempts" in e.detail["why"] for e in errors)
    assert len([e for e in events if e.kind is EventKind.PLAN]) <= 15


def test_a_stop_asks_the_planners_nothing_while_nothing_changes(
    demo: tuple[Station, Planners],
) -> None:
    """The background check looks again only when what its queries read has changed: a
    station that has stopped does not ask the same question every second (unannounced
    queries included, which the event log does not show)."""
    station, planners = demo
    path = next(p for p in FAULTS if p.stem == "endless_camera_misses")
    scenario = load_scenario(path.read_text(), str(path), station)
    asked: list[tuple[float, str]] = []

    class Count:
        def asked(self, now: float, level: PlanLevel, purpose: str) -> None:
            asked.append((now, purpose))

        def answered(self, result: PlanResult, millis: float | None) -> None:
            pass

        def announced(self) -> None:
            pass

    events = list(play(station, scenario, planners, observer=Count()))
    assert events[-1].kind is EventKind.STOPPED
    changes = (EventKind.PLAN, EventKind.EFFECT, EventKind.TAKEN, EventKind.UNEXPECTED)
    last_change = max(e.time for e in events if e.kind in changes)
    assert last_change < events[-1].time - 60  # a long quiet stop to look at
    recheck = scenario.config.recheck_period
    assert [a for a in asked if a[0] > last_change + recheck + 0.5] == []


@pytest.mark.parametrize("sequential", [False, True])
def test_robots_do_not_take_turns_for_ever_after_a_camera_dropout(
    demo: tuple[Station, Planners],
    plays: dict[str, tuple[Scenario, list[Event]]],
    sequential: bool,
) -> None:
    """One operation at a time, a robot that made way for the other made its camera forget
    the tool it found; planned again, the work went back to it, and the other's camera forgot
    in turn.  The plan now looks again where it needs to, so each locating operation
    succeeds a bounded number of times.  With operations in parallel both robots look at
    once, and the bound holds as well."""
    scenario, events = plays["robots_take_turns_after_camera_dropout"]
    if sequential:
        station, planners = demo
        config = replace(scenario.config, sequential=True)
        events = list(play(station, replace(scenario, config=config), planners))
    assert events[-1].kind is EventKind.DONE
    located = [
        e.subject
        for e in events
        if e.kind is EventKind.OPERATION
        and e.subject.startswith("locate_tool_")
        and e.detail["why"] == "goal reached"
    ]
    assert len(located) <= 4, located
    if sequential:
        repairs = [e for e in events if e.kind is EventKind.REPAIRED and e.detail.get("inserted")]
        assert repairs, "the plan was not mended where the camera forgot"


def test_a_way_out_is_planned_once_the_silent_robot_answers_again(
    plays: dict[str, tuple[Scenario, list[Event]]],
) -> None:
    """No maintenance plan exists while both robots are silent; the station must not wait
    for r2 for ever once r1, which can do the work, answers again."""
    _, events = plays["double_r1_silent_when_r2_holds_the_nutrunner"]
    [back] = [e.time for e in events if e.kind is EventKind.AVAILABLE and e.subject == "r1"]
    maintenance = [
        e for e in events if e.kind is EventKind.PLAN and e.detail["reason"] == "maintenance"
    ]
    assert any(e.detail["status"] == "unreachable" and e.time < back for e in maintenance)
    found = [e for e in maintenance if e.detail["status"] == "found"]
    assert found and found[0].time == back, [(e.time, e.detail["status"]) for e in maintenance]
    done = [e.detail["transition"] for e in events if e.kind is EventKind.OPERATOR]
    assert done == ["operator.move_r2_home", "operator.hang_nr_from_r2"]
    assert events[-1].kind is EventKind.DONE
