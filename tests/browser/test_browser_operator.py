"""The operator's flows in a real browser on a watch-sized screen (320 x 320 px).

A real server (uvicorn on 127.0.0.1) runs the demo station on a fresh SQLite file with its
simulated devices; Debian's Chromium, driven by Playwright, signs in as the operator and
works the task cards: E2 (approve taking off the oil filters mounted too early) and E6 (move
r2 home by hand after it stopped answering).  Screenshots go to tests/screenshots/.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest

from tests.support.paths import SCREENSHOTS
from tests.support.stations import PASSWORDS, RunningStation, new_password

SCREENSHOTS = SCREENSHOTS
WATCH = {"width": 320, "height": 320}


def sign_in(page: Any, station: RunningStation, name: str) -> None:
    """Through the login form, changing the first-login password."""
    sign_in_first_time(page, station.url, name)
    station.changed.add(name)


def sign_in_first_time(page: Any, url: str, name: str) -> None:
    """The login form, then the first-login password change, as a new user meets them."""
    page.goto(url + "/login")
    page.fill("input[name=name]", name)
    page.fill("input[name=password]", PASSWORDS[name])
    page.locator("form[action='/login'] button[type=submit]").click()
    page.wait_for_url("**/password")
    page.fill("input[name=current_password]", PASSWORDS[name])
    page.fill("input[name=new_password]", new_password(name))
    page.fill("input[name=repeat]", new_password(name))
    page.locator("form[action='/password'] button[type=submit]").click()
    page.wait_for_url(lambda url: not url.endswith(("/password", "/login")))


def assert_fits_the_watch(page: Any) -> None:
    """No horizontal scrolling, and every button at least 44 px tall."""
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= WATCH["width"], f"the page is {width} px wide on a 320 px screen"
    for button in page.locator("section.card button").all():
        box = button.bounding_box()
        if box is not None:
            assert box["height"] >= 44 and box["width"] >= 44, f"a button is only {box}"


def operate(
    page: Any,
    until: Callable[[], bool],
    on_card: Callable[[str, str, Any], None],
    seconds: float = 240,
) -> list[tuple[str, str]]:
    """Act as the operator: approve each recovery step and do each task, until `until()`.

    Returns the cards seen, as (kind, title)."""
    seen: list[tuple[str, str]] = []
    deadline = time.monotonic() + seconds
    while not until():
        assert time.monotonic() < deadline, f"not done in {seconds} s; cards seen: {seen}"
        cards = page.locator("section.card.waits")
        if cards.count() == 0:
            page.wait_for_timeout(100)
            continue
        card = cards.first
        kind = card.get_attribute("data-kind") or ""
        title = card.locator(".card-title").inner_text()
        key = card.get_attribute("id")
        if (kind, title) not in seen:
            seen.append((kind, title))
            on_card(kind, title, card)
        button = "Approve" if kind == "approval" else "Done"
        card.get_by_role("button", name=button).click()
        # the answer replaces the cards once the runner has taken the tap (a loaded shared
        # machine has stalled this past 15 s once)
        page.wait_for_function(
            "key => !document.getElementById(key) || !document.getElementById(key).isConnected",
            arg=key,
            timeout=30_000,
        )
    return seen


def screenshot(page: Any, name: str) -> None:
    SCREENSHOTS.mkdir(exist_ok=True)
    page.screenshot(path=str(SCREENSHOTS / name), full_page=True)


def play(station: RunningStation, experiment: str) -> None:
    title, scenario = station.built.server.experiments[experiment]
    station.live.play_experiment(scenario, title, "engineer").result(10)


def finished(station: RunningStation, intention: str) -> Callable[[], bool]:
    return lambda: station.live.view.state.intentions.get(intention) == "f"


@pytest.fixture
def watch(browser: Any) -> Any:
    context = browser.new_context(viewport=WATCH, has_touch=True, is_mobile=True)
    page = context.new_page()
    page.set_default_timeout(15_000)
    yield page
    context.close()


def test_e2_operator_is_told_to_take_off_the_oil_filters_on_a_watch(
    served: RunningStation, watch: Any
) -> None:
    """The way out of E2's forbidden state is the operator's own step: an instruction card
    (done, or "I cannot do this"), not an approval of something the station would do."""
    sign_in(watch, served, "operator")
    screenshot(watch, "operator-watch-idle.png")
    play(served, "e2_oil_filter_early")
    checked: dict[str, bool] = {}

    def on_card(kind: str, title: str, card: Any) -> None:
        assert_fits_the_watch(watch)
        assert kind != "approval", title  # nothing of the station's to approve here
        if kind == "instruction" and "oil filters" in title:
            # nothing runs until the operator has done it: filters stay on meanwhile
            state = served.live.view.state
            assert state.recovery is not None and not state.recovery.taken
            assert state.values["oil_filter1.state"] == "mounted"
            assert "Not allowed now" in card.inner_text()  # abnormal, said in words
            assert card.get_attribute("data-abnormal") == "true"
            assert card.get_by_role("button", name="I cannot do this").count() == 1
            screenshot(watch, "operator-watch-recovery.png")
            checked["recovery"] = True
        elif kind == "instruction":
            screenshot(watch, "operator-watch-instruction.png")
        elif "command" not in checked:
            screenshot(watch, "operator-watch-task.png")
            checked["command"] = True

    seen = operate(watch, finished(served, "tighten_bolts"), on_card)
    assert checked.get("recovery"), f"no recovery card: {seen}"
    assert ("instruction", "Take off the oil filters mounted too early") in seen
    assert any(kind == "command" and "bolt pair" in title for kind, title in seen)
    kinds = [e.kind for e in served.live.view.events]
    assert "recovered" in kinds
    assert served.live.view.state.values["oil_filter1.state"] == "none"


def test_e6_operator_moves_r2_home_from_a_task_card_on_a_watch(
    served: RunningStation, watch: Any
) -> None:
    sign_in(watch, served, "operator")
    play(served, "e6_r2_disconnects_above_engine")

    def on_card(kind: str, title: str, card: Any) -> None:
        assert_fits_the_watch(watch)
        if kind == "instruction":
            text = card.inner_text()
            assert text.count("Robot 2 stopped answering") == 1, text  # the cause first
            screenshot(watch, "operator-watch-e6-instruction.png")

    seen = operate(watch, finished(served, "tighten_bolts"), on_card)
    assert ("instruction", "Move robot 2 home by hand") in seen, seen
    watch.goto(served.url + "/alarms")  # r2 was not answering: an alarm waits for a person
    assert watch.locator("li.alarm[data-key='resource:r2']").count() == 1
    assert_fits_the_watch(watch)
    screenshot(watch, "operator-watch-alarms.png")
    state = served.live.view.state
    assert state.values["r2.pos"] == "home"
    assert all(state.values[f"bp{k}.state"] == "tightened" for k in range(1, 5))
