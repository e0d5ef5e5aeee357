"""Operations in parallel (DESIGN.md section 3.4): independent operations start at once, no
two executing operations share a variable, and the transition plan of one never undoes what
the next operation in the partial order needs (its causal links, `planner.runner.links`).

Each property is held by a test that fails when the mechanism is taken away (a planted
fault): the links left out of the query, the start rule for executing operations dropped.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from app.station.player import Planners, play
from app.station.scenario import Scenario, load_scenario
from planner.bdd.symbolic import Function, SymbolicModel
from planner.model.expressions import Expr
from planner.model.semantics import Semantics
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import EventKind, OperationState, RunnerConfig, RunnerState, links, operations
from planner.runner.station_index import StationIndex
from tests.support import plays

# Robot a finds a tool with its camera from the shared zone (scan), then waits for the
# operator to bring the part it takes.  Robot b first fetches its gripper from a rack, far
# away, then works in the zone.  Once b needs the zone, a must leave it, and a camera whose
# robot leaves scan forgets what it found: take_a could no longer start.
CAMERA = """
station: camera_and_zone
variables:
  - {name: done_a, domain: bool, kind: decision}
  - {name: done_b, domain: bool, kind: decision}
resources:
  - name: a
    variables:
      - {name: pos, domain: [home, scan], kind: measured}
      - {name: ref, domain: [home, scan], kind: command}
    transitions:
      - {name: goto_scan, guard: "pos == ref && pos == home", actions: ["ref := scan"]}
      - {name: goto_home, guard: "pos == ref && pos == scan", actions: ["ref := home"]}
      - {name: arrive, kind: effect, guard: "pos != ref", actions: ["pos := ref"]}
      - {name: take, guard: "pos == scan && pos == ref && cam.located && operator.ready && !done_a",
         actions: ["done_a := true"]}
  - name: cam
    variables:
      - {name: located, domain: bool, kind: measured}
      - {name: trigger, domain: bool, kind: command}
    transitions:
      - {name: locate, guard: "a.pos == scan && a.ref == scan && !located && !trigger",
         actions: ["trigger := true"]}
      - {name: found, kind: effect, guard: "trigger && !located && a.pos == scan",
         actions: ["located := true"]}
      - {name: seen, kind: automatic, guard: "trigger && located", actions: ["trigger := false"]}
      - {name: forget, kind: effect, guard: "located && a.pos != scan",
         actions: ["located := false"]}
  - name: b
    variables:
      - {name: pos, domain: [home, rack, way, zone], kind: measured}
      - {name: ref, domain: [home, rack, way, zone], kind: command}
      - {name: gripper, domain: bool, kind: measured}
    transitions:
      - {name: goto_rack, guard: "pos == ref && pos == home", actions: ["ref := rack"]}
      - {name: grab, guard: "pos == rack && ref == rack && !gripper", actions: ["ref := way"]}
      - {name: grabbed, kind: effect, guard: "pos == rack && ref == way && !gripper",
         actions: ["gripper := true"]}
      - {name: goto_way, guard: "pos == ref && gripper && pos == rack", actions: ["ref := way"]}
      - {name: goto_zone, guard: "pos == ref && pos == way", actions: ["ref := zone"]}
      - {name: goto_home, guard: "pos == ref && pos == zone && done_b", actions: ["ref := home"]}
      - {name: arrive, kind: effect, guard: "pos != ref && (ref != way || gripper)",
         actions: ["pos := ref"]}
      - {name: work, guard: "pos == zone && ref == zone && !done_b", actions: ["done_b := true"]}
  - name: operator
    variables:
      - {name: asked, domain: bool, kind: command}
      - {name: ready, domain: bool, kind: measured}
    transitions:
      - {name: ask, guard: "!asked && !ready", actions: ["asked := true"]}
      - {name: bring, kind: effect, guard: "asked && !ready", actions: ["ready := true"]}
specifications:
  - {name: one_robot_in_the_zone, invariant: "!(a.pos == scan && (b.pos == zone || b.ref == zone))"}
operations:
  - {name: locate_a, precondition: "!cam.located && !done_a", effects: ["cam.located := true"]}
  - {name: bring_part, precondition: "!operator.ready", effects: ["operator.ready := true"]}
  - {name: take_a, precondition: "cam.located && operator.ready && !done_a",
     effects: ["done_a := true"]}
  - {name: fetch_gripper, precondition: "!b.gripper", effects: ["b.gripper := true"]}
  - {name: work_b, precondition: "b.gripper && !done_b", effects: ["done_b := true"]}
intentions:
  - {name: both, goal: "done_a && done_b"}
