"""The runner's safety nets, each held by a test that fails when the net is taken away:
the supervisor's check before a controlled step, automatic transitions first, approval of
every recovery step, the retry limit, the monotonic abstraction, and every change of an
intention or operation following its life cycle."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import pytest

from app.station.cycle import ScheduledFault, StationCycle
from app.station.player import Planners, play
from app.station.scenario import load_scenario
from hw.faults import Fault, FaultKind
from hw.simulated import SimulatedWorld
from planner.model.expression_text import parse_expr
from planner.model.expressions import Value
from planner.planning.operation_planner import OperationPlanner
from planner.planning.partial_order import blocks
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.reading.yaml_reader import scope_for
from planner.runner import (
    Approve,
    Event,
    EventKind,
    Inputs,
    IntentionState,
    MaintenanceDone,
    OperationState,
    Reject,
    ReplanReason,
    Runner,
    RunnerConfig,
    RunnerState,
    StartIntention,
    TransitionPlan,
)
from planner.runner.following import plan_reaches, take
from planner.runner.tick import Tick
from planner.runner.vocabulary import INTENTION_LIFE_CYCLE, OPERATION_LIFE_CYCLE
from tests.support import plays
from tests.support.paths import MINI_STATION, REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
SCENARIOS = sorted((ROOT / "models" / "scenarios").glob("*.yaml"))
MINI = MINI_STATION

# A press that must never come down on a hand or on nothing.  A hand may enter only while
# the press is up (a light curtain), so lowering it is safe exactly when no hand is in.
PRESS = """
station: press
variables:
  - {name: part.present, domain: bool, initial: true, kind: estimated}
  - {name: part.pressed, domain: bool, initial: false, kind: decision}
resources:
  - name: press
    variables:
      - {name: down, domain: bool, kind: command}
    transitions:
      - {name: lower, guard: "!down && part.present", actions: ["down := true"]}
      - {name: lift, guard: "down", actions: ["down := false", "part.pressed := true"]}
  - name: curtain
    variables:
      - {name: hand_in, domain: bool, kind: measured}
    transitions:
      - {name: hand_enters, kind: effect, guard: "!press.down && !hand_in",
         actions: ["hand_in := true"]}
      - {name: hand_leaves, kind: effect, guard: "hand_in", actions: ["hand_in := false"]}
specifications:
  - {name: no_hand_under_press, invariant: "!(press.down && curtain.hand_in)"}
  - {name: press_only_on_a_part, invariant: "!press.down || part.present"}
operations:
  - {name: press_part, precondition: "part.present && !part.pressed",
     effects: ["part.pressed := true"]}
intentions:
  - {name: pressed, goal: "part.pressed"}
"""

# Two lamps; the panel lights a only once b is lit.  Lighting a alone (operation light_a)
# cannot be done without lighting b, which is operation light_b's to change.
LAMPS = """
station: lamps
variables:
  - {name: a.lit, domain: bool, kind: decision}
  - {name: b.lit, domain: bool, kind: decision}
resources:
  - name: panel
    transitions:
      - {name: light_b, guard: "!b.lit", actions: ["b.lit := true"]}
      - {name: light_a, guard: "b.lit && !a.lit", actions: ["a.lit := true"]}
operations:
  - {name: light_a, precondition: "!a.lit", effects: ["a.lit := true"]}
  - {name: light_b, precondition: "!b.lit", effects: ["b.lit := true"]}
intentions:
  - {name: a_lit, goal: "a.lit"}
"""

# An automatic cycle the planners were not built with (a stale supervisor, say), and a
# controlled step whose guard holds all along.
BLINKER = """
station: blinker
resources:
  - name: lamp
    variables:
      - {name: on, domain: bool, initial: false, kind: decision}
      - {name: armed, domain: bool, initial: true, kind: command}
      - {name: bell, domain: bool, initial: false, kind: command}
    transitions:
      - {name: ring, guard: "!bell", actions: ["bell := true"]}
      - {name: light, kind: automatic, guard: "armed && !on", actions: ["on := true"]}
      - {name: dim, kind: automatic, guard: "armed && on", actions: ["on := false"]}
