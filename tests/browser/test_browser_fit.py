"""Every page fits its screen: no sideways scroll on a 320x320 watch, a 390x844 phone or a
1280x800 desktop, read by the admin (who may open every page) while the station shows work
on its pages: E6's maintenance card, then E2's forbidden state with its approvals.

The pages are found from the app's routes (tests/web/test_no_internal_names.py `page_paths`),
so a new page is checked without being listed here.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from planner.runner import Reject
from tests.browser.test_browser_operator import sign_in_first_time
from tests.support.stations import REJECT_BUDGET, RunningStation, start_station
from tests.web.test_no_internal_names import _cards_until, _play, operator_hands, page_paths

SCREENS = {
    "watch": {"width": 320, "height": 320},
    "phone": {"width": 390, "height": 844},
    "desktop": {"width": 1280, "height": 800},
}

WIDER_THAN_THE_SCREEN = """() => {
  const inner = window.innerWidth;
  const wide = [...document.querySelectorAll("body *")]
    .filter((e) => e.getBoundingClientRect().right > inner + 1 && e.offsetParent !== null)
    .filter((e) => !e.closest(".table-scroll, .editor, pre, svg"))
    .slice(0, 3)
    .map((e) => e.tagName.toLowerCase() + (e.id ? "#" + e.id : "") +
                (e.className && typeof e.className === "string" ? "." + e.className : ""));
  return [document.documentElement.scrollWidth, inner, wide];
}"""


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(tmp_path_factory.mktemp("fit"), planning_budget=REJECT_BUDGET)
    running.serve()
    yield running
    running.stop()


def test_no_page_scrolls_sideways_on_a_watch_a_phone_or_a_desktop(
    station: RunningStation, browser: Any
) -> None:
    paths = page_paths(station)
    assert {"/", "/station", "/station/details", "/model", "/users", "/audit"} <= set(paths)
    pages: dict[str, Any] = {}
    contexts = []
    too_wide: list[str] = []

    def check(moment: str) -> None:
        for screen, page in pages.items():
            for path in paths:
                answer = page.goto(station.url + path)
                assert answer is not None and answer.status == 200, (path, screen)
                width, inner, wide = page.evaluate(WIDER_THAN_THE_SCREEN)
                if width > inner:
                    too_wide.append(
                        f"{path} on a {screen} ({moment}): {width} px > {inner}; {wide}"
                    )

    with operator_hands(station):
        try:
            _play(station, "e6_r2_disconnects_above_engine")
            for screen, viewport in SCREENS.items():
                context = browser.new_context(viewport=viewport)
                contexts.append(context)
                page = context.new_page()
                page.set_default_timeout(15_000)
                if pages:  # the admin's other devices, in the same session
                    context.add_cookies(next(iter(pages.values())).context.cookies())
                else:
                    sign_in_first_time(page, station.url, "admin")
                pages[screen] = page
            _cards_until(station, lambda c: c.transition == "operator.move_r2_home")
            check("E6 maintenance card")
            _play(station, "e2_oil_filter_early")
            removal = "operator.remove_oil_filters"
            cards = _cards_until(station, lambda c: c.transition == removal)
            step = next(c.step for c in cards if c.transition == removal)
            station.live.act(Reject(user="operator", step=step)).result(10)
            _cards_until(station, lambda c: c.kind == "approval")
            check("E2 approvals")
        finally:
            for context in contexts:
                context.close()
    assert not too_wide, "pages wider than their screen:\n" + "\n".join(too_wide)
