"""Values nobody vouches for are not acted on (issue 28): a resource whose driver says it
does not answer is unavailable at once, and an automatic step whose guard reads what such a
resource measures, or what a silent device without a resource (a PLC) reports, fires only if
it holds whatever those values really are now."""

from __future__ import annotations

from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import EventKind, Inputs, Runner, RunnerConfig, RunnerState
from planner.runner.waiting import Who, waiting_for

# A robot carries the nutrunner down onto bolt pair 1, then 2; "finished" on a pair is what
# the robot's position says it is.  A frozen robot stream keeps saying "bp1".
TIGHTENING = """
station: tightening
variables:
  - {name: bp1.done, domain: bool, initial: false, kind: decision}
  - {name: bp2.done, domain: bool, initial: false, kind: decision}
  - {name: line.part, domain: bool, initial: false, kind: measured}
resources:
  - name: r1
    variables:
      - {name: pos, domain: [home, bp1, bp2], initial: bp1, kind: measured}
      - {name: ref, domain: [home, bp1, bp2], initial: bp1, kind: command}
    transitions:
      - {name: go_bp2, guard: "pos == ref && ref == bp1", actions: ["ref := bp2"]}
      - {name: arrive, kind: effect, guard: "pos != ref", actions: ["pos := ref"]}
  - name: nr
    variables:
      - {name: run, domain: bool, initial: true, kind: command}
      - {name: torque, domain: bool, initial: false, kind: measured}
    transitions:
      - {name: reached, kind: effect, guard: "run && !torque", actions: ["torque := true"]}
      - {name: finish_bp1, kind: automatic, guard: "torque && run && r1.pos == bp1",
         actions: ["run := false", "bp1.done := true"]}
      - {name: finish_bp2, kind: automatic, guard: "torque && run && r1.pos == bp2",
         actions: ["run := false", "bp2.done := true"]}
      - {name: count, kind: automatic,
         guard: "torque && run && line.part && (r1.pos == bp1 || r1.pos != bp1)",
         actions: ["run := false"]}
"""

FROZEN = {"r1": "r1 does not answer: no fresh data for 1.0 s"}


def runner() -> Runner:
    station = load_station(TIGHTENING, "tightening.yaml")
    config = RunnerConfig(auto_intentions=frozenset())
    return Runner(station, TransitionPlanner(station.model), OperationPlanner(station), config)


def everyone(runner: Runner) -> frozenset[str]:
    return frozenset(r.name for r in runner.station.resources)


def moving_to_bp2(runner: Runner) -> RunnerState:
    """r1 was sent from bolt pair 1 towards pair 2 (the runner has not seen it arrive)."""
    state = runner.initial(0.0)
    state = runner.tick(state, Inputs(heartbeats=everyone(runner)), 0.1).state
    state.values["r1.ref"] = "bp2"
    return state


def test_a_resource_its_driver_calls_silent_is_unavailable_at_once_and_back_when_it_answers() -> (
    None
):
    r = runner()
    state = moving_to_bp2(r)
    result = r.tick(state, Inputs(heartbeats=everyone(r) - {"r1"}, silent=FROZEN), 0.2)
    [event] = [e for e in result.events if e.kind is EventKind.UNAVAILABLE]
    assert (event.subject, event.detail["why"]) == ("r1", FROZEN["r1"])
    assert "r1" in result.state.unavailable
    # said once while it lasts
    again = r.tick(result.state, Inputs(heartbeats=everyone(r) - {"r1"}, silent=FROZEN), 0.3)
    assert not [e for e in again.events if e.kind is EventKind.UNAVAILABLE]
    back = r.tick(again.state, Inputs(heartbeats=everyone(r)), 0.4)
    assert [e.subject for e in back.events if e.kind is EventKind.AVAILABLE] == ["r1"]


def test_an_automatic_step_waits_for_a_silent_robot_s_position_and_takes_the_true_one() -> None:
    """The hazard: the torque came on bolt pair 2 while r1's data froze on pair 1."""
    r = runner()
    state = moving_to_bp2(r)
    frozen = Inputs(measured={"nr.torque": True}, heartbeats=everyone(r) - {"r1"}, silent=FROZEN)
    result = r.tick(state, frozen, 0.2)
    taken = [e.subject for e in result.events if e.kind is EventKind.TAKEN]
    assert taken == [] and result.state.values["nr.run"] is True
    assert result.state.values["bp1.done"] is False
    # r1 answers again, on bolt pair 2: that pair is finished, not pair 1
    back = Inputs(measured={"r1.pos": "bp2"}, heartbeats=everyone(r))
    result = r.tick(result.state, back, 0.3)
    taken = [e.subject for e in result.events if e.kind is EventKind.TAKEN]
    assert taken == ["nr.finish_bp2"]
    assert result.state.values["bp2.done"] is True and result.state.values["bp1.done"] is False