"""


def runner_for(text: str, config: RunnerConfig | None = None) -> Runner:
    station = load_station(text, "test.yaml")
    planners = TransitionPlanner(station.model), OperationPlanner(station)
    return Runner(station, *planners, config or RunnerConfig(auto_intentions=frozenset()))


def plan_of(runner: Runner, goal: str, steps: list[str]) -> TransitionPlan:
    model = runner.model
    order = blocks(model, tuple(steps))
    return TransitionPlan(parse_expr(goal, scope_for(model.domains)), tuple(steps), tuple(order))


def everyone(runner: Runner) -> frozenset[str]:
    return frozenset(r.name for r in runner.station.resources)


# -- the supervisor and automatic transitions before a controlled step ------------------------


def test_a_step_the_supervisor_holds_back_is_not_taken_and_the_plan_is_made_again() -> None:
    runner = runner_for(PRESS)
    state = runner.initial(0.0, {"curtain.hand_in": True})
    plan = state.transition_plan = plan_of(runner, "press.down", ["press.lower"])
    tick = Tick(runner, state, 1.0)
    assert runner.index.transition("press.lower").guard(tick.current())  # the model allows it
    assert not take(tick, plan, 0, supervised=True)
    assert state.values["press.down"] is False
    [blocked] = tick.events
    assert (blocked.kind, blocked.subject) == (EventKind.BLOCKED, "press.lower")
    assert "supervisor" in blocked.detail["why"]
    assert state.replan_transitions is ReplanReason.DEVIATION
    assert not take(tick, plan, 0, supervised=True)
    assert len(tick.events) == 1  # said once, not every tick

    state.values["curtain.hand_in"] = False  # the hand is out: now it may come down
    assert take(tick, plan, 0, supervised=True)
    assert state.values["press.down"] is True and 0 not in plan.held


def test_a_rest_of_plan_through_a_bad_state_does_not_count_as_reaching_its_goal() -> None:
    runner = runner_for(PRESS)
    plan = plan_of(runner, "press.down", ["press.lower"])
    clear = Tick(runner, runner.initial(0.0), 1.0)
    assert plan_reaches(clear, plan)
    hand_in = Tick(runner, runner.initial(0.0, {"curtain.hand_in": True}), 1.0)
    assert not plan_reaches(hand_in, plan)


def test_a_controlled_step_waits_while_an_automatic_transition_is_enabled() -> None:
    station = load_station(BLINKER, "blinker.yaml")
    stale = load_station(BLINKER.replace("- {name: dim", "# "), "blinker.yaml")
    runner = Runner(station, TransitionPlanner(stale.model), OperationPlanner(stale))
    state = runner.initial(0.0)
    plan = plan_of(runner, "lamp.bell", ["lamp.ring"])
    tick = Tick(runner, state, 0.0)
    assert not take(tick, plan, 0, supervised=True)
    assert state.values["lamp.bell"] is False
    [blocked] = tick.events
    assert blocked.kind is EventKind.BLOCKED and "goes first" in blocked.detail["why"]
    # the same after the runner halted the cycle: halting does not make the step safe
    result = runner.tick(state, Inputs(heartbeats=everyone(runner)), 0.1)
    assert result.state.halted
    tick = Tick(runner, result.state, 0.2)
    assert not take(tick, plan, 0, supervised=True)
    assert result.state.values["lamp.bell"] is False


# -- forbidden-state recovery ------------------------------------------------------------------


def test_a_controlled_recovery_step_is_taken_only_once_approved() -> None:
    """Someone took the part out from under the lowered press: the way out is to lift it,
    a step of the station's own, and even that waits for an operator's approval."""
    runner = runner_for(PRESS)
    state = runner.initial(0.0, {"press.down": True})
    heard = everyone(runner)
    result = runner.tick(state, Inputs(observed={"part.present": False}, heartbeats=heard), 0.1)
    kinds = [(e.kind, e.subject) for e in result.events]
    assert (EventKind.FORBIDDEN, "press_only_on_a_part") in kinds
    assert (EventKind.APPROVAL, "press.lift") in kinds
    approval = next(e for e in result.events if e.kind is EventKind.APPROVAL)
    assert approval.detail["type"] == "controlled"
    state = result.state
    for k in range(2, 12):
        result = runner.tick(state, Inputs(heartbeats=heard), k / 10)
        state = result.state
        assert not [e for e in result.events if e.kind is EventKind.TAKEN]
        assert state.values["press.down"] is True
    result = runner.tick(state, Inputs(heartbeats=heard, actions=(Approve(step=0),)), 1.2)
    assert [r.accepted for r in result.replies] == [True]
    assert (EventKind.TAKEN, "press.lift") in [(e.kind, e.subject) for e in result.events]
    assert result.state.values["press.down"] is False
    result = runner.tick(result.state, Inputs(heartbeats=heard), 1.3)
    assert EventKind.RECOVERED in [e.kind for e in result.events]
    assert result.state.recovery is None


def test_only_a_recovery_step_that_was_asked_for_can_be_answered() -> None:
    """A person answers what the watch showed: an approval for a step not yet asked (a
    stale page, a replayed request) is refused and nothing moves."""
    runner = runner_for(PRESS)
    heard = everyone(runner)
    state = runner.initial(0.0, {"press.down": True})
    state = runner.tick(
        state, Inputs(observed={"part.present": False}, heartbeats=heard), 0.1
    ).state
    assert state.recovery is not None and state.recovery.asked == {0}
    for step, why in ((3, "no such recovery step"), (0, "that step has not been asked for yet")):
        tried = state.copy()
        assert tried.recovery is not None
        tried.recovery.asked.clear()
        result = runner.tick(tried, Inputs(heartbeats=heard, actions=(Approve(step=step),)), 0.2)
        [reply] = result.replies
        assert not reply.accepted and reply.why == why
        assert not [e for e in result.events if e.kind is EventKind.TAKEN]
        assert result.state.values["press.down"] is True


# -- the retry limit ---------------------------------------------------------------------------


def test_an_operation_that_used_up_its_retries_is_not_tried_again() -> None:
    """E3 with one retry: get_nr_r1 fails once, which uses it up.  Neither the maintenance
    after it nor the background check may put it back to initial; with retries left (E3
    itself), the background check does."""
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    path = ROOT / "models" / "scenarios" / "e3_lock_fails_on_attach.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)

    def back_to_initial(retries: int) -> list[Event]:
        config = RunnerConfig(
            auto_intentions=scenario.config.auto_intentions,
            effect_timeouts=scenario.config.effect_timeouts,
            retries=retries,
        )
        played = play(station, replace(scenario, config=config), planners)
        return [
            e
            for e in played
            if e.kind is EventKind.OPERATION
            and e.subject == "get_nr_r1"
            and (e.detail["before"], e.detail["after"]) == ("error", "i")
        ]

    assert back_to_initial(retries=2)  # E3 as written: tried again
    assert back_to_initial(retries=1) == []


def test_maintenance_done_puts_an_operation_back_only_within_its_retries(
    demo_runner: Runner,
) -> None:
    """A finished maintenance plan for an operation in error: back to initial while it has
    retries left, else it stays in error."""
    runner = demo_runner
    for failures, expected in ((1, OperationState.INITIAL), (2, OperationState.ERROR)):
        state = runner.initial(0.0)
        state.intentions["tighten_bolts"] = IntentionState.ERROR
        state.operations["get_nr_r1"] = OperationState.ERROR
        state.failures["get_nr_r1"] = failures
        plan = plan_of(runner, "true", ["operator.hang_nr_from_r1"])
        plan.start(0)  # done: it has no effects to wait for
        state.maintenance, state.maintenance_for = plan, "get_nr_r1"
        state.next_background_check = 100.0  # not now: the maintenance alone decides
        result = runner.tick(state, Inputs(heartbeats=everyone(runner)), 1.0)
        assert result.state.operations["get_nr_r1"] == expected, failures


def test_the_background_check_clears_an_operation_only_within_its_retries(
    demo_runner: Runner,
) -> None:
    runner = demo_runner
    for failures, expected in ((1, OperationState.INITIAL), (2, OperationState.ERROR)):
        state = runner.initial(0.0)
        state.intentions["tighten_bolts"] = IntentionState.ERROR  # it needs the operation
        state.operations["get_nr_r1"] = OperationState.ERROR
        state.failures["get_nr_r1"] = failures
        result = runner.tick(state, Inputs(heartbeats=everyone(runner)), 0.0)
        assert result.state.operations["get_nr_r1"] == expected, failures


def test_an_operation_error_does_not_outlive_the_intentions_that_needed_it(
    demo_runner: Runner,
) -> None:
    runner = demo_runner
    state = runner.initial(0.0)
    state.operations["get_nr_r1"] = OperationState.ERROR
    state.failures["get_nr_r1"] = 2  # out of retries: only the release clears it
    result = runner.tick(state, Inputs(heartbeats=everyone(runner)), 0.0)
    assert result.state.operations["get_nr_r1"] == OperationState.INITIAL
    assert "get_nr_r1" not in result.state.failures
    [change] = [e for e in result.events if e.kind is EventKind.OPERATION]
    assert change.detail["why"] == "no intention needs it any more"


def test_a_resource_that_answers_again_clears_its_failures_and_is_rechecked_at_once(
    demo_runner: Runner,
) -> None:
    runner = demo_runner
    heard = everyone(runner)
    state = runner.initial(0.0)
    state.intentions["tighten_bolts"] = IntentionState.ERROR
    state.operations["get_nr_r2"] = OperationState.ERROR
    state.failures["get_nr_r2"] = 2  # out of retries while r2 was silent
    state.unavailable.add("r2")
    state.next_background_check = 50.0  # the periodic check is far off
    quiet = runner.tick(state, Inputs(heartbeats=heard - {"r2"}), 3.0)
    assert quiet.state.operations["get_nr_r2"] == OperationState.ERROR
    back = runner.tick(quiet.state, Inputs(heartbeats=heard), 3.1)
    assert EventKind.AVAILABLE in [e.kind for e in back.events]
    # the cause is gone: the failures it caused are forgotten, and the check runs at once
    assert back.state.operations["get_nr_r2"] == OperationState.INITIAL
    assert back.state.failures == {}


@pytest.fixture(scope="module")
def demo_runner() -> Runner:
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = TransitionPlanner(station.model), OperationPlanner(station)
    return Runner(station, *planners, RunnerConfig(auto_intentions=frozenset()))


# -- the monotonic abstraction -----------------------------------------------------------------


def test_the_transition_planner_changes_no_decision_of_another_operation() -> None:
    """Seed 000 sec. 4.3: while light_a executes, the runner may not light b (light_b's
    effect) to get there, although the panel would let it."""
    runner = runner_for(LAMPS)
    state = runner.initial(0.0)
    heard = everyone(runner)
    actions: tuple[StartIntention, ...] = (StartIntention(name="a_lit"),)
    for k in range(40):
        before = state
        result = runner.tick(state, Inputs(heartbeats=heard, actions=actions), k / 10)
        actions, state = (), result.state
        for event in result.events:
            if event.kind is EventKind.TAKEN and event.subject == "panel.light_b":
                executing = before.operations_in(OperationState.EXECUTING)
                executing += result.state.operations_in(OperationState.EXECUTING)
                assert "light_b" in executing, (k, event)


# -- life cycles -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def scenario_events() -> dict[str, list[Event]]:
    """Every scenario's one play in this test process (tests/support/plays.py)."""
    return {path.stem: plays.played(path.stem).events for path in SCENARIOS}


