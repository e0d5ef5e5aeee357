"""The operator's watch first, in Chromium: every card kind E1-E9 produce and the reject path,
on a 320 x 320 watch, a 390 x 844 phone and a 1280 x 800 desktop signed in to one station.

One simulated station (12 x real time) plays the experiments in sequence; the watch taps, the
phone and the desktop follow by themselves.  On every new card each page shows exactly one
card, its action inside the viewport, no horizontal scroll and touch targets of 44 px; the
pages that did not tap vibrate (navigator.vibrate is recorded by an init script).  Then: a
tap that raced another device gets a message and the fresh card; a card sent while the watch
was offline shows once it is back; "done today" counts the engines and the operator's taps.
Screenshots go to tests/screenshots/.
"""

from __future__ import annotations

import itertools
import re
import time
from collections.abc import Iterator
from typing import Any

import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from app.pages.cards import task_cards
from tests.browser.test_browser_operator import sign_in_first_time
from tests.support.paths import REPOSITORY, SCREENSHOTS
from tests.support.stations import REJECT_BUDGET, RunningStation, new_password, start_station
from tests.web.test_web_alarms import alarm_records, raised_since

SCREENSHOTS = SCREENSHOTS
VIEWPORTS = {
    "watch": {"width": 320, "height": 320},
    "phone": {"width": 390, "height": 844},
    "desktop": {"width": 1280, "height": 800},
}
RECORD_VIBRATIONS = """
window.__vibrations = [];
Object.defineProperty(Navigator.prototype, "vibrate", {
  configurable: true,
  value: function (pattern) { window.__vibrations.push(pattern); return true; },
});
"""
# what a person must not read on a card: model identifiers and paper references
INTERNAL = re.compile(r"\b(?:bp\d|nr|r\d_\w+|\w+_\w+|seed \d+|Figure \d+)\b|demo_station")
TARGETS = """() => [...document.querySelectorAll(
    'button, a[href], input:not([type=hidden]), select, textarea, summary')]
  .filter((e) => !e.closest('.skip-link'))
  .map((e) => [e, e.getBoundingClientRect()])
  .filter(([e, r]) => r.width > 0 && r.height > 0 && getComputedStyle(e).visibility !== 'hidden')
  .filter(([e, r]) => r.width < 44 || r.height < 44)
  .map(([e, r]) => `${e.outerHTML.slice(0, 60)} ${Math.round(r.width)}x${Math.round(r.height)}`)
"""


def screenshot(page: Any, name: str) -> None:
    SCREENSHOTS.mkdir(exist_ok=True)
    page.screenshot(path=str(SCREENSHOTS / name))


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(
        tmp_path_factory.mktemp("watch"), speed=12.0, planning_budget=REJECT_BUDGET
    )
    running.serve()
    yield running
    running.stop()


class Device:
    """One signed-in page, and the JavaScript errors it had."""

    def __init__(self, browser: Any, station: RunningStation, name: str) -> None:
        size = VIEWPORTS[name]
        mobile = name != "desktop"
        self.context = browser.new_context(viewport=size, has_touch=mobile, is_mobile=mobile)
        self.context.add_init_script(RECORD_VIBRATIONS)
        self.page = self.context.new_page()
        self.page.set_default_timeout(15_000)
        self.page.on("dialog", lambda dialog: dialog.accept())  # hx-confirm
        self.errors: list[str] = []
        self.lost_taps = 0  # taps that reached no button (the list replaced under them)
        self.page.on("pageerror", lambda exc: self.errors.append(str(exc)))
        self.page.on(
            "console",
            lambda m: self.errors.append(m.text) if "re-target" in m.text else None,
        )
        self.name, self.size = name, size
        if "operator" in station.changed:
            sign_in_again(self.page, station.url, "operator")
        else:
            sign_in_first_time(self.page, station.url, "operator")
            station.changed.add("operator")

    def key(self) -> str:
        key: str = self.page.evaluate(
            "document.querySelector('#tasks .task-now')?.dataset.key || ''"
        )
        return key

    def shows(self, key: str, seconds: float = 15) -> None:
        self.page.wait_for_function(
            "key => document.querySelector('#tasks .task-now')?.dataset.key === key",
            arg=key,
            timeout=seconds * 1000,
        )

    def vibrations(self) -> int:
        count: int = self.page.evaluate("window.__vibrations.length")
        return count


