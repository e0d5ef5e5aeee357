"""Issue 29, an operator never misses work, in Chromium: the offline state on every page
(greyed card area, "No connection since HH:MM", a vibration when the connection drops and
another when it is back), the task count on the Tasks tab and in the title of every page,
live; "Tap to turn on alerts"; a card the station has reminded the person of vibrates a
reminder; both devices of a same-round race are told; the password form keeps what was
typed; a page whose session ended with a role change goes to sign-in and comes back with
the new role's menu.  One station (12 x real time) for the module, a watch and a phone.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest

from app.pages.cards import CardKind, task_cards
from tests.browser.test_browser_operator import sign_in_first_time
from tests.browser.test_browser_watch import (
    Device,
    finished,
    screenshot,
    sign_in_again,
    tap,
    work,
)
from tests.support.stations import REJECT_BUDGET, RunningStation, start_station

# the vibration patterns of static/js/hmi.js (BUZZ), each told apart from a new card's
LOST, BACK, ALERTS = [600, 200, 100, 200, 100], [100, 100, 100], [150]
OVERDUE = [400, 150, 400, 150, 400]
BANNER = re.compile(r"^No connection since \d\d:\d\d — tasks may be missing$")
STUB_NOTIFICATIONS = """
window.__asked = 0;
let permission = %r;
Object.defineProperty(Notification, "permission", { configurable: true, get: () => permission });
Notification.requestPermission = () => { window.__asked += 1; permission = "granted";
  return Promise.resolve(permission); };