def test_every_change_of_state_in_every_scenario_follows_its_life_cycle(
    scenario_events: dict[str, list[Event]],
) -> None:
    cycles = {EventKind.INTENTION: INTENTION_LIFE_CYCLE, EventKind.OPERATION: OPERATION_LIFE_CYCLE}
    for name, events in scenario_events.items():
        now: dict[tuple[EventKind, str], str] = {}
        for event in events:
            if event.kind not in cycles:
                continue
            before, after = event.detail["before"], event.detail["after"]
            assert after in cycles[event.kind][before], (name, event)
            key = (event.kind, event.subject)
            assert now.get(key, "i") == before, (name, event)  # nothing changed unseen
            now[key] = after
            if after == "error":
                assert event.detail["why"], (name, event)  # an error always says why


def test_the_first_cause_of_an_error_is_kept_in_the_state() -> None:
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    path = ROOT / "models" / "scenarios" / "e3_lock_fails_on_attach.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    states: list[RunnerState] = []
    events = list(play(station, scenario, planners, watch=states.append))
    first = next(
        e
        for e in events
        if e.kind is EventKind.OPERATION
        and e.subject == "get_nr_r1"
        and e.detail["after"] == "error"
    )
    in_error = [s for s in states if s.operations["get_nr_r1"] == OperationState.ERROR]
    assert in_error
    assert {s.operation_causes["get_nr_r1"] for s in in_error} == {first.detail["why"]}
    assert "get_nr_r1" not in states[-1].operation_causes  # gone once it left the error