"""

SLOW_OPERATOR = {"default": 1.0, "operator": 9.0}


def play_camera(
    monkeypatch: pytest.MonkeyPatch | None = None, *, sequential: bool = False
) -> tuple[list[object], list[RunnerState]]:
    station = load_station(CAMERA, "camera.yaml")
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    config = RunnerConfig(sequential=sequential, effect_timeout=30.0)
    scenario = Scenario("camera.yaml", config=config, delays=SLOW_OPERATOR, until=120.0)
    states: list[RunnerState] = []
    events = list(play(station, scenario, planners, watch=states.append))
    return events, states


def broken_links(states: list[RunnerState]) -> list[tuple[int, str]]:
    """Ticks where cam.located went from true to false while take_a was still to come."""
    out = []
    for k, (before, after) in enumerate(itertools.pairwise(states)):
        pending = (
            before.operations["take_a"] == OperationState.INITIAL and not before.values["done_a"]
        )
        if pending and before.values["cam.located"] and not after.values["cam.located"]:
            out.append((k, "cam.located"))
    return out


def test_the_other_robot_waits_rather_than_undo_what_the_next_operation_needs() -> None:
    events, states = play_camera()
    assert events[-1].kind is EventKind.DONE
    assert broken_links(states) == []
    [deferred] = [e for e in events if e.kind is EventKind.BLOCKED and e.subject == "work_b"]
    assert deferred.detail["waits_for"] == ["take_a"]
    assert "cam.located" in deferred.detail["why"]
    located = [e for e in events if e.subject == "locate_a" and e.detail.get("after") == "e"]
    assert len(located) == 1  # found once, kept until used
    # work_b started again once take_a was done, and finished
    starts = [e.time for e in events if e.subject == "work_b" and e.detail.get("after") == "e"]
    took = next(e.time for e in events if e.subject == "take_a" and e.detail.get("after") == "i")
    assert len(starts) == 2 and starts[1] >= took


def test_without_the_links_the_plan_undoes_them(monkeypatch: pytest.MonkeyPatch) -> None:
    """The planted fault: the transition planner not told the links.  b makes a leave the
    zone, the camera forgets, and the tool must be found again."""
    monkeypatch.setattr(links, "protected_links", lambda tick: ())
    import planner.runner.transitions as transitions

    monkeypatch.setattr(transitions, "protected_links", lambda tick: ())
    events, states = play_camera()
    assert events[-1].kind is EventKind.DONE
    assert broken_links(states)
    located = [e for e in events if e.subject == "locate_a" and e.detail.get("after") == "e"]
    assert len(located) == 2


def test_a_link_the_world_breaks_after_the_plan_is_kept_too(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The planted fault: the planner keeps a link only in the plan's own states.  Robot a
    leaving scan leaves cam.located true; the camera forgets a moment later by itself, so
    the other robot's plan breaks the link all the same."""
    import planner.planning.bmc as bmc
    import planner.planning.symbolic_planner as symbolic_planner

    def shallow(sym: SymbolicModel, predicate: Expr) -> Function:
        return ~sym.expr(predicate)

    monkeypatch.setattr(symbolic_planner, "breaking", shallow)
    monkeypatch.setattr(bmc, "breaking", shallow)
    events, states = play_camera()
    assert broken_links(states)
    assert not [e for e in events if e.kind is EventKind.BLOCKED and e.subject == "work_b"]


def test_one_at_a_time_there_are_no_links_and_the_cycle_is_longer() -> None:
    parallel, _ = play_camera()
    sequential, states = play_camera(sequential=True)
    assert sequential[-1].kind is EventKind.DONE
    assert not [e for e in sequential if e.kind is EventKind.BLOCKED and e.subject == "work_b"]
    assert max(len(executing(s)) for s in states) == 1
    assert sequential[-1].time > parallel[-1].time


