"""A resource whose devices answer but cannot act (a robot in a protective stop) is
unavailable at once, with the cause said, its steps held back with it, and the operator
named in `waiting_for`; it is available again in the first round it can act (issue 28)."""

from __future__ import annotations

import pytest

from planner.runner import EventKind, Runner, RunnerConfig
from planner.runner.tick_io import Inputs
from planner.runner.waiting import Who, waiting_for
from tests.support import plays

WHY = "r2 is in a protective stop: release it on r2's teach pendant"


@pytest.fixture(scope="module")
def demo_runner() -> Runner:
    station, planners = plays.demo()
    config = RunnerConfig(auto_intentions=frozenset())
    return Runner(station, planners.transition, planners.operation, config)


def test_a_resource_that_cannot_act_is_unavailable_at_once_and_back_when_it_can(
    demo_runner: Runner,
) -> None:
    runner = demo_runner
    everyone = frozenset(r.name for r in runner.station.resources)
    state = runner.initial(0.0)
    state = runner.tick(state, Inputs(heartbeats=everyone), 0.1).state
    stopped = Inputs(heartbeats=everyone - {"r2"}, cannot_act={"r2": WHY})
    result = runner.tick(state, stopped, 0.2)  # well within the heartbeat time-out
    [event] = [e for e in result.events if e.kind is EventKind.UNAVAILABLE]
    assert (event.subject, event.detail["why"]) == ("r2", WHY)
    state = result.state
    assert "r2" in state.unavailable and state.cannot_act == {"r2": WHY}
    waits = [(w.who, w.subject, w.what) for w in waiting_for(runner, state) if w.subject == "r2"]
    assert waits == [(Who.OPERATOR, "r2", WHY)]
    # said once while it stays so; a new cause is said again
    result = runner.tick(state, stopped, 0.3)
    assert not [e for e in result.events if e.kind is EventKind.UNAVAILABLE]
    # it answers (heartbeats keep it in `last_heard`) long past the time-out: still the cause
    state = result.state
    for k in range(40):
        state = runner.tick(state, stopped, 0.4 + 0.1 * k).state
    assert state.cannot_act == {"r2": WHY}
    # released: available again in that very round
    result = runner.tick(state, Inputs(heartbeats=everyone), 5.0)
    assert [e.subject for e in result.events if e.kind is EventKind.AVAILABLE] == ["r2"]
    assert "r2" not in result.state.unavailable and result.state.cannot_act == {}


def test_a_resource_that_goes_silent_after_a_stop_is_waited_for_as_silent(
    demo_runner: Runner,
) -> None:
    runner = demo_runner
    everyone = frozenset(r.name for r in runner.station.resources)
    state = runner.initial(0.0)
    state = runner.tick(state, Inputs(heartbeats=everyone - {"r2"}, cannot_act={"r2": WHY}), 0.1)
    state = state.state
    silent = Inputs(heartbeats=everyone - {"r2"})
    for k in range(40):  # 4 s: past the heartbeat time-out
        state = runner.tick(state, silent, 0.2 + 0.1 * k).state
    assert "r2" in state.unavailable and state.cannot_act == {}
    waits = [(w.who, w.what) for w in waiting_for(runner, state) if w.subject == "r2"]
    assert waits == [(Who.DEVICE, "r2 to answer again")]