# -- replies and the station cycle -------------------------------------------------------------


def test_each_action_gets_a_typed_reply_in_its_order(demo_runner: Runner) -> None:
    runner = demo_runner
    state = runner.initial(0.0)
    actions = (
        StartIntention(user="ann", name="tighten_bolts"),
        StartIntention(user="ann", name="tighten_bolt"),
        Approve(user="ann", step=3),
        MaintenanceDone(user="ann", transition="operator.move_r2_home"),
    )
    result = runner.tick(state, Inputs(heartbeats=everyone(runner), actions=actions), 0.0)
    assert [r.action for r in result.replies] == list(actions)
    assert [r.accepted for r in result.replies] == [True, False, False, False]
    assert [(r.subject, r.why) for r in result.replies[1:]] == [
        ("tighten_bolt", "there is no such intention"),
        ("step 3", "no such recovery step"),
        ("operator.move_r2_home", "not a maintenance step asked for now"),
    ]
    assert str(result.replies[1]) == "tighten_bolt: there is no such intention"
    refused = [e for e in result.events if e.kind is EventKind.REFUSED]
    assert [e.subject for e in refused] == ["tighten_bolt", "step 3", "operator.move_r2_home"]


def test_maintenance_the_runner_accepted_is_done_in_the_world_too() -> None:
    """E6: r2 dies above the engine and the operator is asked to move it home.  Once the
    runner accepts the step, the devices (here simulated) see r2 at home as well."""
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    path = ROOT / "models" / "scenarios" / "e6_r2_disconnects_above_engine.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    runner = Runner(station, planners.transition, planners.operation, scenario.config)
    world = SimulatedWorld(
        station, delays=scenario.delays, default_delay=scenario.default_delay, start=scenario.start
    )
    cycle = StationCycle(runner, world, runner.initial(0.0, scenario.start), list(scenario.faults))
    now, asked = 0.0, ""
    while not asked and now < 120:
        for event in cycle.step(now).events:
            if event.kind is EventKind.INSTRUCTION:
                asked = event.subject
        now = round(now + 0.1, 6)
    assert asked == "operator.move_r2_home"
    assert world.values["r2.pos"] != "home"
    done = cycle.step(now, [MaintenanceDone(user="ann", transition=asked)])
    assert [r.accepted for r in done.replies] == [True]
    assert world.values["r2.pos"] == "home" and cycle.state.values["r2.pos"] == "home"


