"""Faults the station cannot get out of by itself end in a quiet stop that says why: the
devices' failed attempts are counted and escalate, nothing is planned again while nothing
changes, and `waiting_for` names the cause, not only its consequence."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.scenario import Planners, load_scenario, play
from planner.operation_planner import OperationPlanner
from planner.planning import PlanResult
from planner.runner import Event, EventKind, PlanLevel
from planner.station import Station, load_station
from planner.transition_planner import TransitionPlanner

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "demo_station.yaml"
BENCH = ROOT / "models" / "scenarios" / "faults"


@pytest.fixture(scope="module")
def demo() -> tuple[Station, Planners]:
    station = load_station(MODEL.read_text(), str(MODEL))
    return station, Planners(TransitionPlanner(station.model), OperationPlanner(station))


def played(demo: tuple[Station, Planners], name: str) -> list[Event]:
    station, planners = demo
    path = BENCH / f"{name}.yaml"
    return list(play(station, load_scenario(path.read_text(), str(path), station), planners))


@pytest.mark.parametrize(
    ("name", "operation", "missed"),
    [
        ("endless_camera_misses", "locate_tool_r", "instead of r1_cam.locate_tool.found"),
        ("endless_torque_nok", "tighten_bp", "nr.run_nut.torque_nok happened instead of"),
    ],
)
def test_a_device_that_always_fails_ends_in_a_quiet_stop_naming_the_cause(
    demo: tuple[Station, Planners], name: str, operation: str, missed: str
) -> None:
    events = played(demo, name)
    errors = [
        e
        for e in events
        if e.kind is EventKind.OPERATION and e.detail["after"] == "error" and operation in e.subject
    ]
    assert errors and all("failed attempts" in e.detail["why"] for e in errors)
    activity = (EventKind.PLAN, EventKind.OPERATION, EventKind.INTENTION, EventKind.TAKEN)
    last = max(e.time for e in events if e.kind in activity)
    stop = events[-1]
    assert stop.kind is EventKind.STOPPED and stop.time - last > 60  # quiet for a minute
    [waiting] = stop.detail["waiting_for"]
    assert waiting["who"] == "engineer" and waiting["subject"] == "tighten_bolts"
    assert missed in waiting["what"]  # the cause, not only "no operation plan"
    plans = [e for e in events if e.kind is EventKind.PLAN]
    assert len(plans) <= 15  # was 53 and 26: replanned for as long as the run lasted


def test_a_stop_asks_the_planners_nothing_while_nothing_changes(
    demo: tuple[Station, Planners],
) -> None:
    """The background check looks again only when what its queries read has changed: a
    station that has stopped does not ask the same question every second."""
    station, planners = demo
    path = BENCH / "endless_camera_misses.yaml"
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
    last_plan = max(e.time for e in events if e.kind is EventKind.PLAN)
    assert [a for a in asked if a[0] > last_plan + 2] == []