def sign_in_again(page: Any, url: str, name: str) -> None:
    page.goto(url + "/login")
    page.fill("input[name=name]", name)
    page.fill("input[name=password]", new_password(name))
    page.locator("form[action='/login'] button[type=submit]").click()
    page.wait_for_url(lambda u: not u.endswith("/login"))


@pytest.fixture(scope="module")
def devices(browser: Any, station: RunningStation) -> Iterator[dict[str, Device]]:
    found = {name: Device(browser, station, name) for name in VIEWPORTS}
    yield found
    for device in found.values():
        device.context.close()


def assert_usable(device: Device) -> None:
    """No horizontal scroll, touch targets of 44 px, and (with a card) exactly one card whose
    action button is whole inside the viewport."""
    page = device.page
    wide = page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
    assert wide <= 0, f"{device.name}: {wide} px of horizontal scroll"
    small = page.evaluate(TARGETS)
    assert not small, f"{device.name}: touch targets under 44 px: {small}"
    assert page.locator("#tasks section.card").count() == 1, device.name
    assert page.evaluate("() => window.scrollY") == 0, f"{device.name}: scrolled down"
    cards = page.locator("#tasks section.card.waits")
    if cards.count() == 0:
        return
    box = None
    for _ in range(20):  # a card being swapped in (the station moved meanwhile) has no box yet
        page.wait_for_function(SETTLED)
        box = cards.first.locator(".card-actions button").first.bounding_box()
        if box is not None:
            break
        page.wait_for_timeout(50)
    assert box is not None, device.name
    width, height = device.size["width"], device.size["height"]
    inside = box["x"] >= 0 and box["y"] >= 0
    inside = inside and box["x"] + box["width"] <= width and box["y"] + box["height"] <= height
    assert inside, f"{device.name}: the action button at {box} is outside {width}x{height}"
    text = cards.first.inner_text()
    assert not INTERNAL.search(text), f"{device.name}: a model name in {text!r}"


def play(station: RunningStation, experiment: str) -> tuple[str, ...]:
    title, scenario = station.built.server.experiments[experiment]
    station.live.play_experiment(scenario, title, "engineer").result(10)
    return scenario.started


def finished(station: RunningStation, intentions: tuple[str, ...]) -> bool:
    state = station.live.view.state
    return all(state.intentions.get(name) == "f" for name in intentions)


def work(
    station: RunningStation,
    devices: dict[str, Device],
    intentions: tuple[str, ...],
    reject: bool = False,
    seconds: float = 90,
) -> list[dict[str, Any]]:
    """The watch taps each card until the intentions finish (with `reject`, it cannot do the
    first recovery step); each new card is checked on every page.  Returns the cards, each
    with `new` (not shown before since its last tap: a card pushed back by one that came
    first is shown again) and the phone's `vibrations` so far."""
    watch = devices["watch"]
    seen: list[dict[str, Any]] = []
    untapped: set[str] = set()  # shown and not tapped yet
    deadline = time.monotonic() + seconds
    rejected = False
    while not finished(station, intentions):
        assert time.monotonic() < deadline, f"not done in {seconds} s: {seen}"
        cards = task_cards(station.live.view)
        if not cards:
            watch.page.wait_for_timeout(50)
            continue
        key = cards[0].key
        try:
            for device in devices.values():
                device.shows(key, 5)
        except Exception:  # the card went on, or another came first meanwhile: look again
            now = task_cards(station.live.view)
            if now and now[0].key == key:
                shown = {n: (d.key(), d.page.url) for n, d in devices.items()}
                raise AssertionError(f"{key} is not shown everywhere: {shown}") from None
            continue
        card = watch.page.evaluate(CARD, key)  # read at once: the page changes under us
        if card is None:  # another card came first meanwhile
            continue
        if card["waiting"]:  # the next step shown ahead: no Done until the station is ready
            watch.page.wait_for_timeout(50)
            continue
        if not seen or seen[-1]["key"] != key:
            card.update(key=key, new=key not in untapped)
            card["vibrations"] = devices["phone"].vibrations()  # the phone did not tap
            seen.append(card)
            untapped.add(key)
            for device in devices.values():
                assert_usable(device)
        if card["kind"] == "approval":
            button = "Approve all"
        elif reject and not rejected and card["abnormal"]:
            button, rejected = "I cannot do this", True
        else:
            button = "Done"
        take_screenshots(devices, card["kind"], key)
        if tap(watch, key, button):
            untapped.discard(key)
    return seen


