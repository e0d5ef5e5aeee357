"""The task cards of a recovery in work terms: a plan approved as one decision, naming what
each machine step acts on; cause first, the model's safety note before Done; the next
maintenance step shown at once after the one before is done."""

from __future__ import annotations

import re

import pytest

from app.pages.cards import CardKind, TaskCard, task_cards
from app.station.cycle import StationCycle
from app.station.view import ActiveModel, StationView
from planner.runner import Event, RunnerState
from tests.support import plays


def _view(cycle: StationCycle, state: RunnerState, events: tuple[Event, ...] = ()) -> StationView:
    runner = cycle.runner
    model = ActiveModel(
        1, 1, "", runner.station, runner.transition_planner, runner.operation_planner
    )
    return StationView(0, 0.0, model, runner, state, (), events, simulated=True)


@pytest.fixture(scope="module")
def declined() -> tuple[StationCycle, float]:
    return plays.declined_e2()


def test_a_recovery_plan_is_one_card_naming_each_steps_object(
    declined: tuple[StationCycle, float],
) -> None:
    cycle, _ = declined
    cards = task_cards(_view(cycle, cycle.state))
    approvals = [c for c in cards if c.kind is CardKind.APPROVAL]
    assert len(approvals) == 1  # one decision, not one card per machine step
    [card] = approvals
    plan = cycle.state.recovery
    assert plan is not None
    machine = [k for k in range(len(plan.blocks)) if k in card.plan_steps]
    assert len(card.steps) == len(card.plan) == len(machine) >= 4
    # the whole plan in work terms: what it does to the bolt pairs, and how many steps
    assert re.fullmatch(r"Bolt pairs \d\u2013\d tightened: \d+ machine steps", card.title), card
    assert card.title.endswith(f"{len(card.steps)} machine steps")
    # each run of the nutrunner says which bolt pair it tightens; each differs
    runs = [line for line in card.steps if line.startswith("The nutrunner")]
    tightened = [re.search(r"bolt pair (\d) is tightened", line) for line in runs]
    assert runs and all(tightened)
    numbers = [m.group(1) for m in tightened if m]
    assert len(set(numbers)) == len(numbers)
    assert card.cause.startswith("Not allowed now: ") and "oil filters" in card.cause.lower()
    assert card.asked and set(card.asked) <= set(card.plan_steps)


def _e7_after_first_done() -> tuple[StationCycle, RunnerState, tuple[Event, ...]]:
    once = plays.played("e7_r2_disconnects_holding_tool", states=True)
    assert once.states is not None
    for state in once.states:
        plan = state.maintenance
        if plan is not None and plan.taken and not plan.asked - plan.taken:
            kinds = [plan.blocks[k].transition for k in plan.taken]
            if "operator.move_r2_home" in kinds:
                cycle, _ = plays.declined_e2()  # a cycle for its runner only
                return cycle, state, tuple(once.events[:200])
    raise AssertionError("no state between the two maintenance steps")


def test_the_next_maintenance_step_shows_at_once_with_what_the_station_does_first() -> None:
    """E7: after "move robot 2 home", the plan's robot steps (robot 1 above the engine, the
    nutrunner stopped) run before "take the nutrunner off robot 2"; that step is shown at
    once, without Done, saying what the station does first -- not "nothing for you"."""
    cycle, state, events = _e7_after_first_done()
    cards = task_cards(_view(cycle, state, events))
    assert cards, "nothing shown between two maintenance steps of one plan"
    card = cards[0]
    assert card.kind is CardKind.INSTRUCTION and card.transition == "operator.hang_nr_from_r2"
    assert card.waiting.startswith("Wait: the station first does this:")
    assert "the nutrunner" in card.waiting.lower()
    assert card.label.startswith("Next")
    assert "robot 2's emergency stop" in card.safety


def test_an_instruction_leads_with_the_cause_and_no_ambiguous_it() -> None:
    once = plays.played("e6_r2_disconnects_above_engine", states=True)
    assert once.states is not None
    cycle, _ = plays.declined_e2()
    for k, state in enumerate(once.states):
        if state.maintenance is not None and state.maintenance.asked - state.maintenance.taken:
            events = tuple(e for e in once.events if e.time <= k * 0.1 + 1e-9)
            [card] = [c for c in task_cards(_view(cycle, state, events)) if c.transition]
            break
    else:
        raise AssertionError("E6 asked for no maintenance step")
    assert card.cause == "Robot 2 stopped answering above the engine; robot 1 cannot go there."
    assert "It stopped" not in card.why and "The station cannot go on with:" in card.why
    assert card.transition == "operator.move_r2_home"
    assert card.safety == "press robot 2's emergency stop and switch it to hand guiding first"


def test_the_card_says_the_cause_and_the_safety_note_before_its_buttons(
    declined: tuple[StationCycle, float],
) -> None:
    from jinja2 import Environment, FileSystemLoader

    from tests.support.paths import REPOSITORY

    env = Environment(loader=FileSystemLoader(REPOSITORY / "templates"), autoescape=True)
    template = env.get_template("_tasks.html")
    cycle, _ = declined
    view = _view(cycle, cycle.state)
    [approval] = [c for c in task_cards(view) if c.kind is CardKind.APPROVAL]
    instruction = TaskCard(
        CardKind.INSTRUCTION,
        "m",
        "Move robot 2 home by hand",
        "The station cannot go on.",
        transition="operator.move_r2_home",
        cause="Robot 2 stopped answering.",
        safety="press robot 2's emergency stop first",
    )

    def html(card: TaskCard, role: str) -> str:
        user = type("U", (), {"role": role})()
        values = {"cards": [card], "view": view, "csrf_token": "t", "user": user}
        return template.render(values, station_activity=None)

    page = html(instruction, "operator")
    assert page.index("Robot 2 stopped answering.") < page.index(">Done<")
    assert page.index("Safety first:") < page.index(">Done<")
    operator = html(approval, "operator")
    assert operator.index(approval.cause) < operator.index("Approve all")
    assert operator.count('name="steps"') == len(approval.plan)
    assert "<details" in operator and all(line in operator for line in approval.steps[:1])
    assert "Approve this step only" not in operator  # per step: for an engineer who asks
    engineer = html(approval, "engineer")
    assert engineer.count("Approve this step only") == len(set(approval.asked))
