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