def test_an_automatic_step_waiting_on_a_value_that_was_right_fires_when_it_answers() -> None:
    """No measured change when r1 answers again: the waiting step is looked at anyway."""
    r = runner()
    state = r.tick(r.initial(0.0), Inputs(heartbeats=everyone(r)), 0.1).state
    frozen = Inputs(measured={"nr.torque": True}, heartbeats=everyone(r) - {"r1"}, silent=FROZEN)
    state = r.tick(state, frozen, 0.2).state
    assert state.values["bp1.done"] is False
    result = r.tick(state, Inputs(heartbeats=everyone(r)), 0.3)
    assert [e.subject for e in result.events if e.kind is EventKind.TAKEN] == ["nr.finish_bp1"]


def test_a_guard_that_holds_whatever_the_silent_value_is_fires() -> None:
    """A silent resource does not stop what does not depend on it; a silent PLC's value is
    stale, said once, and trusted again when it answers."""
    r = runner()
    state = r.tick(r.initial(0.0), Inputs(heartbeats=everyone(r)), 0.1).state
    state.values["line.part"] = True
    plc = {"line.part": "plc does not answer: no good answer for 1.1 s"}
    inputs = Inputs(
        measured={"nr.torque": True}, heartbeats=everyone(r) - {"r1"}, silent=FROZEN, stale={}
    )
    # `count` reads r1.pos but holds for every value of it
    result = r.tick(state, inputs, 0.2)
    assert [e.subject for e in result.events if e.kind is EventKind.TAKEN] == ["nr.count"]
    # the same with line.part stale: it waits, and says what is stale
    state = r.tick(r.initial(0.0), Inputs(heartbeats=everyone(r)), 0.1).state
    state.values["line.part"] = True
    state.values["r1.pos"] = state.values["r1.ref"] = "home"
    result = r.tick(
        state, Inputs(measured={"nr.torque": True}, heartbeats=everyone(r), stale=plc), 0.2
    )
    assert not [e for e in result.events if e.kind is EventKind.TAKEN]
    [said] = [e for e in result.events if e.kind is EventKind.STALE]
    assert (said.subject, said.detail["why"]) == ("line.part", plc["line.part"])
    assert result.state.stale == plc
    waits = [(w.who, w.subject, w.what) for w in waiting_for(r, result.state)]
    assert (Who.DEVICE, "line.part", f"{plc['line.part']}: its values are stale") in waits
    result = r.tick(result.state, Inputs(heartbeats=everyone(r)), 0.3)
    assert [e.subject for e in result.events if e.kind is EventKind.FRESH] == ["line.part"]
    assert [e.subject for e in result.events if e.kind is EventKind.TAKEN] == ["nr.count"]
    assert result.state.stale == {}


def test_values_of_a_robot_that_answers_but_cannot_act_are_trusted() -> None:
    """A protective stop: the robot reports where it stands, and that is taken."""
    r = runner()
    state = r.tick(r.initial(0.0), Inputs(heartbeats=everyone(r)), 0.1).state
    stopped = Inputs(
        measured={"nr.torque": True},
        heartbeats=everyone(r) - {"r1"},
        cannot_act={"r1": "r1 is in a protective stop: release it on r1's teach pendant"},
    )
    result = r.tick(state, stopped, 0.2)
    assert [e.subject for e in result.events if e.kind is EventKind.TAKEN] == ["nr.finish_bp1"]


def test_a_robot_that_cannot_act_and_then_goes_silent_is_no_longer_trusted() -> None:
    r = runner()
    state = r.tick(r.initial(0.0), Inputs(heartbeats=everyone(r)), 0.1).state
    why = "r1 is in a protective stop: release it on r1's teach pendant"
    state = r.tick(state, Inputs(heartbeats=everyone(r) - {"r1"}, cannot_act={"r1": why}), 0.2)
    state = state.state
    frozen = Inputs(measured={"nr.torque": True}, heartbeats=everyone(r) - {"r1"}, silent=FROZEN)
    result = r.tick(state, frozen, 0.3)
    assert result.state.cannot_act == {} and "r1" in result.state.unavailable
    assert [e.detail["why"] for e in result.events if e.kind is EventKind.UNAVAILABLE] == [
        FROZEN["r1"]
    ]
    assert not [e for e in result.events if e.kind is EventKind.TAKEN]  # r1.pos is stale now