def camera_family(ways: int, forgets: bool, zone: bool) -> str:
    """CAMERA with robot b's way to its work `ways` poses longer, a camera that forgets or
    not, and b's work in the shared zone or on its own side."""
    poses = ["home", "rack", *[f"w{k}" for k in range(ways)], "zone"]
    target = "zone" if zone else poses[-2]
    path = poses[1 : poses.index(target) + 1]
    moves = [
        {
            "name": f"to_{b}",
            "guard": f"pos == ref && pos == {a} && gripper",
            "actions": [f"ref := {b}"],
        }
        for a, b in itertools.pairwise(path)
    ]
    b_transitions = [
        {"name": "goto_rack", "guard": "pos == ref && pos == home", "actions": ["ref := rack"]},
        {
            "name": "grab",
            "guard": "pos == rack && ref == rack && !gripper",
            "actions": ["close := true"],
        },
        {
            "name": "grabbed",
            "kind": "effect",
            "guard": "close && !gripper",
            "actions": ["gripper := true"],
        },
        *moves,
        {
            "name": "goto_home",
            "guard": f"pos == ref && pos == {target} && done_b",
            "actions": ["ref := home"],
        },
        {"name": "arrive", "kind": "effect", "guard": "pos != ref", "actions": ["pos := ref"]},
        {
            "name": "work",
            "guard": f"pos == {target} && ref == {target} && gripper && !done_b",
            "actions": ["done_b := true"],
        },
    ]
    model = yaml.safe_load(CAMERA)
    b = next(r for r in model["resources"] if r["name"] == "b")
    b["variables"] = [
        {"name": "pos", "domain": poses, "kind": "measured"},
        {"name": "ref", "domain": poses, "kind": "command"},
        {"name": "gripper", "domain": "bool", "kind": "measured"},
        {"name": "close", "domain": "bool", "kind": "command"},
    ]
    b["transitions"] = b_transitions
    cam = next(r for r in model["resources"] if r["name"] == "cam")
    if not forgets:
        cam["transitions"] = [t for t in cam["transitions"] if t["name"] != "forget"]
    return yaml.safe_dump(model, sort_keys=False)


def zone_taken(state: RunnerState) -> bool:
    v = state.values
    return v["a.pos"] == "scan" and (v["b.pos"] == "zone" or v["b.ref"] == "zone")


@settings(max_examples=25, deadline=None)
@given(
    ways=st.integers(0, 3),
    forgets=st.booleans(),
    zone=st.booleans(),
    operator=st.sampled_from([0.5, 2.0, 5.0, 9.0, 14.0]),
    default=st.sampled_from([0.5, 1.0, 2.0]),
)
def test_a_family_of_two_robot_cells_keeps_its_links(
    ways: int, forgets: bool, zone: bool, operator: float, default: float
) -> None:
    """Checked against what the partial order means, not against the runner's own links:
    the tool is found once and never forgotten before it is taken, no state has both robots
    in the zone, no two operations sharing a variable execute at once, the goal is reached,
    and in parallel the cycle is no longer than one operation at a time."""
    station = load_station(camera_family(ways, forgets, zone), "family.yaml")
    index = StationIndex(station, Semantics(station.model))
    ends = []
    for sequential in (False, True):
        planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
        config = RunnerConfig(sequential=sequential, effect_timeout=60.0)
        delays = {"default": default, "operator": operator}
        scenario = Scenario("family.yaml", config=config, delays=delays, until=300.0)
        states: list[RunnerState] = []
        events = list(play(station, scenario, planners, watch=states.append))
        assert events[-1].kind is EventKind.DONE, (sequential, events[-1])
        assert broken_links(states) == []
        assert not any(zone_taken(s) for s in states)
        assert shared_variables(index, states) == []
        found = [e for e in events if e.subject == "locate_a" and e.detail.get("after") == "e"]
        assert len(found) == 1
        ends.append(events[-1].time)
    assert ends[0] <= ends[1]


def executing(state: RunnerState) -> list[str]:
    return [n for n, s in state.operations.items() if s == OperationState.EXECUTING]


def shared_variables(index: StationIndex, states: list[RunnerState]) -> list[tuple[str, str]]:
    """Pairs of operations that executed at once though they share a variable."""
    out = []
    for state in states:
        running = executing(state)
        for i, a in enumerate(running):
            for b in running[i + 1 :]:
                if index.operation_variables[a] & index.operation_variables[b]:
                    out.append((a, b))
    return out


def demo_plays() -> Iterator[tuple[str, list[RunnerState]]]:
    for name in ("nominal", "e3_lock_fails_on_attach", "e5_r2_disconnects_clear"):
        played = plays.played(name, states=True)
        assert played.states is not None
        yield name, played.states


def test_operations_that_share_a_variable_never_execute_at_once() -> None:
    station, _ = plays.demo()
    index = StationIndex(station, Semantics(station.model))
    for name, states in demo_plays():
        assert max(len(executing(s)) for s in states) >= 2, name  # they do run in parallel
        assert shared_variables(index, states) == [], name


def test_an_operation_does_not_start_beside_one_from_an_earlier_plan(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The planted fault: operations started by the plan's order alone.  In E5 the plan made
    after r2 failed no longer lists the operator's running card, and the next card would
    start beside it."""
    monkeypatch.setattr(operations, "shares_with_executing", lambda tick, name: False)
    station, planners = plays.demo()
    path = plays.scenario_path("e5_r2_disconnects_clear")
    scenario = load_scenario(path.read_text(), str(path), station)
    states: list[RunnerState] = []
    list(play(station, scenario, planners, watch=states.append))
    index = StationIndex(station, Semantics(station.model))
    assert ("place_bp1", "place_bp2") in shared_variables(index, states)
