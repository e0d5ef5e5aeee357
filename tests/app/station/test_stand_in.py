"""The stand-in for the station's people (`app.station.stand_in`): it answers what the runner
asks as the scenario's operator would, each after the scenario's delay, in its own name, and
taps each card shown on a watch once."""

from __future__ import annotations

from dataclasses import replace

from app.station.scenario import Scenario
from app.station.stand_in import STAND_IN, StandIn
from planner.model.flat import TransitionKind
from planner.runner import Approve, Event, EventKind, MaintenanceDone, Reject
from tests.support import plays

SCENARIO = Scenario(file="s.yaml", delays={"operator": 2.0}, operator_delay=3.0)


def test_each_card_is_tapped_once_after_its_delay() -> None:
    station, _ = plays.demo()
    (_, watch), *_ = station.watches
    stand_in = StandIn(SCENARIO, station, user=STAND_IN, taps=True)
    shown = {watch.card: "place_bp1"}
    assert stand_in.cards_to_tap(10.0, shown) == []
    assert stand_in.cards_to_tap(11.9, shown) == []
    assert stand_in.cards_to_tap(12.0, shown) == [(watch.confirm, "place_bp1")]
    assert stand_in.cards_to_tap(12.1, shown) == []  # once, though it is still shown
    assert stand_in.cards_to_tap(13.0, {watch.card: "place_bp2"}) == []  # another card
    assert stand_in.cards_to_tap(15.0, {watch.card: "place_bp2"}) == [(watch.confirm, "place_bp2")]
    assert stand_in.cards_to_tap(16.0, {watch.card: "idle"}) == []
    assert stand_in.cards_to_tap(17.0, {watch.card: "place_bp2"}) == []  # shown again: anew
    assert stand_in.cards_to_tap(19.0, {watch.card: "place_bp2"}) == [(watch.confirm, "place_bp2")]


def test_without_taps_the_cards_are_left_to_the_world() -> None:
    station, _ = plays.demo()
    (_, watch), *_ = station.watches
    stand_in = StandIn(SCENARIO, station)
    assert stand_in.cards_to_tap(0.0, {watch.card: "x"}) == []
    assert stand_in.cards_to_tap(100.0, {watch.card: "x"}) == []


def approval(step: int, kind: TransitionKind, subject: str = "t") -> Event:
    return Event(0.0, EventKind.APPROVAL, subject, {"step": step, "type": kind.value})


def test_approvals_and_maintenance_are_answered_in_the_stand_ins_name() -> None:
    station, _ = plays.demo()
    stand_in = StandIn(SCENARIO, station, user=STAND_IN)
    stand_in.answer(approval(0, TransitionKind.CONTROLLED), 10.0)
    stand_in.answer(approval(1, TransitionKind.MAINTENANCE, "mend"), 10.0)
    stand_in.answer(Event(10.0, EventKind.INSTRUCTION, "fix", {}), 10.0)
    stand_in.answer(Event(10.0, EventKind.PLAN, "x", {}), 10.0)  # asks nothing
    assert stand_in.due(12.9) == ()
    assert stand_in.due(13.0) == (
        Approve(user=STAND_IN, step=0),
        Approve(user=STAND_IN, step=1),
        MaintenanceDone(user=STAND_IN, transition="fix"),
    )
    assert stand_in.due(16.0) == (MaintenanceDone(user=STAND_IN, transition="mend"),)
    assert stand_in.due(100.0) == ()


def test_it_rejects_the_first_steps_the_scenario_says_then_approves() -> None:
    station, _ = plays.demo()
    stand_in = StandIn(replace(SCENARIO, rejects=1, maintenance=False), station)
    stand_in.answer(Event(0.0, EventKind.INSTRUCTION, "take_off", {"recovery": True, "step": 0}), 0)
    stand_in.answer(Event(0.0, EventKind.INSTRUCTION, "take_off", {"recovery": True, "step": 0}), 1)
    stand_in.answer(approval(1, TransitionKind.CONTROLLED), 1.0)
    assert stand_in.due(5.0) == (Reject(step=0), Approve(step=1))  # no maintenance done


def test_an_operator_who_does_not_approve_answers_nothing() -> None:
    station, _ = plays.demo()
    stand_in = StandIn(replace(SCENARIO, approve=False, maintenance=False), station)
    stand_in.answer(approval(0, TransitionKind.MAINTENANCE), 0.0)
    stand_in.answer(Event(0.0, EventKind.INSTRUCTION, "fix", {}), 0.0)
    assert stand_in.due(1000.0) == ()