CARD = """key => {
  const now = document.querySelector("#tasks .task-now");
  const card = now?.querySelector("section.card.waits");
  if (!card || now.dataset.key !== key) return null;
  return {kind: card.dataset.kind, abnormal: card.dataset.abnormal === "true",
          waiting: card.dataset.waiting === "true",
          label: card.querySelector(".card-kind").innerText, text: card.innerText};
}"""


def tap(watch: Device, key: str, button: str) -> bool:
    """Tap `button` on the card `key`, as a person would: again when the tap was lost (the
    card list replaced under the finger as another card came).  False when another card
    came first."""
    # the person had scrolled down (a long page): after the tap the next card shows from
    # the top (the tap without Playwright's scrolling to the button)
    watch.page.evaluate(LONG_PAGE)
    gone = "key => document.querySelector('#tasks .task-now')?.dataset.key !== key"
    for _ in range(3):
        watch.page.wait_for_function(SETTLED)  # a button swapped out under the tap is lost
        if not watch.page.evaluate(CLICK, [key, button]):  # another card came first meanwhile
            watch.page.evaluate(SHORT_PAGE)
            return False
        try:
            watch.page.wait_for_function(gone, arg=key, timeout=5_000)
            return True
        except PlaywrightTimeout:
            watch.lost_taps += 1
    raise AssertionError(f"three taps on {button} of {key} were lost")


# found and clicked at once: the card may go between a look and a tap from outside the page
CLICK = """([key, name]) => {
  const now = document.querySelector("#tasks .task-now");
  if (now?.dataset.key !== key) return false;
  const button = [...now.querySelectorAll(".card-actions button")]
    .find((b) => b.textContent.trim() === name);
  button?.click();
  return button !== undefined;
}"""


SHOTS: dict[str, str] = {}
LONG_PAGE = """() => {
  document.body.style.paddingBottom = "1000px";
  window.scrollTo(0, 400);
}"""


SETTLED = """() => !document.querySelector(
  "#tasks.htmx-swapping, #tasks.htmx-settling, #tasks .htmx-added"
)"""
SHORT_PAGE = """() => {
  document.body.style.paddingBottom = "";
  window.scrollTo(0, 0);
}"""


def take_screenshots(devices: dict[str, Device], kind: str, key: str) -> None:
    """The first card on the phone, the first approval on the watch, before the tap."""
    if "phone-card.png" not in SHOTS:
        screenshot(devices["phone"].page, "phone-card.png")
        SHOTS["phone-card.png"] = key
    if kind == "approval" and "watch-approval.png" not in SHOTS:
        screenshot(devices["watch"].page, "watch-approval.png")
        SHOTS["watch-approval.png"] = key


