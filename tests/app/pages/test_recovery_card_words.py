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
    from app.station.scenario import load_scenario
    from app.web.routes.simulation import experiments_context
    from planner.words import Wording

    station, _ = plays.demo()
    path = plays.scenario_path("e7_r2_disconnects_holding_tool")
    scenario = load_scenario(path.read_text(), str(path), station)
    [row] = experiments_context({"e7": ("E7", scenario)}, Wording(station))["experiments"]
    assert row["recovery_labels"] == ["TP w/RTO", "OP w/DO", "TP w/MT"]
    assert row["recovery"][0].startswith("the machines' steps planned again without")
    assert not [r for r in row["recovery"] if "w/" in r]
