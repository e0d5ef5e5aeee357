"""A forbidden-state recovery plan approved or refused in one decision (`ApprovePlan`,
`RejectPlan`): E2 with the filter removal declined, on the simulated world."""

from __future__ import annotations

import json
from collections.abc import Iterable

import pytest

from app.station.cycle import StationCycle
from planner.runner import (
    Action,
    ApprovePlan,
    Event,
    EventKind,
    Inputs,
    RejectPlan,
    Runner,
    TransitionPlan,
)
from planner.runner.forbidden import needs_approval
from planner.runner.snapshot import dump, load
from planner.runner.vocabulary import PersonAct
from tests.support import plays


def _shown(cycle: StationCycle) -> tuple[str, ...]:
    plan = cycle.state.recovery
    assert plan is not None
    return tuple(plan.blocks[k].transition for k in needs_approval(cycle.runner.index, plan))


def _run(cycle: StationCycle, now: float, until: float) -> tuple[list[Event], float]:
    events: list[Event] = []
    while now < until and cycle.state.recovery is not None:
        now = round(now + 0.1, 6)
        events += cycle.step(now).events
    return events, now


@pytest.fixture(scope="module")
def declined() -> tuple[StationCycle, float]:
    return plays.declined_e2()


def _copy(cycle: StationCycle) -> StationCycle:
    """A cycle of its own (the devices are played afresh; the runner state is copied)."""
    fresh, _ = plays.declined_e2()
    assert fresh.state.values == cycle.state.values
    return fresh


def test_one_approval_takes_every_machine_step_without_asking_again(
    declined: tuple[StationCycle, float],
) -> None:
    cycle, now = declined
    cycle = _copy(cycle)
    shown = _shown(cycle)
    assert len(shown) >= 4  # the robot's moves and the nutrunner's runs, more than one
    result = cycle.step(round(now + 0.1, 6), [ApprovePlan(user="ann", steps=shown)])
    assert [r.accepted for r in result.replies] == [True]
    [approved] = [e for e in result.events if e.kind is EventKind.OPERATOR]
    assert approved.subject == PersonAct.APPROVE_PLAN and approved.detail["user"] == "ann"
    assert approved.detail["transitions"] == list(shown)  # the audit names every step
    events, _ = _run(cycle, now + 0.1, now + 120)
    assert not [e for e in events if e.kind is EventKind.APPROVAL]  # asked once, not per step
    taken = [e.subject for e in [*result.events, *events] if e.kind is EventKind.TAKEN]
    assert [n for n in taken if n in shown] == list(shown)  # every step, none unapproved
    assert EventKind.RECOVERED in [e.kind for e in events]


def test_a_plan_that_changed_since_it_was_shown_is_refused(
    declined: tuple[StationCycle, float],
) -> None:
    cycle, now = declined
    shown = _shown(cycle)
    before = cycle.state
    for steps in (shown[:-1], (*shown, shown[0]), tuple(reversed(shown))):
        result = cycle.runner.tick(
            before, _inputs(cycle.runner, [ApprovePlan(user="ann", steps=steps)]), now
        )
        [reply] = result.replies
        assert not reply.accepted and "changed since it was shown" in reply.why
        plan = result.state.recovery
        assert plan is not None and plan.approved == _approved(before.recovery)
        assert [e.kind for e in result.events if e.kind is EventKind.REFUSED]


def test_refusing_the_plan_leaves_all_its_machine_steps_out_of_the_next(
    declined: tuple[StationCycle, float],
) -> None:
    cycle, now = declined
    shown = _shown(cycle)
    result = cycle.runner.tick(
        cycle.state, _inputs(cycle.runner, [RejectPlan(user="bo", steps=shown)]), now
    )
    assert [r.accepted for r in result.replies] == [True]
    [refused] = [e for e in result.events if e.kind is EventKind.OPERATOR]
    assert refused.subject == PersonAct.REJECT_PLAN and refused.detail["user"] == "bo"
    assert set(shown) <= result.state.rejected
    plan = result.state.recovery
    if plan is not None:
        assert not {b.transition for b in plan.blocks} & set(shown)


def test_an_approved_plan_round_trips_through_a_snapshot(
    declined: tuple[StationCycle, float],
) -> None:
    cycle, now = declined
    shown = _shown(cycle)
    result = cycle.runner.tick(cycle.state, _inputs(cycle.runner, [ApprovePlan(steps=shown)]), now)
    plan = result.state.recovery
    assert plan is not None and plan.approved - plan.asked  # approved in advance
    back = load(cycle.runner, json.loads(json.dumps(dump(result.state))), now)
    assert back.recovery is not None
    assert (back.recovery.approved, back.recovery.asked) == (plan.approved, plan.asked)


def _approved(plan: TransitionPlan | None) -> set[int]:
    return set() if plan is None else set(plan.approved)


def _inputs(runner: Runner, actions: Iterable[Action]) -> Inputs:
    heard = frozenset(r.name for r in runner.station.resources)
    return Inputs(heartbeats=heard, actions=tuple(actions))