def test_the_devices_are_told_the_commands_only() -> None:
    runner = runner_for(PRESS)
    written: list[dict[str, object]] = []

    class Recorder(SimulatedWorld):
        def write(self, commands: Mapping[str, Value]) -> None:
            written.append(dict(commands))

    world = Recorder(runner.station)
    cycle = StationCycle(runner, world, runner.initial(0.0))
    cycle.step(0.1)
    assert written and all(set(w) == {"press.down"} for w in written)


def test_a_step_of_a_silent_resource_or_a_timed_out_effect_is_blocked_with_why() -> None:
    runner = runner_for(PRESS)
    state = runner.initial(0.0)
    state.unavailable.add("press")
    plan = plan_of(runner, "press.down", ["press.lower"])
    tick = Tick(runner, state, 1.0)
    assert not take(tick, plan, 0, supervised=True)
    assert [(e.kind, e.detail["why"]) for e in tick.events] == [
        (EventKind.BLOCKED, "press is not answering")
    ]
    assert state.values["press.down"] is False
    state.unavailable.clear()
    state.timed_out.add("press.lower")
    assert not take(tick, plan, 0, supervised=True)
    assert tick.events[-1].detail["why"] == "it did not happen in time and is disabled"


# -- what the station waits for, and people's time -------------------------------------------

