"""The runner on the demo station against the simulated world: seed 000 Table 1 scenarios."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.scenario import Planners, Scenario, ScenarioError, load_scenario, play
from planner.operation_planner import OperationPlanner
from planner.runner import RunnerState
from planner.runner_io import Event
from planner.station import Station, load_station
from planner.transition_planner import TransitionPlanner

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "demo_station.yaml"
SCENARIOS = ROOT / "models" / "scenarios"


@pytest.fixture(scope="module")
def demo() -> tuple[Station, Planners]:
    station = load_station(MODEL.read_text(), str(MODEL))
    return station, Planners(TransitionPlanner(station.model), OperationPlanner(station))


def run(
    demo: tuple[Station, Planners], name: str
) -> tuple[Scenario, list[Event], list[RunnerState]]:
    station, planners = demo
    path = SCENARIOS / f"{name}.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    states: list[RunnerState] = []
    events = list(play(station, scenario, planners, watch=states.append))
    return scenario, events, states


def recovery(events: list[Event]) -> list[Event]:
    """Planning actions after the first fault that were not routine (new goals, new intentions)."""
    first = next(k for k, e in enumerate(events) if e.kind == "fault")
    return [
        e
        for e in events[first:]
        if e.kind == "plan" and e.detail["reason"] not in ("goals", "intentions")
    ]


def matches(paper: str, event: Event) -> bool:
    level, *flags = paper.replace(" w/", " ").split()
    return event.detail["level"] == level and set(flags) <= set(event.detail["flags"])


def is_subsequence(paper: list[str], ours: list[Event]) -> bool:
    it = iter(ours)
    return all(any(matches(p, e) for e in it) for p in paper)


def operator_work(events: list[Event]) -> list[str]:
    return [
        str(e.detail["transition"])
        for e in events
        if e.kind == "operator" and e.subject == "maintenance done"
    ]


def test_nominal_assembly_finishes_without_errors(demo: tuple[Station, Planners]) -> None:
    station, planners = demo
    _, events, states = run(demo, "nominal")
    assert events[-1].kind == "done"
    assert states[-1].intentions["assemble_engine"] == "f"
    assert not [e for e in events if e.kind in ("error", "unexpected", "timeout", "forbidden")]
    assert not [e for e in events if e.kind == "operation" and e.detail["after"] == "error"]
    # no state the runner was ever in is bad (violating, or doomed to violate, a specification)
    sem_bad = planners.transition
    for state in states:
        values = tuple(state.values[v.name] for v in station.model.variables)
        assert not sem_bad.sym.contains(sem_bad.bad, values)


@pytest.mark.parametrize(
    "name",
    [
        "e1_bolt_undone",
        "e2_oil_filter_early",
        "e3_lock_fails_on_attach",
        "e4_lock_fails_on_release",
        "e5_r2_disconnects_clear",
        "e6_r2_disconnects_above_engine",
        "e7_r2_disconnects_holding_tool",
        "e8_camera_miss",
        "e9_torque_not_reached",
    ],
)
def test_table_1_experiment_recovers_as_in_the_paper(
    demo: tuple[Station, Planners], name: str
) -> None:
    scenario, events, states = run(demo, name)
    assert events[-1].kind == "done", [str(e) for e in events[-30:]]
    assert all(states[-1].intentions[i] == "f" for i in scenario.intentions or ())
    ours = recovery(events)
    paper = list(scenario.expect["recovery"])
    assert ours, "the fault caused no replanning"
    assert matches(paper[0], ours[0]), [str(e) for e in ours]
    assert is_subsequence(paper, ours), [str(e) for e in ours]
    assert ours[0].detail["status"] == "found" or len(paper) > 1
    assert operator_work(events) == list(scenario.expect["operator"])


def test_forbidden_state_recovery_waits_for_the_approval(
    demo: tuple[Station, Planners],
) -> None:
    _, events, _ = run(demo, "e2_oil_filter_early")
    kinds = [e.kind for e in events]
    asked = kinds.index("approval")
    approved = next(k for k, e in enumerate(events) if e.subject == "approve")
    recovered = kinds.index("recovered")
    assert asked < approved < recovered
    # nothing was taken by the runner between the forbidden state and the approval
    between = events[kinds.index("forbidden") : approved]
    assert not [e for e in between if e.kind == "taken" and e.detail["type"] == "controlled"]


def test_replaying_the_same_scenario_gives_the_same_events(
    demo: tuple[Station, Planners],
) -> None:
    _, first, _ = run(demo, "e8_camera_miss")
    _, second, _ = run(demo, "e8_camera_miss")
    assert first == second


def test_bad_scenarios_are_reported_with_file_and_entry(demo: tuple[Station, Planners]) -> None:
    station, _ = demo
    cases = {
        "start: {r9.pos: home}": "start: unknown variable 'r9.pos'",
        "start: {r1.pos: moon}": "start: r1.pos: 'moon' is not in",
        "intentions: [build_car]": "unknown intention 'build_car'",
        "faults: [{at: 1, kind: explode}]": "kind must be one of",
        "faults: [{kind: disconnect, resource: r2}]": "give 'at' (seconds) or 'when'",
        "faults: [{when: 'r1.poss == home', kind: set}]": "did you mean 'r1.pos'",
        "colour: red": "unknown scenario key 'colour'",
    }
    for text, message in cases.items():
        with pytest.raises(ScenarioError, match=r"bad\.yaml") as caught:
            load_scenario(text, "bad.yaml", station)
        assert message in str(caught.value)
