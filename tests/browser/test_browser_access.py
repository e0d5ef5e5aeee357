"""The auditor's and the refused person's pages in Debian's Chromium (issue 16), on one
station: the audit table neither scrolls sideways nor breaks a word across lines at 1280 and
390 px; the access-denied page fits a watch and links only where the role may go; a wrong
password leaves the name typed."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from app.store import audit
from app.store.audit import AuditEntry
from tests.support.paths import SCREENSHOTS
from tests.support.stations import (
    PASSWORDS,
    RunningStation,
    new_password,
    sign_in_with_forms,
    start_station,
)

SCREENSHOTS = SCREENSHOTS
DESKTOP = {"width": 1280, "height": 800}
PHONE = {"width": 390, "height": 844}
WATCH = {"width": 320, "height": 320}

# words of the cells cut in two by a line break (the client rects of a range over the word
# lie on more than one line) although the cell is wide enough for them, or although they
# are short enough for any column; only a longer word wider than its cell (a file path) may
# break
BROKEN_WORDS = """() => {
  const broken = [];
  for (const cell of document.querySelectorAll(".audit-table tbody td")) {
    const walker = document.createTreeWalker(cell, NodeFilter.SHOW_TEXT);
    for (let node = walker.nextNode(); node; node = walker.nextNode()) {
      if (node.parentElement.closest("pre")) continue;  // the opened JSON detail
      for (const match of node.data.matchAll(/\\S+/g)) {
        const range = document.createRange();
        range.setStart(node, match.index);
        range.setEnd(node, match.index + match[0].length);
        const rects = [...range.getClientRects()];
        const tops = new Set(rects.map((r) => Math.round(r.top)));
        const wide = rects.reduce((sum, r) => sum + r.width, 0);
        const style = getComputedStyle(cell);
        const tracks = style.display === "grid" ? style.gridTemplateColumns.split(" ") : [];
        const room = tracks.length  // a stacked cell: its value's column, beside the label
          ? parseFloat(tracks[tracks.length - 1])
          : cell.clientWidth - parseFloat(style.paddingLeft) - parseFloat(style.paddingRight);
        // a word of up to 32 characters (a model's name, a date) must fit any column
        if (tops.size > 1 && (wide <= room || match[0].length <= 32)) broken.push(match[0]);
      }
    }
  }
  return broken;
}"""


def fits(page: Any) -> None:
    width, inner = page.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
    assert width <= inner, f"the page is {width} px wide in a {inner} px window"


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    """A served station whose log holds long model names and details, as real ones do."""
    running = start_station(tmp_path_factory.mktemp("access"))
    running.serve()
    srv = running.built.server
    for k in range(20):
        detail = {"transition": "operator.remove_oil_filters", "why": "recovery step", "k": k}
        entries = [
            AuditEntry("operator", "operator.remove_oil_filters", "operator", "operator", detail),
            AuditEntry("alarm", "operation:locate_tool_r1", "", "r1", {"after": "normal"}),
            AuditEntry("model", "activated", "engineer", "", {"version": k, "previous": k - 1}),
            AuditEntry(
                "unexpected",
                "r1_cam.locate_tool.miss happened instead of r1_cam.locate_tool.found",
                "engineer",
                "r1_cam",
                {
                    "operation": "locate_tool_r1",
                    "intention": "tighten_bolts",
                    "why": "the 3D camera found nothing where the nutrunner should hang",
                },
            ),
        ]
        audit.write(srv.store, srv.live.name, entries, srv.live.wall())
    with httpx.Client(base_url=running.url) as client:
        sign_in_with_forms(client, "auditor", first=True)
    running.changed.add("auditor")
    yield running
    running.stop()


def opened(browser: Any, viewport: dict[str, int]) -> Any:
    small = viewport["width"] < 700
    context = browser.new_context(viewport=viewport, has_touch=small, is_mobile=small)
    page = context.new_page()
    page.set_default_timeout(15_000)
    return page


def sign_in(page: Any, station: RunningStation, name: str) -> None:
    page.goto(station.url + "/login")
    page.fill("input[name=name]", name)
    page.fill("input[name=password]", new_password(name))
    page.locator("form[action='/login'] button[type=submit]").click()
    page.wait_for_url(lambda url: not url.endswith("/login"))


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_the_audit_table_fits_and_breaks_no_word(
    station: RunningStation, browser: Any, viewport: dict[str, int]
) -> None:
    page = opened(browser, viewport)
    try:
        sign_in(page, station, "auditor")
        for show in ("people", "all"):
            page.goto(f"{station.url}/audit?show={show}")
            assert page.locator(".audit-table tbody tr").count() >= 60
            fits(page)
            assert page.evaluate(BROKEN_WORDS) == []
        page.locator(".audit-table tbody details > summary").first.click()
        fits(page)
        if viewport is DESKTOP:
            SCREENSHOTS.mkdir(exist_ok=True)
            page.goto(station.url + "/audit")
            page.screenshot(path=str(SCREENSHOTS / "auditor-audit-people.png"))
    finally:
        page.context.close()


def test_the_refusal_fits_a_watch_and_links_where_the_role_may_go(
    station: RunningStation, browser: Any
) -> None:
    page = opened(browser, WATCH)
    try:
        sign_in(page, station, "auditor")
        answer = page.goto(station.url + "/station")
        assert answer is not None and answer.status == 403
        assert "Your role (auditor) cannot see this page." in page.inner_text("main")
        links = page.locator('nav[aria-label="Pages you can open"] a')
        assert [links.nth(k).get_attribute("href") for k in range(links.count())] == [
            "/alarms",
            "/audit",
        ]
        fits(page)
        for k in range(links.count()):
            box = links.nth(k).bounding_box()
            assert box is not None and box["height"] >= 44 and box["width"] >= 44, box
        links.nth(1).click()
        page.wait_for_url("**/audit")
    finally:
        page.context.close()


def test_a_wrong_password_leaves_the_name_typed(station: RunningStation, browser: Any) -> None:
    page = opened(browser, PHONE)
    try:
        page.goto(station.url + "/login")
        page.fill("input[name=name]", "auditor")
        page.fill("input[name=password]", PASSWORDS["auditor"])  # changed since: wrong now
        page.locator("form[action='/login'] button[type=submit]").click()
        page.locator(".flash").first.wait_for()
        assert page.input_value("input[name=name]") == "auditor"
        assert page.input_value("input[name=password]") == ""
        assert page.evaluate("document.activeElement.name") == "password"
        icon = page.request.get(station.url + "/favicon.ico")
        assert icon.status == 200
    finally:
        page.context.close()


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_the_users_page_fits_with_its_forms_open(
    station: RunningStation, browser: Any, viewport: dict[str, int]
) -> None:
    """An admin's page: each user's last sign-in, and the role and password forms opened."""
    if "admin" not in station.changed:
        with httpx.Client(base_url=station.url) as client:
            sign_in_with_forms(client, "admin", first=True)
        station.changed.add("admin")
    page = opened(browser, viewport)
    try:
        sign_in(page, station, "admin")
        page.goto(station.url + "/users")
        auditor = page.locator('tr[data-user="auditor"]')
        assert "UTC" in auditor.locator(".last-sign-in").inner_text()
        for summary in ("Role…", "Reset password…"):
            auditor.locator("summary", has_text=summary).click()
        auditor.locator("input[name=password]").wait_for(state="visible")
        fits(page)
    finally:
        page.context.close()
