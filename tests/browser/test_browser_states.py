"""Consistent states in a real browser (issue 29): E6 and E4 played from the simulation
panel, watched on the station page: a silent robot is never "idle", a tool changer the
operator is asked to mend is never "available"; Play says it drops the run going on; the
timeline's chart scrolls on a phone at a readable scale."""

from __future__ import annotations

import time
from typing import Any

import pytest

from tests.browser.test_browser_engineer import signed_in_as_engineer
from tests.browser.test_browser_operator import screenshot
from tests.support.stations import RunningStation

DESKTOP = {"width": 1280, "height": 800}
E6 = "e6_r2_disconnects_above_engine"
E4 = "e4_lock_fails_on_release"


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Any:
    from tests.support.stations import start_station

    running = start_station(tmp_path_factory.mktemp("states"))
    running.serve()
    yield running
    running.stop()


def play_from_the_panel(page: Any, served: RunningStation, experiment: str) -> str:
    """Press Play on the simulation panel; what its confirmation asked."""
    asked: list[str] = []

    def answer(dialog: Any) -> None:
        asked.append(dialog.message)
        dialog.accept()

    page.goto(served.url + "/simulation")
    page.once("dialog", answer)
    page.locator(f"#experiment-{experiment}").get_by_role("button", name="Play").click()
    page.locator("#flash", has_text="started").wait_for()
    return asked[0]


def operator_until_asked_to(served: RunningStation, mend: str, seconds: float = 240) -> None:
    """The operator confirms the cards (without a browser) until the instruction to `mend`
    is shown, and leaves that one waiting."""
    from app.pages.cards import CardKind, task_cards
    from planner.runner import Approve, MaintenanceDone

    deadline = time.monotonic() + seconds
    while True:
        assert time.monotonic() < deadline, f"no instruction {mend} within {seconds} s"
        cards = task_cards(served.live.view)
        if any(c.kind is CardKind.INSTRUCTION and c.transition == mend for c in cards):
            return
        if not cards:
            time.sleep(0.05)
            continue
        card = cards[0]
        if card.kind is CardKind.APPROVAL:
            served.live.act(Approve(user="operator", step=card.step)).result(10)
        elif card.kind is CardKind.INSTRUCTION:
            served.live.act(MaintenanceDone(user="operator", transition=card.transition)).result(10)
        else:
            served.live.confirm_card("operator", card.card).result(10)


def tile(page: Any, resource: str) -> Any:
    return page.locator(f"#station-overview li[data-resource='{resource}']")


def test_e6_and_e4_show_resource_states_consistent_with_what_the_station_waits_for(
    served: RunningStation, browser: Any
) -> None:
    context = browser.new_context(viewport=DESKTOP)
    page = context.new_page()
    page.set_default_timeout(30_000)
    live = served.live
    try:
        signed_in_as_engineer(page, served)
        asked = play_from_the_panel(page, served, E6)
        assert "drops it" not in asked  # nothing was running
        station = context.new_page()
        station.set_default_timeout(60_000)
        station.goto(served.url + "/station")
        r2 = tile(station, "r2")
        # E6: once r2 is silent, its tile says so, and never "idle" while it says so
        station.locator(
            "#station-overview li[data-resource='r2'][data-activity='silent']"
        ).wait_for()
        samples = []
        deadline = time.monotonic() + 4
        while time.monotonic() < deadline:
            samples.append((r2.get_attribute("data-activity"), r2.inner_text().lower()))
            time.sleep(0.2)
        silent = [text for activity, text in samples if activity == "silent"]
        assert silent and all("not answering" in t and "idle" not in t for t in silent)
        assert "r2" in live.view.state.unavailable
        screenshot(station, "engineer-station-r2-silent.png")

        # E4 while E6 runs: Play says the run is dropped
        asked = play_from_the_panel(page, served, E4)
        assert "A run is going" in asked and "drops it" in asked, asked
        operator_until_asked_to(served, "operator.reset_r1_tc")
        changer = tile(station, "r1_tc")
        station.locator(
            "#station-overview li[data-resource='r1_tc'][data-activity='faulted']"
        ).wait_for()
        badge = changer.locator("[data-badge]").inner_text()
        assert badge == "faulted" and "available" not in changer.inner_text().lower()
        assert "waiting for" in changer.inner_text().lower()
        screenshot(station, "engineer-station-tool-changer-faulted.png")
    finally:
        context.close()


def test_the_timeline_chart_scrolls_on_a_phone_at_a_readable_scale(
    served: RunningStation, browser: Any
) -> None:
    context = browser.new_context(viewport={"width": 390, "height": 844})
    page = context.new_page()
    page.set_default_timeout(20_000)
    try:
        signed_in_as_engineer(page, served)
        page.goto(served.url + "/station/timeline")
        chart = page.locator(".timeline-chart")
        chart.wait_for()
        box = chart.bounding_box()
        assert box is not None and box["width"] >= 900  # not a thumbnail
        figure = page.locator(".timeline__figure")
        assert figure.evaluate("e => e.scrollWidth > e.clientWidth")  # it scrolls sideways
        width, inner = page.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
        assert width <= inner  # the page itself does not
    finally:
        context.close()
