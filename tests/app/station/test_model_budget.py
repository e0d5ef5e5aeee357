"""Models are read and built in a child process within a budget (issue 26)."""

from __future__ import annotations

import time

import pytest

from app.station.model_budget import ModelBudget, ModelChecks, OverBudget
from tests.support.bombs import synthesis_bomb
from tests.support.stations import MODEL


def test_reading_in_the_child_finds_what_the_loader_finds() -> None:
    checks = ModelChecks(ModelBudget(read_seconds=30))
    assert checks.problems(MODEL.read_text(encoding="utf-8"), "demo") == []
    found = checks.problems("variables:\n  - {name: x, domain: bool}\ntransitions: 3\n", "m")
    assert found and found[0][:2] == (3, 14), found


def test_a_supervisor_past_its_time_is_refused_in_words_and_its_child_ended() -> None:
    checks = ModelChecks(ModelBudget(seconds=1.0))
    started = time.monotonic()
    with pytest.raises(OverBudget) as refused:
        checks.build(synthesis_bomb(), "model version 2", None)
    assert refused.value.message == "the supervisor is too large to build within 1 s"
    assert time.monotonic() - started < 30  # the child's start, then one second
    assert checks.slots.acquire(blocking=False)  # its slot is free again
