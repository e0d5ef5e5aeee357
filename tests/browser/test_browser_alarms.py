"""The alarms page in Debian's Chromium (issue 16), on a 320 x 320 watch and a 1280 x 800
desktop looking at one station: an alarm takes one short line, its note field appears only
when acknowledging, nothing scrolls sideways and every target is at least 44 px; the badge
says the same count on the page, in the list's answers and in the SSE `alarm` event, and
follows a person's acknowledgement at once.  The watch's screenshot is
tests/screenshots/operator-watch-alarms.png."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from hw.faults import Fault, FaultKind
from tests.support.paths import SCREENSHOTS
from tests.support.stations import (
    RunningStation,
    form_token,
    new_password,
    sign_in_with_forms,
    start_station,
)

WATCH = {"width": 320, "height": 320}
DESKTOP = {"width": 1280, "height": 800}
OUT = ("r1", "r2", "nr")  # resources made to stop answering: one alarm each


SCREENSHOTS = SCREENSHOTS
# what a person taps: buttons, links that act, fields, and the lines that open an alarm
TARGETS = "button, a[href], input:not([type=hidden]), select, summary"


def sign_in_page(page: Any, station: RunningStation, name: str) -> None:
    """Through the login form (the first-login password was changed over HTTP already)."""
    assert name in station.changed
    page.goto(station.url + "/login")
    page.fill("input[name=name]", name)
    page.fill("input[name=password]", new_password(name))
    page.locator("form[action='/login'] button[type=submit]").click()
    page.wait_for_url(lambda url: not url.endswith("/login"))


def assert_fits(page: Any) -> None:
    """No horizontal scroll."""
    width, inner = page.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
    assert width <= inner, f"the page is {width} px wide in a {inner} px window"


def assert_targets(page: Any) -> None:
    """Every visible target of the alarm list and the top bar is at least 44 x 44 px."""
    small = page.evaluate(
        """selector => [...document.querySelectorAll(selector)]
          .filter(el => el.closest("#alarms, .topbar") && el.getClientRects().length)
          .map(el => [el.outerHTML.slice(0, 80), el.getBoundingClientRect()])
          .filter(([, r]) => r.width > 0 && (r.width < 44 || r.height < 44))
          .map(([html, r]) => `${html}: ${Math.round(r.width)}x${Math.round(r.height)}`)""",
        TARGETS,
    )
    assert not small, small


def fault(station: RunningStation, resource: str, kind: str) -> None:
    done = Fault(FaultKind(kind), resource=resource)
    station.live.inject(done, f"{resource}: {kind}", "engineer").result(10)


def waiting(station: RunningStation) -> list[str]:
    return sorted(a.key for a in station.live.view.alarms if a.waiting)


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    """One served station for the module, with three alarms waiting, one of them returned
    (its resource answers again) and one more shelved."""
    running = start_station(tmp_path_factory.mktemp("alarms"))
    running.serve()
    for resource in (*OUT, "operator"):
        fault(running, resource, "disconnect")
    running.wait(lambda: len(waiting(running)) == 4, 60)
    fault(running, "nr", "reconnect")
    running.wait(lambda: not running.live.book.alarm("resource:nr").active, 60)
    yield running
    running.stop()


@pytest.fixture(scope="module")
def operator(station: RunningStation) -> Iterator[httpx.Client]:
    """The operator signed in with plain HTTP (for the event stream and forms)."""
    with httpx.Client(base_url=station.url, timeout=15) as client:
        sign_in_with_forms(client, "operator", first=True)
        station.changed.add("operator")
        token = form_token(client.get("/alarms").text)
        shelved = client.post(
            "/alarms/shelve",
            data={"key": "resource:operator", "minutes": "30", "csrf_token": token},
            headers={"HX-Request": "true"},
        )
        assert shelved.status_code == 200, shelved.text
        yield client


def badge_of(html: str) -> int:
    found = re.search(r'class="alarm-count__n">(\d+)<', html)
    assert found, "no alarm badge"
    return int(found.group(1))


def next_alarm_event(lines: Iterator[str]) -> dict[str, Any]:
    """The data of the next `alarm` event on the stream (before its 15 s keep-alive)."""
    for line in lines:
        assert not line.startswith(": keep-alive"), "no alarm event within 15 s"
        if line == "event: alarm":
            data = next(lines)
            assert data.startswith("data: "), data
            found: dict[str, Any] = json.loads(data.removeprefix("data: "))
            return found
    raise AssertionError("the event stream ended")


def test_the_badge_is_the_same_on_the_page_in_the_list_and_in_the_event(
    station: RunningStation, operator: httpx.Client
) -> None:
    token = form_token(operator.get("/alarms").text)
    with operator.stream("GET", "/events") as events:
        lines = events.iter_lines()
        assert next(lines).startswith("retry:")
        # a person's acknowledgement changes no condition, yet the badge is told at once
        acked = operator.post(
            "/alarms/acknowledge",
            data={"key": "resource:r1", "csrf_token": token},
            headers={"HX-Request": "true"},
        )
        assert acked.status_code == 200, acked.text
        # the round that took it says the new count (an event of an earlier round may come
        # first: the stream is read only now)
        told = [next_alarm_event(lines)]
        while told[-1]["count"] != badge_of(acked.text) and len(told) < 5:
            told.append(next_alarm_event(lines))
        event = told[-1]
    shown = waiting(station)
    assert shown == ["resource:nr", "resource:r2"]
    page = operator.get("/alarms").text
    fragment = operator.get("/fragments/alarms", headers={"HX-Request": "true"}).text
    assert event["count"] == badge_of(acked.text) == badge_of(page) == badge_of(fragment) == 2
    assert event["priority"] == "high"


@pytest.mark.parametrize(
    ("viewport", "shot"),
    [(WATCH, "operator-watch-alarms.png"), (DESKTOP, "")],
    ids=["watch", "desktop"],
)
def test_an_alarm_takes_one_line_and_its_note_only_when_acknowledging(
    station: RunningStation,
    operator: httpx.Client,
    browser: Any,
    viewport: dict[str, int],
    shot: str,
) -> None:
    phone = viewport is WATCH
    context = browser.new_context(viewport=viewport, has_touch=phone, is_mobile=phone)
    try:
        page = context.new_page()
        page.set_default_timeout(15_000)
        sign_in_page(page, station, "operator")
        page.goto(station.url + "/alarms")
        rows = page.locator("ul.alarm-lines:not(.shelved) > .alarm-row")
        rows.first.wait_for()
        assert rows.count() == 3  # r1 acknowledged, r2 active, nr returned; the shelved apart
        for k in range(rows.count() + 1):
            box = page.locator(".alarm-lines > .alarm-row").nth(k).bounding_box()
            assert box is not None and box["height"] <= 2 * 44 + 8, f"an alarm is {box}"
        # the raise time on every line; the shelved one's end
        assert rows.locator(".alarm-line__time").count() == 3
        assert "until" in page.locator(".alarms-shelved + ul .alarm-line__time").inner_text()
        # no note fields until one acknowledges
        assert page.locator("input[name=note]:visible").count() == 0
        assert_fits(page)
        assert_targets(page)
        if shot:
            SCREENSHOTS.mkdir(exist_ok=True)
            page.screenshot(path=str(SCREENSHOTS / shot))

        r2 = page.locator('.alarm-row[data-key="resource:r2"]')
        r2.locator("summary").click()
        note = r2.locator("form[action='/alarms/acknowledge'] input[name=note]")
        note.wait_for(state="visible")
        button = r2.locator("form[action='/alarms/acknowledge'] button")
        page.wait_for_function(
            "el => el.getBoundingClientRect().bottom <= window.innerHeight",
            arg=button.element_handle(),
        )
        assert_fits(page)
        assert_targets(page)
        if shot:
            page.screenshot(path=str(SCREENSHOTS / shot.replace("alarms", "alarm-open")))
        page.locator("details.ack-all > summary").click()
        form = page.locator("form.ack-all__form")
        form.locator("input[name=note]").wait_for(state="visible")
        assert_fits(page)
        assert_targets(page)
    finally:
        context.close()


def test_acknowledge_all_with_one_note_clears_the_badge_at_once(
    station: RunningStation, operator: httpx.Client, browser: Any
) -> None:
    context = browser.new_context(viewport=DESKTOP)
    try:
        page = context.new_page()
        page.set_default_timeout(15_000)
        sign_in_page(page, station, "operator")
        page.goto(station.url + "/alarms")
        assert page.locator("#alarm-count .alarm-count__n").inner_text() == "2"
        page.locator("details.ack-all > summary").click()
        form = page.locator("form.ack-all__form")
        form.locator("input[name=note]").fill("robots lent to line 2")
        form.locator("button[type=submit]").click()
        page.wait_for_function(
            "() => document.querySelector('#alarm-count .alarm-count__n').textContent === '0'"
        )
        page.wait_for_function("() => !document.querySelector('.alarm-row.unacked')")
        assert waiting(station) == []
        r2 = station.live.book.alarm("resource:r2")
        assert (r2.acked_by, r2.note) == ("operator", "robots lent to line 2")
    finally:
        context.close()