"""


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(
        tmp_path_factory.mktemp("never-miss"), speed=12.0, planning_budget=REJECT_BUDGET
    )
    running.serve()
    yield running
    running.stop()


@pytest.fixture(scope="module")
def devices(browser: Any, station: RunningStation) -> Iterator[dict[str, Device]]:
    found = {name: Device(browser, station, name) for name in ("watch", "phone")}
    yield found
    for device in found.values():
        device.context.close()


def play(
    station: RunningStation, experiment: str, reminder: float | None = None
) -> tuple[str, ...]:
    title, scenario = station.built.server.experiments[experiment]
    if reminder is not None:
        scenario = replace(scenario, config=replace(scenario.config, reminder=reminder))
    station.live.play_experiment(scenario, title, "engineer").result(10)
    return scenario.started


def finish_on(watch: Device, station: RunningStation, intentions: tuple[str, ...]) -> None:
    """The watch alone taps every card until `intentions` finish (other pages elsewhere)."""
    deadline = time.monotonic() + 90
    while not finished(station, intentions):
        assert time.monotonic() < deadline, "not finished in 90 s"
        cards = task_cards(station.live.view)
        if not cards:
            watch.page.wait_for_timeout(50)
            continue
        try:
            watch.shows(cards[0].key, 5)
        except Exception:  # the card went on meanwhile: look again
            continue
        tap(watch, cards[0].key, "Approve" if cards[0].kind is CardKind.APPROVAL else "Done")


# the top of the card shown and its key, in one look
CARD_TOP = """() => {
  const card = document.querySelector("#tasks section.card");
  const now = document.querySelector("#tasks .task-now");
  return [card.getBoundingClientRect().y, now ? now.dataset.key : ""];
}"""


def vibrations(device: Device) -> list[Any]:
    found: list[Any] = device.page.evaluate("window.__vibrations")
    return found


def conn(device: Device, state: str) -> None:
    device.page.wait_for_function(
        "s => document.getElementById('conn').dataset.state === s", arg=state
    )


def test_the_offline_state_is_unmistakable_and_ends_when_the_connection_is_back(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    watch, phone = devices["watch"], devices["phone"]
    watch.page.goto(station.url + "/")
    phone.page.goto(station.url + "/alarms")
    for device in (watch, phone):
        conn(device, "live")
    quiet = watch.page.locator("[data-testid=no-tasks]")
    normal = quiet.evaluate("e => getComputedStyle(e).borderTopStyle")
    for device in (watch, phone):
        before = len(vibrations(device))
        device.context.set_offline(True)
        banner = device.page.locator("#offline")
        banner.wait_for(state="visible")
        assert banner.get_attribute("role") == "alert"
        assert BANNER.match(banner.inner_text().strip()), banner.inner_text()
        assert vibrations(device)[before:] == [LOST], vibrations(device)
    # the quiet card, which says nothing is waiting, is no longer the normal grey one
    greyed = quiet.evaluate(
        "e => [getComputedStyle(e).borderTopStyle, getComputedStyle(e).backgroundImage,"
        " getComputedStyle(e.querySelector('.card-title')).textDecorationLine]"
    )
    assert normal != "dashed" and greyed[0] == "dashed", (normal, greyed)
    assert "repeating-linear-gradient" in greyed[1] and "line-through" in greyed[2], greyed
    screenshot(watch.page, "watch-offline.png")
    for device in (watch, phone):
        before = len(vibrations(device))
        device.context.set_offline(False)
        conn(device, "live")
        device.page.locator("#offline").wait_for(state="hidden")
        assert vibrations(device)[before:] == [BACK], vibrations(device)
        assert device.page.evaluate("document.body.dataset.offline") is None


def test_the_task_count_is_on_every_page_and_follows_the_cards(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    """The phone sits on the Alarms page while a card comes and is done on the watch."""
    watch, phone = devices["watch"], devices["phone"]
    phone.page.goto(station.url + "/alarms")
    watch.page.goto(station.url + "/")
    tab = phone.page.locator("nav .nav__list a[href='/']")
    assert tab.inner_text() == "Tasks" and phone.page.title().startswith("Alarms · ")
    conn(phone, "live")
    intentions = play(station, "e1_bolt_undone")
    phone.page.wait_for_function("() => /^\\(\\d+\\) Alarms · /.test(document.title)")
    assert re.fullmatch(r"Tasks \(\d+\)", tab.inner_text()), tab.inner_text()
    count = int(phone.page.title()[1 : phone.page.title().index(")")])
    assert count >= 1 and tab.inner_text() == f"Tasks ({count})"
    finish_on(watch, station, intentions)
    phone.page.wait_for_function("() => document.title.startsWith('Alarms · ')")
    assert tab.inner_text() == "Tasks"
    for device in devices.values():
        assert not device.errors, device.errors


def test_a_tap_that_went_as_a_plain_form_leaves_the_next_card_in_view(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    """A Done tapped before the page was ready goes as a plain form: the page comes back
    with "Done." -- over the top bar on the watch, gone after a few seconds -- and the next
    card where a card always is, its button on the 320 px screen."""
    watch = devices["watch"]
    watch.page.goto(station.url + "/")
    intentions = play(station, "e1_bolt_undone")
    watch.page.locator("#tasks section.card.waits").wait_for()
    top, key = watch.page.evaluate(CARD_TOP)  # read at once: the card area may be swapped
    with watch.page.expect_navigation():  # form.submit() fires no submit event: no htmx
        watch.page.evaluate(
            "() => document.querySelector('#tasks .card-actions button.done-button')"
            ".closest('form').submit()"
        )
    flash = watch.page.locator("main > .flash")
    assert flash.inner_text().strip() == "Done."
    watch.page.wait_for_function(
        "k => document.querySelector('#tasks .task-now')?.dataset.key !== k", arg=key
    )
    after, _ = watch.page.evaluate(CARD_TOP)
    assert abs(after - top) <= 1, (top, after)  # not pushed down
    flash.wait_for(state="hidden", timeout=10_000)
    finish_on(watch, station, intentions)


def test_tap_to_turn_on_alerts_vibrates_asks_and_says_how_when_blocked(
    browser: Any, station: RunningStation, devices: dict[str, Device]
) -> None:
    watch = devices["watch"]
    context = watch.context
    for permission in ("default", "denied"):
        page = context.new_page()
        page.add_init_script(STUB_NOTIFICATIONS % permission)
        try:
            page.goto(station.url + "/alarms")
            prompt = page.locator("#alerts")
            prompt.wait_for(state="visible")
            button = prompt.get_by_role("button", name="Tap to turn on alerts")
            denied = prompt.locator(".alerts__denied")
            if permission == "denied":
                assert denied.is_visible() and "site settings" in denied.inner_text()
                continue
            assert button.is_visible() and not denied.is_visible()
            screenshot(page, "watch-alerts-prompt.png")
            box = button.bounding_box()
            assert box is not None and box["height"] >= 44
            button.focus()  # by keyboard
            page.keyboard.press("Enter")
            prompt.wait_for(state="hidden")
            assert page.evaluate("window.__vibrations") == [ALERTS]
            assert page.evaluate("window.__asked") == 1
        finally:
            page.close()


def test_a_card_the_station_reminded_of_vibrates_a_reminder(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    watch = devices["watch"]
    watch.page.goto(station.url + "/")
    intentions = play(station, "e1_bolt_undone", reminder=2.0)
    overdue = watch.page.locator("#tasks section.card[data-overdue='true']")
    overdue.wait_for()
    assert overdue.locator("[data-testid=overdue]").is_visible()
    bottom = watch.page.evaluate(  # read at once: the card area may be swapped
        '() => document.querySelector(\'#tasks section.card[data-overdue="true"]'
        " .card-actions button').getBoundingClientRect().bottom"
    )
    assert bottom <= 320, bottom  # still on the watch's screen
    watch.page.wait_for_function(
        "p => window.__vibrations.some((v) => JSON.stringify(v) === JSON.stringify(p))",
        arg=OVERDUE,
    )
    play(station, "e1_bolt_undone")  # without reminders, to finish
    finish_on(watch, station, intentions)


# what the card area showed after each swap: the stale message and the card
RECORD_SWAPS = """() => {
  window.__swaps = [];
  document.addEventListener("htmx:afterSwap", () => {
    const now = document.querySelector("#tasks .task-now");
    const stale = now?.querySelector("[data-testid=stale]")?.innerText || "";
    window.__swaps.push([stale, now?.dataset.key || ""]);
  });
}"""
# a tap at wall-clock time `at` (ms), not waited for: both pages are handed theirs first
CLICK_AT = """at => { setTimeout(() => {
  document.querySelector("#tasks .card-actions button.done-button").click();
}, Math.max(0, at - Date.now())); }"""


def test_both_devices_of_a_same_round_race_are_told(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    """The watch and the phone tap Done on one card at the same moment: one tap is taken,
    the other gets "Already done on another device." and the fresh card."""
    watch, phone = devices["watch"], devices["phone"]
    for device in (watch, phone):
        device.page.goto(station.url + "/")
    intentions = play(station, "e1_bolt_undone")
    station.wait(lambda: bool(task_cards(station.live.view)), 30)
    first = task_cards(station.live.view)[0]
    assert first.kind is CardKind.COMMAND
    before = len(station.audit_records("operator", "card done"))
    for device in (watch, phone):
        device.shows(first.key)
    for device in (watch, phone):
        device.page.evaluate(RECORD_SWAPS)
    at = watch.page.evaluate("Date.now()") + 500
    for device in (watch, phone):
        device.page.evaluate(CLICK_AT, at)
    station.wait(lambda: len(station.audit_records("operator", "card done")) > before, 10)
    told = []
    for device in (watch, phone):  # each has had the answer to its own tap
        device.page.wait_for_function(
            "k => window.__swaps.some(([, key]) => key !== k)", arg=first.key
        )
        swaps = device.page.evaluate("window.__swaps")
        told.append([stale for stale, key in swaps if stale])
        assert all(key != first.key for stale, key in swaps if stale), swaps
    assert sorted(len(t) for t in told) == [0, 1], told
    assert [t for t in told if t] == [["Already done on another device."]], told
    assert len(station.audit_records("operator", "card done")) == before + 1
    work(station, devices, intentions)


def test_the_password_form_keeps_what_was_typed_when_it_is_too_short(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    page = devices["phone"].page
    page.goto(station.url + "/password")
    typed = {"current_password": "operator-changed-pw", "new_password": "short"}
    typed["repeat"] = "short"
    for field, value in typed.items():
        page.fill(f"#{field}", value)
    page.locator("form[action='/password'] button[type=submit]").click()
    assert page.url.endswith("/password")
    assert {f: page.input_value(f"#{f}") for f in typed} == typed
    assert page.evaluate("document.getElementById('new_password').validity.tooShort")
    page.fill("#new_password", "long-enough-1")
    page.fill("#repeat", "long-enough-2")
    assert page.evaluate("document.getElementById('repeat').validationMessage")


def test_a_new_role_takes_the_open_page_to_sign_in_and_back_with_its_menu(
    browser: Any, station: RunningStation
) -> None:
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    try:
        page = context.new_page()
        if "auditor" in station.changed:
            sign_in_again(page, station.url, "auditor")
        else:
            sign_in_first_time(page, station.url, "auditor")
            station.changed.add("auditor")
        page.goto(station.url + "/alarms")
        assert page.locator("nav a[href='/station']").count() == 0
        admin = station.client()
        token = station.login(admin, "admin")
        changed = admin.post(
            "/users/role", data={"name": "auditor", "role": "engineer", "csrf_token": token}
        )
        assert changed.status_code in (200, 303), changed.text
        started = time.monotonic()
        page.wait_for_url(re.compile(r"/login\?next=%2Falarms$"), timeout=20_000)
        print(f"signed out {time.monotonic() - started:.1f} s after the role change")
        page.fill("input[name=name]", "auditor")
        page.fill("input[name=password]", "auditor-changed-pw")
        page.locator("form[action='/login'] button[type=submit]").click()
        page.wait_for_url("**/alarms")
        assert page.locator("nav a[href='/station']").count() >= 1
    finally:
        context.close()