def test_the_watch_says_the_station_is_idle_before_anything_starts(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    watch = devices["watch"]
    watch.page.goto(station.url + "/")
    quiet = watch.page.locator("[data-testid=no-tasks]")
    assert quiet.get_attribute("data-activity") == "idle"
    assert "Nothing to do" in quiet.inner_text()
    header = watch.page.locator("header.topbar").bounding_box()
    assert header is not None and header["height"] <= 46, header
    assert "demo_station" not in watch.page.content().split("<main")[1]
    assert "demo_station" not in watch.page.title()
    for device in devices.values():
        device.page.goto(station.url + "/")
        assert_usable(device)
    screenshot(watch.page, "watch-idle.png")


EXPERIMENTS = sorted(p.stem for p in (REPOSITORY / "models" / "scenarios").glob("e[1-9]_*.yaml"))


def test_every_card_of_e1_to_e9_and_the_reject_path_on_three_screens(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    started = time.monotonic()
    cards: dict[str, list[dict[str, Any]]] = {}
    raised: dict[str, list[str]] = {}
    for experiment in EXPERIMENTS:
        before = len(alarm_records(station))
        intentions = play(station, experiment)
        cards[experiment] = work(station, devices, intentions)
        raised[experiment] = raised_since(station, before)
        devices["watch"].page.wait_for_function(
            "() => document.querySelector('[data-testid=no-tasks]')?.dataset.activity"
            " === 'complete'"
        )
    intentions = play(station, "e2_oil_filter_early")
    cards["reject"] = work(station, devices, intentions, reject=True)
    # one fault, one alarm: what each run raised on the live station is its `expect.alarms`
    experiments = station.built.server.experiments
    assert raised == {e: list(experiments[e][1].expect["alarms"]) for e in EXPERIMENTS}, raised

    kinds = {(c["kind"], c["abnormal"]) for run in cards.values() for c in run}
    assert kinds >= {
        ("command", False),  # routine: place a bolt pair
        ("instruction", False),  # maintenance after an error (E4, E6, E7)
        ("instruction", True),  # the operator's way out of a forbidden state (E2)
    }, kinds
    # after the reject the way out is the station's steps, approved, and (with operations in
    # parallel, when bolt pairs are still to be placed) the operator's own cards within it
    assert kinds <= {
        ("command", False),
        ("instruction", False),
        ("instruction", True),
        ("approval", True),
        ("command", True),
    }, kinds
    for run in cards.values():
        for card in run:
            if card["abnormal"]:
                assert card["label"].startswith("Abnormal"), card
            elif card["kind"] == "instruction":
                assert card["label"].startswith("Maintenance"), card
            else:
                assert card["label"].startswith("Your task"), card
    # every new card vibrated the phone, which never tapped (with operations in parallel two
    # cards can come between two looks, and one pushed back is shown again without a new one)
    shown = [card for run in cards.values() for card in run]
    counts = [card["vibrations"] for card in shown]
    assert all(b >= a for a, b in itertools.pairwise(counts)), counts
    new = list(itertools.accumulate(int(card["new"]) for card in shown))
    pairs = list(zip(counts, new, strict=True))
    assert all(c >= n for c, n in pairs), pairs
    assert devices["watch"].lost_taps <= 3, devices["watch"].lost_taps

    # E6: the cause first -- robot 2 stopped answering -- not a consequence
    e6 = [c for c in cards["e6_r2_disconnects_above_engine"] if c["kind"] == "instruction"]
    assert e6 and "robot 2 stopped answering" in e6[0]["text"].lower(), e6
    # E7: the person's steps numbered without gaps
    e7 = [c["label"] for c in cards["e7_r2_disconnects_holding_tool"] if c["kind"] != "command"]
    assert e7 == ["Maintenance · step 1 of 2", "Maintenance · step 2 of 2"], e7
    # the reject path: after "I cannot do this" the station found another way, shown as
    # abnormal cards (its steps to approve, the operator's own cards within it)
    rejected = next(k for k, c in enumerate(cards["reject"]) if c["kind"] == "instruction")
    assert any(c["abnormal"] for c in cards["reject"][rejected + 1 :]), cards["reject"]
    for device in devices.values():
        assert not device.errors, device.errors
    lost = devices["watch"].lost_taps
    print(f"E1-E9 and the reject path: {time.monotonic() - started:.1f} s, {lost} taps lost")


def test_e6_cause_card_on_the_watch(station: RunningStation, devices: dict[str, Device]) -> None:
    """Stops at E6's maintenance card for its screenshot, then finishes the run."""
    watch = devices["watch"]
    intentions = play(station, "e6_r2_disconnects_above_engine")
    deadline = time.monotonic() + 60
    while True:
        assert time.monotonic() < deadline
        cards = task_cards(station.live.view)
        if cards and cards[0].kind == "instruction":
            break
        if cards:
            try:
                watch.shows(cards[0].key, 5)
            except Exception:  # the card went on meanwhile: look again
                continue
            tap(watch, cards[0].key, "Done")  # again when the tap was lost under a swap
        else:
            watch.page.wait_for_timeout(50)
    watch.shows(cards[0].key)
    cause = watch.page.locator("#tasks [data-testid=cause]")
    # the cause, then what follows from it, from the model's specifications (planner.model.kept_out)
    assert "Robot 2 stopped answering above the engine; robot 1 cannot go there" in (
        cause.inner_text()
    )
    safety = watch.page.locator("#tasks [data-testid=safety]")
    assert "emergency stop" in safety.inner_text()  # the model's safety note, before Done
    done = watch.page.locator("#tasks .card-actions button", has_text="Done").bounding_box()
    above = [cause.bounding_box(), safety.bounding_box()]
    assert done and all(b and b["y"] + b["height"] <= done["y"] for b in above), (above, done)
    assert_usable(watch)  # Done still on the 320 x 320 screen
    screenshot(watch.page, "watch-e6-cause.png")
    # the connection drops: the banner says so, over the top bar, and Done stays on the screen
    watch.context.set_offline(True)
    watch.page.locator("#offline").wait_for(state="visible")
    banner = watch.page.locator("#offline").bounding_box()
    card = watch.page.locator("#tasks section.card").bounding_box()
    screenshot(watch.page, "watch-offline-card.png")
    assert banner and card and banner["y"] + banner["height"] <= card["y"], (banner, card)
    assert_usable(watch)
    watch.context.set_offline(False)
    watch.page.locator("#offline").wait_for(state="hidden")
    work(station, devices, intentions)


def test_a_tap_that_raced_another_device_gets_a_message_and_the_fresh_card(
    browser: Any, station: RunningStation, devices: dict[str, Device]
) -> None:
    late = Device(browser, station, "watch")
    try:
        late.page.route("**/events", lambda route: route.abort())  # it hears nothing new
        intentions = play(station, "e1_bolt_undone")
        station.wait(lambda: bool(task_cards(station.live.view)), 30)
        first = task_cards(station.live.view)[0]
        late.page.goto(station.url + "/")
        late.shows(first.key)
        station.live.confirm_card("operator", first.card).result(10)  # another device
        station.wait(lambda: first.key not in [c.key for c in task_cards(station.live.view)])
        late.page.locator("#tasks .card-actions").get_by_role("button", name="Done").click()
        stale = late.page.locator("[data-testid=stale]")
        stale.wait_for()
        assert stale.inner_text() == "Already done on another device."
        assert late.key() != first.key
        assert not late.errors, late.errors
        work(station, devices, intentions)
    finally:
        late.context.close()


def test_a_card_sent_while_offline_shows_when_the_watch_is_back(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    watch = devices["watch"]
    intentions = play(station, "e1_bolt_undone")
    station.wait(lambda: bool(task_cards(station.live.view)), 30)
    first = task_cards(station.live.view)[0]
    watch.shows(first.key)
    watch.page.wait_for_function("() => document.getElementById('conn').dataset.state === 'live'")
    watch.context.set_offline(True)
    watch.page.wait_for_function("() => document.getElementById('conn').dataset.state === 'down'")
    station.live.confirm_card("operator", first.card).result(10)  # done on another device
    station.wait(lambda: bool(task_cards(station.live.view)))
    sent = task_cards(station.live.view)[0]
    assert sent.key != first.key
    watch.context.set_offline(False)
    watch.shows(sent.key, 5)
    watch.page.wait_for_function(
        "() => document.getElementById('conn').dataset.state === 'live'", timeout=5000
    )
    work(station, devices, intentions)


def test_done_today_counts_the_engines_and_the_operators_taps(
    station: RunningStation, devices: dict[str, Device]
) -> None:
    for device in devices.values():
        device.page.goto(station.url + "/today")
        engines = device.page.locator("[data-testid=engines-today] li")
        tasks = device.page.locator("[data-testid=tasks-today] li")
        # only runs of the intention the model marks `product: true` are engines (assembling
        # the engine, which E4 starts; the other experiments only tighten bolts)
        assert engines.count() >= 1, engines.all_inner_texts()
        assert all("Assemble the engine" in t for t in engines.all_inner_texts())
        assert tasks.count() >= 4 * len(EXPERIMENTS), tasks.count()
        text = device.page.locator("main").inner_text()
        assert "Approved" in text and "Could not do" in text
        assert not INTERNAL.search(text), text
        wide = device.page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
        assert wide <= 0
        assert not device.page.evaluate(TARGETS), device.name
    screenshot(devices["watch"].page, "watch-done-today.png")
    # reachable from the watch's menu
    watch = devices["watch"].page
    watch.goto(station.url + "/")
    watch.locator("details.user-menu > summary").click()
    watch.locator("details.user-menu").get_by_role("link", name="Done today").click()
    watch.wait_for_url("**/today")