NOD = """
station: nod
variables:
  - {name: part.checked, domain: bool, kind: decision}
resources:
  - name: inspector
    kind: person
    variables:
      - {name: asked, domain: bool, kind: command}
      - {name: nodded, domain: bool, kind: measured}
    transitions:
      - {name: ask, guard: "!asked && !part.checked", actions: ["asked := true"]}
      - {name: nod, kind: effect, guard: "asked && !nodded", actions: ["nodded := true"]}
      - {name: done, kind: automatic, guard: "asked && nodded && !part.checked",
         actions: ["asked := false", "part.checked := true"]}
  - name: gauge
    variables:
      - {name: on, domain: bool, kind: command}
      - {name: ready, domain: bool, kind: measured}
    transitions:
      - {name: switch_on, guard: "!on", actions: ["on := true"]}
      - {name: warm, kind: effect, guard: "on && !ready", actions: ["ready := true"]}
operations:
  - {name: check, precondition: "!part.checked", effects: ["part.checked := true"]}
intentions:
  - {name: checked, goal: "part.checked"}
"""


def test_a_persons_effect_is_never_timed_out_as_a_devices_is() -> None:
    runner = runner_for(NOD, RunnerConfig(auto_intentions=frozenset(), effect_timeout=1.0))
    assert runner.index.person_effects == {"inspector.nod"}
    state = runner.initial(0.0, {"inspector.asked": True, "gauge.on": True})
    heard = everyone(runner)
    timed_out: list[str] = []
    for k in range(40):  # 4 s: both effects enabled all along, neither happens
        result = runner.tick(state, Inputs(heartbeats=heard), k / 10)
        state = result.state
        timed_out += [e.subject for e in result.events if e.kind is EventKind.TIMEOUT]
    assert timed_out == ["gauge.warm"]
    # the configuration may still give a person's effect a time-out of its own
    config = RunnerConfig(effect_timeouts={"inspector.nod": 1.0})
    assert config.timeout_of("inspector.nod", person=True) == 1.0
    assert config.timeout_of("gauge.warm") == config.effect_timeout


def test_waiting_for_names_who_must_act(demo_runner: Runner) -> None:
    from planner.runner.waiting import Who, waiting_for

    runner = demo_runner
    state = runner.initial(0.0)
    assert waiting_for(runner, state) == []  # no intention active
    state.intentions["tighten_bolts"] = IntentionState.ERROR
    state.intention_causes["tighten_bolts"] = "no operation plan reaches its goal"
    [stuck] = waiting_for(runner, state)
    assert (stuck.who, stuck.subject) == (Who.ENGINEER, "tighten_bolts")
    assert "no operation plan reaches its goal" in stuck.what
    state.unavailable.add("r2")
    plan = plan_of(runner, "true", ["operator.move_r2_home"])
    plan.asked.add(0)
    state.maintenance, state.maintenance_for = plan, "get_nr_r2"
    items = [(w.who, w.subject) for w in waiting_for(runner, state)]
    assert items == [(Who.OPERATOR, "operator.move_r2_home"), (Who.DEVICE, "r2")]


def test_a_run_that_stops_says_what_it_waits_for() -> None:
    """E6 with nobody to move r2 home: the last event names the operator's step."""
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    path = ROOT / "models" / "scenarios" / "e6_r2_disconnects_above_engine.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    scenario = replace(scenario, maintenance=False, until=40.0)
    last = list(play(station, scenario, planners))[-1]
    assert last.kind is EventKind.STOPPED and last.subject == "time limit"
    waiting = last.detail["waiting_for"]
    assert {"who": "operator", "subject": "operator.move_r2_home"}.items() <= waiting[0].items()
    assert {"who": "device", "subject": "r2", "what": "r2 to answer again"} in waiting


