"""E2's reject path on a 320 x 320 watch, in Chromium: after "I cannot do this" the station's
way out is one card, approved once.

The plan made after the reject is long when the fault comes early (the bolt pairs still to
be placed and tightened: about 30 steps) and its query takes tens of seconds on a shared
machine, so this station has a planning budget of its own (`PLANNING`)."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from typing import Any

import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from app.pages.cards import task_cards
from tests.browser.test_browser_accessibility import axe_violations
from tests.browser.test_browser_watch import (
    CARD,
    INTERNAL,
    Device,
    assert_usable,
    finished,
    play,
    screenshot,
    tap,
)
from tests.support.stations import RunningStation, start_station

PLANNING = 300.0  # seconds: the reject's recovery query, on a loaded machine


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(
        tmp_path_factory.mktemp("recovery"), speed=12.0, planning_budget=PLANNING
    )
    running.serve()
    yield running
    running.stop()


def test_after_i_cannot_do_this_the_recovery_is_one_decision_on_the_watch(
    station: RunningStation, browser: Any
) -> None:
    """E2's reject path: "I cannot do this" on taking the filters off; the station's way out
    is one card -- what is wrong above the buttons, the plan in work terms, its steps on
    demand -- approved once with "Approve all", and no step asks again."""
    watch = Device(browser, station, "watch")
    intentions = play(station, "e2_oil_filter_early")
    deadline = time.monotonic() + PLANNING + 120
    rejected, approvals = False, []
    while not finished(station, intentions):
        assert time.monotonic() < deadline, approvals
        cards = task_cards(station.live.view)
        if not cards:
            watch.page.wait_for_timeout(50)
            continue
        key = cards[0].key
        try:
            watch.shows(key, 5)
        except PlaywrightTimeout:
            continue
        card = watch.page.evaluate(CARD, key)
        if card is None or card["waiting"]:
            continue
        if card["kind"] == "approval":
            approvals.append(card)
            page = watch.page
            cause = page.locator("#tasks [data-testid=cause]").bounding_box()
            button = page.locator("#tasks button", has_text="Approve all").bounding_box()
            assert cause and button and cause["y"] + cause["height"] <= button["y"], card
            assert re.search(r"\d+ machine steps", card["text"]), card
            assert_usable(watch)  # one card, its buttons inside 320 x 320, targets of 44 px
            assert not axe_violations(page), axe_violations(page)  # and axe-core clean
            steps = page.locator("#tasks [data-testid=plan-steps]")
            steps.locator("summary").click()  # the steps on demand
            listed = steps.locator("li").all_inner_texts()
            assert len(listed) >= 2 and any("bolt pair" in line for line in listed), listed
            assert not INTERNAL.search(" ".join(listed)), listed
            screenshot(page, "watch-recovery-plan.png")
            steps.locator("summary").click()
            page.evaluate("() => window.scrollTo(0, 0)")
            button_name = "Approve all"
        elif card["abnormal"] and not rejected:
            button_name, rejected = "I cannot do this", True
        else:
            button_name = "Done"
        tap(watch, key, button_name)
    assert rejected
    assert len(approvals) == 1, [a["text"] for a in approvals]  # one decision, not one per step
    decided = [e for e in station.live.view.events if e.subject == "approve plan"]
    assert decided and decided[-1].detail["user"] == "operator"
    assert not [e for e in station.live.view.events if e.subject == "approve"]
    assert not watch.errors, watch.errors
    watch.context.close()
