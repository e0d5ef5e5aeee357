"""The recovery card's words hold no model identifier nor paper reference (the check of
tests/web/test_no_internal_names.py, on every text the approval card shows)."""

from __future__ import annotations

from app.pages.cards import CardKind, task_cards
from tests.app.pages.test_recovery_cards import _view
from tests.support import plays
from tests.web.test_no_internal_names import internal_names, offences


def test_the_recovery_cards_words_name_no_model_identifier() -> None:
    cycle, _ = plays.declined_e2()
    forbidden = internal_names(cycle.runner.station)
    [card] = [c for c in task_cards(_view(cycle, cycle.state)) if c.kind is CardKind.APPROVAL]
    shown = [card.label, card.cause, card.title, card.why, card.detail, *card.steps]
    assert all(shown), shown
    assert [t for t in shown if offences(t, forbidden)] == []


def test_a_simulation_card_leads_with_plain_words_and_keeps_the_table_1_label_aside() -> None:
    """The words the simulation card shows for each recovery type (app.web.routes.simulation
    puts them first and the Table 1 label aside)."""
    from app.station.scenario import load_scenario
    from planner.words import recovery_words

    station, _ = plays.demo()
    path = plays.scenario_path("e7_r2_disconnects_holding_tool")
    scenario = load_scenario(path.read_text(), str(path), station)
    labels = [str(r) for r in scenario.expect["recovery"]]
    assert labels == ["TP w/RTO", "OP w/DO", "TP w/MT"]
    said = [recovery_words(label) for label in labels]
    assert said[0].startswith("the machines' steps planned again without")
    assert not [r for r in said if "w/" in r]