def test_a_recovery_with_every_way_out_rejected_holds_quietly_and_says_whom_it_waits_for() -> None:
    """E2 with both offered recoveries rejected: the station plans once more, finds nothing,
    says so once and holds; no forbidden/plan pair every tick, other work coming to an end
    does not bring the rejected steps back, and the stop names the engineer.  Once the
    operator takes the filters off by hand, production goes on."""
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    path = (
        ROOT / "models" / "scenarios" / "faults" / "reject_oil_filter_removal_and_alternative.yaml"
    )
    scenario = load_scenario(path.read_text(), str(path), station)
    events = list(play(station, scenario, planners))
    [mounted] = [e.time for e in events if e.kind is EventKind.FAULT]
    rejects = [e.time for e in events if e.subject == "reject"]
    assert len(rejects) == 2
    after = [e for e in events if e.time >= rejects[-1]]
    plans = [e for e in after if e.kind is EventKind.PLAN]
    # planned once more when the state changed (the operator's card, a robot arriving), and
    # the rejections stand: nothing they read or write changed
    assert plans and {(p.subject, p.detail["status"]) for p in plans} == {
        ("TP w/MT", "unreachable")
    }
    assert [e.subject for e in after if e.kind is EventKind.ERROR] == ["no recovery plan"]
    # the violation is said once, when it is seen, however often recovery plans again
    assert [e.time for e in events if e.kind is EventKind.FORBIDDEN] == [mounted]
    last = events[-1]
    assert last.kind is EventKind.STOPPED
    [waiting] = last.detail["waiting_for"]
    assert (waiting["who"], waiting["subject"]) == ("engineer", "oil_filters_after_bolts")

    # a person puts it right by hand: the state changed, and production goes on
    removed = {f"oil_filter{k}.state": "none" for k in (1, 2, 3)}
    by_hand = rejects[-1] + 8.0
    fix = ScheduledFault(Fault(FaultKind.SET, values=removed), at=by_hand, text="taken off by hand")
    fixed = replace(scenario, faults=(*scenario.faults, fix), until=400.0)
    events = list(play(station, fixed, planners))
    assert events[-1].kind is EventKind.DONE


def test_recovery_steps_of_people_are_instructions_and_of_machines_approvals(
    demo_runner: Runner,
) -> None:
    """A recovery plan with the operator's maintenance step, the operator's own watch card
    and a robot's move: the maintenance step is an instruction (reported done, or rejected
    as "I cannot"), the watch card is shown at once (doing it is the consent), and only the
    robot's move waits for an approval.  The cards say the same."""
    from app.pages.cards import CardKind, TaskCard, task_cards
    from app.station.view import ActiveModel, StationView

    runner = demo_runner
    heard = everyone(runner)
    mounted = {f"oil_filter{k}.state": "mounted" for k in (1, 2, 3)}
    tightened = {f"bp{k}.state": "tightened" for k in (1, 2, 3)}
    state = runner.initial(0.0, {"frame.state": "on_engine", **tightened, **mounted})
    steps = ["operator.remove_oil_filters", "operator.place_bolts_bp4", "r1.goto_scan"]
    state.recovery = plan_of(runner, "true", steps)
    state.relaxed = frozenset(runner.semantics.violated(runner.index.as_state(state.values)))
    result = runner.tick(state, Inputs(heartbeats=heard), 0.1)
    kinds = {e.subject: e.kind for e in result.events if e.kind is not EventKind.FORBIDDEN}
    assert kinds["operator.remove_oil_filters"] is EventKind.INSTRUCTION
    assert kinds["operator.place_bolts_bp4"] is EventKind.TAKEN  # the watch shows the card
    recovery = result.state.recovery
    assert recovery is not None and recovery.approved == {0, 1}
    station = runner.station
    model = ActiveModel(1, 1, "", station, runner.transition_planner, runner.operation_planner)

    def cards(state: RunnerState) -> dict[str, TaskCard]:
        view = StationView(0, 0.0, model, runner, state, (), (), simulated=True)
        return {c.transition: c for c in task_cards(view) if c.transition}

    first = cards(result.state)["operator.remove_oil_filters"]
    assert first.kind is CardKind.INSTRUCTION and first.rejectable

    # the operator cannot take the filters off: rejected like an approval, and the way out
    # planned without it has robots' steps, which wait for approvals
    reject = Reject(user="operator", step=0)
    later = runner.tick(result.state, Inputs(heartbeats=heard, actions=(reject,)), 0.2)
    assert [r.accepted for r in later.replies] == [True]
    assert "operator.remove_oil_filters" in later.state.rejected
    recovery = later.state.recovery
    assert recovery is not None and recovery.steps[0] == "r1.goto_scan", recovery.steps
    asked = [e for e in later.events if e.kind is EventKind.APPROVAL]
    assert [e.subject for e in asked] == ["r1.goto_scan"]
    move = cards(later.state)["r1.goto_scan"]
    assert move.kind is CardKind.APPROVAL and "Nothing moves before you approve" in move.why
    assert move.title.endswith("machine steps") and move.plan[0] == "r1.goto_scan"
    assert later.state.values["r1.ref"] != "scan"  # not taken before it is approved


