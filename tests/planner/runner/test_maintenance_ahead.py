"""E7's second maintenance step, shown at once after the first is done.

The gap the watch showed ("nothing for you" for about 2 s between "move robot 2 home" and
"take the nutrunner off robot 2") is not a plan asked again: the maintenance plan is the
same throughout, and robot 1's move above the engine and the nutrunner's stop come between
(the supervisor lets a person take the nutrunner off only once it has stopped).
`next_maintenance` names the next person's step and what it waits for, so the card is up
at once."""

from __future__ import annotations

from planner.model.flat import TransitionKind
from planner.runner import EventKind, Runner
from planner.runner.maintenance import next_maintenance
from tests.support import plays


def test_the_next_maintenance_step_of_the_same_plan_is_known_at_once_after_a_done() -> None:
    once = plays.played("e7_r2_disconnects_holding_tool", states=True)
    assert once.states is not None
    station, planners = plays.demo()
    index = Runner(station, planners.transition, planners.operation).index
    done = next(e.time for e in once.events if e.subject == "maintenance done")
    asked = [e for e in once.events if e.kind is EventKind.INSTRUCTION]
    assert [e.subject for e in asked] == ["operator.move_r2_home", "operator.hang_nr_from_r2"]
    # the same plan all along: no plan asked between the first Done and the second step
    between = [e for e in once.events if done <= e.time < asked[1].time]
    assert not [e for e in between if e.kind is EventKind.PLAN]
    gap = [s for s in once.states if s.maintenance is not None]
    first_done = [
        s
        for s in gap
        if s.maintenance is not None
        and any(
            s.maintenance.blocks[k].transition == "operator.move_r2_home"
            for k in s.maintenance.taken
        )
        and not s.maintenance.asked - s.maintenance.taken
    ]
    assert first_done, "no round between the two steps"
    for state in first_done:
        plan = state.maintenance
        assert plan is not None
        ahead = next_maintenance(index, plan)
        assert ahead is not None
        k, waits = ahead
        assert plan.blocks[k].transition == "operator.hang_nr_from_r2"
        # what it waits for is the station's own steps, never a person's
        assert all(
            index.kind_of(plan.blocks[j].transition) is TransitionKind.CONTROLLED for j in waits
        )
    # before the person did any step of the plan, nothing is shown ahead
    before = next(s for s in gap if s.maintenance is not None and not s.maintenance.asked)
    assert before.maintenance is not None and next_maintenance(index, before.maintenance) is None
