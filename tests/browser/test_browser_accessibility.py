"""axe-core on every page at the three sizes (issue 29): a 320 x 320 watch, a 390 x 844 phone
and a 1280 x 800 desktop, for every role's pages, idle and with work on them (a command card,
a maintenance step with its alarm, E2's abnormal step), the 404 page and the API docs: no
violation of impact serious or critical.

axe-core is not in git: `bash scripts/install` puts the npm registry's release, checked
against its pinned sha512, in tests/browser/vendor/ (see AXE_VERSION there).  The station's
Content-Security-Policy allows no injected script, so the browser contexts of this module
alone are made with `bypass_csp=True` (the pages' own policy is tested elsewhere:
test_browser_api_docs.py, tests/web/).

The keyboard test: the operator signs in, does a task card, opens the user menu and an
alarm's acknowledge form with Tab, Shift+Tab, Enter, Space and Escape only, and every
element reached shows a focus ring.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import pytest

from app.pages.cards import CardKind, TaskCard, task_cards
from hw.faults import Fault, FaultKind
from planner.runner import Approve, MaintenanceDone
from tests.support.paths import SCREENSHOTS, TESTS
from tests.support.stations import (
    REJECT_BUDGET,
    RunningStation,
    new_password,
    sign_in_with_forms,
    start_station,
)
from tests.web.test_no_internal_names import page_paths

AXE_VERSION = "4.14.1"  # as scripts/install's AXE_VERSION
AXE = TESTS / "browser" / "vendor" / f"axe-core-{AXE_VERSION}" / "axe.min.js"
SIZES = {
    "watch": {"width": 320, "height": 320},
    "phone": {"width": 390, "height": 844},
    "desktop": {"width": 1280, "height": 800},
}
# axe's findings a person is held back by: the serious and critical ones, each in one line
ROLES = ("", "operator", "auditor", "admin")  # "": signed out
OPERATOR_PAGES = ("/", "/alarms", "/today", "/account")
RUN_AXE = """async () => {
  const result = await axe.run(document, {resultTypes: ["violations"]});
  return result.violations
    .filter((v) => v.impact === "serious" || v.impact === "critical")
    .map((v) => `${v.id} (${v.impact}): ${v.help}; at ` +
      v.nodes.slice(0, 3).map((n) => n.target.join(" ")).join(", ") +
      (v.nodes.length > 3 ? ` and ${v.nodes.length - 3} more` : ""));
}"""


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    """One station with the API docs, the people's first-login passwords already changed
    (with time for E2's recovery planning on a loaded machine)."""
    assert AXE.is_file(), f"{AXE} is missing: `bash scripts/install` downloads axe-core"
    running = start_station(
        tmp_path_factory.mktemp("axe"), speed=12.0, planning_budget=REJECT_BUDGET, api_docs=True
    )
    running.serve()
    with httpx.Client(base_url=running.url, timeout=15) as client:
        for name in ("operator", "auditor", "admin"):
            sign_in_with_forms(client, name, first=True)
            running.changed.add(name)
            client.cookies.clear()
    yield running
    running.stop()


def axe_violations(page: Any) -> list[str]:
    """axe-core's serious and critical findings on the page as it is now, one line each."""
    page.evaluate(AXE.read_text(encoding="utf-8"))  # the policy is bypassed: see above
    found: list[str] = page.evaluate(RUN_AXE)
    return found


@dataclass
class Audit:
    """The pages checked at one size and the violations found, reported all at once."""

    size: str
    checked: list[str] = field(default_factory=list)
    found: list[str] = field(default_factory=list)

    def check(self, page: Any, moment: str) -> None:
        page.wait_for_load_state()
        if page.url.endswith("/docs"):
            page.wait_for_selector(".opblock-summary")  # Swagger UI draws the page itself
        where = f"{page.url.split('/', 3)[-1] or 'tasks'} ({moment}, {self.size})"
        self.checked.append(where)
        for violation in axe_violations(page):
            self.found.append(f"/{where}: {violation}")

    def visit(self, page: Any, url: str, moment: str, status: int = 200) -> None:
        answer = page.goto(url)
        assert answer is not None and answer.status == status, (url, moment)
        self.check(page, moment)

    def assert_clean(self) -> None:
        assert not self.found, (
            f"{len(self.found)} serious or critical axe-core violations on "
            f"{len(self.checked)} pages:\n" + "\n".join(self.found)
        )


def signed_in(browser: Any, station: RunningStation, size: str, name: str) -> Any:
    """A page of a new context at `size`, signed in as `name` (or anonymous for "")."""
    mobile = size != "desktop"
    context = browser.new_context(
        viewport=SIZES[size], has_touch=mobile, is_mobile=mobile, bypass_csp=True
    )
    page = context.new_page()
    page.set_default_timeout(20_000)
    if name:
        page.goto(station.url + "/login")
        page.fill("input[name=name]", name)
        page.fill("input[name=password]", new_password(name))
        page.locator("form[action='/login'] button[type=submit]").click()
        page.wait_for_url(lambda url: not url.endswith("/login"))
    return page


def play(station: RunningStation, experiment: str) -> tuple[str, ...]:
    title, scenario = station.built.server.experiments[experiment]
    station.live.play_experiment(scenario, title, "engineer").result(10)
    return scenario.started


def work_until(
    station: RunningStation, wanted: Callable[[TaskCard], bool], seconds: float = 90
) -> TaskCard:
    """Do the operator's first card (Done, Approve) until the first card is `wanted`."""
    found: list[TaskCard] = []

    def reached() -> bool:
        found[:] = task_cards(station.live.view)
        if found and wanted(found[0]):
            return True
        if found:
            do(station, found[0])
        return False

    station.wait(reached, seconds)
    return found[0]


def do(station: RunningStation, card: TaskCard) -> None:
    """The operator's tap on `card`, as the card's buttons do (a tap the station no longer
    needs is let go: the next look sees the fresh cards)."""
    live = station.live
    if card.kind is CardKind.COMMAND:
        done: Any = live.confirm_card("operator", card.card)
    elif card.kind is CardKind.APPROVAL:
        done = live.act(Approve(user="operator", step=card.step))
    else:
        done = live.act(MaintenanceDone(user="operator", transition=card.transition))
    try:
        done.result(10)
    except Exception:  # raced the station: the card went on
        return


def finish(station: RunningStation, intentions: tuple[str, ...]) -> None:
    """Every card done until the intentions finish; then the alarms acknowledged."""

    def finished() -> bool:
        state = station.live.view.state
        if all(state.intentions.get(name) == "f" for name in intentions):
            return True
        cards = task_cards(station.live.view)
        if cards:
            do(station, cards[0])
        return False

    station.wait(finished, 120)
    waiting = [a.key for a in station.live.view.alarms if a.waiting]
    if waiting:
        station.live.acknowledge_all(waiting, "operator", "checked").result(10)


def is_kind(kind: CardKind) -> Callable[[TaskCard], bool]:
    return lambda card: card.kind is kind


@pytest.mark.parametrize("size", list(SIZES))
def test_axe_finds_nothing_serious_on_any_page(
    station: RunningStation, browser: Any, size: str
) -> None:
    url, audit = station.url, Audit(size)
    pages = {name: signed_in(browser, station, size, name) for name in ROLES}
    anonymous, operator, auditor, admin = pages.values()
    try:
        audit.visit(anonymous, url + "/login", "signed out")
        audit.visit(anonymous, url + "/no-such-page", "signed out", 404)
        station.wait(lambda: not task_cards(station.live.view))
        for path in (*page_paths(station), "/password", "/docs"):
            audit.visit(admin, url + path, "idle")
        audit.visit(admin, url + "/no-such-page", "idle", 404)
        for path in OPERATOR_PAGES:
            audit.visit(operator, url + path, "idle")
        audit.visit(auditor, url + "/audit", "idle")
        station.wait(lambda: not any(a.active or a.waiting for a in station.live.view.alarms))
        audit.visit(operator, url + "/alarms", "no alarm")
        assert operator.locator("[data-testid=no-alarms]").count() == 1

        intentions = play(station, "e6_r2_disconnects_above_engine")
        work_until(station, is_kind(CardKind.COMMAND))
        audit.visit(operator, url + "/", "a command card")
        work_until(station, is_kind(CardKind.INSTRUCTION))
        assert any(a.waiting for a in station.live.view.alarms)
        for path in ("/", "/alarms"):
            audit.visit(operator, url + path, "E6's maintenance step")
        for path in ("/station", "/station/details", "/alarms"):
            audit.visit(admin, url + path, "E6's maintenance step")
        finish(station, intentions)

        # E2's abnormal step (its "I cannot do this" leads to approvals, whose card is this
        # one's with Approve and Reject; the planning that reject needs takes a minute on a
        # loaded machine, so approvals are not reached here)
        intentions = play(station, "e2_oil_filter_early")
        work_until(station, lambda card: card.rejectable)
        audit.visit(operator, url + "/", "E2's abnormal step")
        audit.visit(admin, url + "/station", "E2's forbidden state")
        finish(station, intentions)

        for path in OPERATOR_PAGES:
            audit.visit(operator, url + path, "after work")
        audit.visit(admin, url + "/station/timeline", "after work")
        audit.visit(auditor, url + "/audit", "after work")
    except BaseException:
        SCREENSHOTS.mkdir(exist_ok=True)
        for name, page in pages.items():
            page.screenshot(path=str(SCREENSHOTS / f"failed-axe-{size}-{name or 'anonymous'}.png"))
        raise
    finally:
        for page in pages.values():
            page.context.close()
    audit.assert_clean()


# the focused element and whether it shows a ring (outline or box-shadow); null on the body
FOCUSED = """() => {
  const e = document.activeElement;
  if (!e || e === document.body) return null;
  const s = getComputedStyle(e);
  const outline = s.outlineStyle !== "none" && parseFloat(s.outlineWidth) > 0;
  return {html: e.outerHTML.slice(0, 90), ring: outline || s.boxShadow !== "none"};
}"""


def press_until(page: Any, key: str, selector: str, most: int = 40) -> None:
    """Press `key` until the focus is on `selector`; each element it passes shows a ring."""
    for _ in range(most):
        page.keyboard.press(key)
        focused = page.evaluate(FOCUSED)
        if focused is None:
            continue
        assert focused["ring"], f"no visible focus on {focused['html']}"
        if page.evaluate("s => document.activeElement.matches(s)", selector):
            return
    raise AssertionError(f"{key} {most} times did not reach {selector}")


def fault(station: RunningStation, resource: str, kind: str) -> None:
    done = Fault(FaultKind(kind), resource=resource)
    station.live.inject(done, f"{resource}: {kind}", "engineer").result(10)


def acknowledge_with_the_keyboard(page: Any, station: RunningStation, key: str) -> None:
    """From the tasks page to the alarms, the alarm `key` opened and acknowledged with a
    note."""
    station.wait(lambda: any(a.key == key and a.waiting for a in station.live.view.alarms))
    press_until(page, "Tab", "nav a[href='/alarms']")
    page.keyboard.press("Enter")
    page.wait_for_url(station.url + "/alarms")
    row = f".alarm-row[data-key='{key}']"
    press_until(page, "Tab", f"{row} summary")
    page.keyboard.press("Enter")
    form = f"{row} form[action='/alarms/acknowledge']"
    press_until(page, "Tab", f"{form} input[name=note]")
    page.keyboard.type("seen from the keyboard")
    press_until(page, "Tab", f"{form} button")
    page.keyboard.press("Enter")
    station.wait(lambda: station.live.book.alarm(key).acked_by == "operator")
    assert station.live.book.alarm(key).note == "seen from the keyboard"


def test_the_operator_works_with_the_keyboard_only(station: RunningStation, browser: Any) -> None:
    """Sign in, do a task card, use the user menu and acknowledge an alarm with Tab,
    Shift+Tab, Enter, Space and Escape (a phone-sized window: the menu is folded)."""
    url = station.url
    context = browser.new_context(viewport=SIZES["phone"])
    page = context.new_page()
    page.set_default_timeout(20_000)
    try:
        page.goto(url + "/login")
        press_until(page, "Tab", "input[name=name]")
        page.keyboard.type("operator")
        press_until(page, "Tab", "input[name=password]")
        page.keyboard.type(new_password("operator"))
        page.keyboard.press("Enter")
        page.wait_for_url(url + "/")

        intentions = play(station, "e1_bolt_undone")
        card = work_until(station, is_kind(CardKind.COMMAND))
        shown = "key => document.querySelector('#tasks .task-now')?.dataset.key === key"
        page.wait_for_function(shown, arg=card.key)
        press_until(page, "Tab", "#tasks .done-button")
        page.keyboard.press("Space")
        station.wait(lambda: card.key not in [c.key for c in task_cards(station.live.view)])
        page.wait_for_function(f"key => !({shown.split('=> ', 1)[1]})", arg=card.key)

        # the user menu: opened with Enter, closed with Escape (the focus back on it)
        menu = page.locator("details.user-menu")
        press_until(page, "Shift+Tab", "details.user-menu > summary")
        page.keyboard.press("Enter")
        press_until(page, "Tab", "details.user-menu a[href='/today']")
        page.keyboard.press("Escape")
        assert menu.get_attribute("open") is None
        assert page.evaluate("document.activeElement.matches('details.user-menu > summary')")
        page.keyboard.press("Enter")
        press_until(page, "Tab", "details.user-menu a[href='/today']")
        page.keyboard.press("Enter")
        page.wait_for_url(url + "/today")
        finish(station, intentions)

        fault(station, "nr", "disconnect")
        acknowledge_with_the_keyboard(page, station, "resource:nr")
    except BaseException:
        SCREENSHOTS.mkdir(exist_ok=True)
        page.screenshot(path=str(SCREENSHOTS / "failed-keyboard.png"), full_page=True)
        raise
    finally:
        fault(station, "nr", "reconnect")
        context.close()