def test_a_new_model_version_keeps_what_both_versions_know(demo_runner: Runner) -> None:
    """carry_over: values still in their domain, restart mode with its reason, intentions
    that finished or failed (with why); plans, operations and failures start afresh."""
    from planner.runner.carry_over import carry_over

    old = demo_runner.initial(0.0, {"r1.pos": "scan", "r1.ref": "scan"})
    old.restart_mode, old.restart_reason, old.restart_user = True, "r2 pushed by hand", "eve"
    old.intentions["tighten_bolts"] = IntentionState.ERROR
    old.intention_causes["tighten_bolts"] = "no operation plan reaches its goal"
    old.operations["get_nr_r1"] = OperationState.ERROR
    old.failures["get_nr_r1"] = 2
    old.transition_plan = plan_of(demo_runner, "true", ["r1.goto_scan"])
    same = carry_over(old, demo_runner, 5.0)
    assert (same.restart_mode, same.restart_reason, same.restart_user) == (
        True,
        "r2 pushed by hand",
        "eve",
    )
    assert same.intentions["tighten_bolts"] == IntentionState.ERROR
    assert same.intention_causes == old.intention_causes
    assert same.values["r1.pos"] == "scan"
    assert same.operations["get_nr_r1"] == OperationState.INITIAL
    assert same.failures == {} and same.transition_plan is None

    mini = load_station(MINI.read_text(), str(MINI))
    other = Runner(mini, TransitionPlanner(mini.model), OperationPlanner(mini))
    moved = carry_over(old, other, 5.0)
    assert moved.values["r1.pos"] == "home"  # 'scan' is not a position of this version
    assert set(moved.intentions) == {"assemble"} and moved.intention_causes == {}
    assert moved.restart_mode


def test_a_watch_card_says_how_long_the_station_has_waited_once_it_reminded(
    demo_runner: Runner,
) -> None:
    """A person is reminded, not timed out: after a reminder the card says how long the
    station has been waiting for them; before it, nothing nags."""
    from app.pages.cards import CardKind, task_cards
    from app.station.view import ActiveModel, StationView

    runner = demo_runner
    station = runner.station
    model = ActiveModel(1, 1, "", station, runner.transition_planner, runner.operation_planner)
    state = runner.initial(0.0, {"operator.card": "place_bp1"})
    state.effect_enabled_since["operator.confirm"] = 10.0

    def why(now: float, reminded: dict[str, int]) -> str:
        view = StationView(0, now, model, runner, replace(state, reminded=reminded), (), (), True)
        [card] = [c for c in task_cards(view) if c.kind is CardKind.COMMAND]
        return card.why

    assert "waiting for you" not in why(100.0, {})
    assert why(160.0, {"operator.confirm": 1}).endswith("waiting for you for 2 min.")


def test_a_maintenance_plan_that_waits_for_what_can_no_longer_happen_is_made_again(
    demo_runner: Runner,
) -> None:
    """The maintenance plan waits for r1 to arrive at the scan pose, but r1 is already
    there (it arrived before the plan's step was taken): the plan is dropped, said so, and
    planned again from where the station is, instead of waiting for ever."""
    runner = demo_runner
    state = runner.initial(0.0, {"frame.state": "on_engine", "r1.pos": "scan", "r1.ref": "scan"})
    state.intentions["tighten_bolts"] = IntentionState.ERROR
    state.operations["get_nr_r1"] = OperationState.ERROR
    stale = plan_of(runner, "true", ["r1.goto_scan", "r1.goto.arrive"])
    stale.start(0)  # taken: waits for r1.goto.arrive, whose guard (ref != pos) is false
    state.maintenance, state.maintenance_for = stale, "get_nr_r1"
    result = runner.tick(state, Inputs(heartbeats=everyone(runner)), 0.1)
    blocked = [e for e in result.events if e.kind is EventKind.BLOCKED]
    assert [(e.subject, e.detail["why"]) for e in blocked] == [
        ("maintenance plan", "r1.goto.arrive can no longer happen")
    ]
    assert result.state.maintenance is not stale
    asked = [e for e in result.events if e.kind is EventKind.PLAN]
    assert asked and asked[0].detail["reason"] == "maintenance"
