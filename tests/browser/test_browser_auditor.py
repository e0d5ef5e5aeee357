"""The auditor's flow in a real browser: filter the audit log by user and kind, page through
it, export the filtered rows as CSV; an auditor may look but not act."""

from __future__ import annotations

import csv
import io
from typing import Any

from tests.browser.test_browser_engineer import desktop  # noqa: F401 (fixture)
from tests.browser.test_browser_operator import screenshot, sign_in
from tests.support.stations import RunningStation


def test_auditor_filters_the_log_and_exports_csv(served: RunningStation, desktop: Any) -> None:  # noqa: F811
    page = desktop
    sign_in(page, served, "engineer")  # some history: a sign-in, a password change, an action
    from planner.runner import StartIntention

    served.live.act(StartIntention(user="engineer", name="assemble_engine")).result(10)
    # leave the engineer's live page first: signed out under it, its own updates send it to
    # the login page, and that navigation would race the one below
    page.goto("about:blank")
    page.context.clear_cookies()
    sign_in(page, served, "auditor")
    page.wait_for_url("**/audit")  # an auditor's home is the log

    page.select_option("#f-user", "engineer")
    page.select_option("#f-kind", "operator")
    page.get_by_role("button", name="Filter").click()
    page.wait_for_url("**user=engineer**")
    rows = page.locator("tbody tr[data-id]")
    assert rows.count() >= 1
    for k in range(rows.count()):
        assert rows.nth(k).locator("td[data-label='User']").inner_text() == "engineer"
        assert rows.nth(k).locator("td[data-label='Kind']").inner_text() == "operator"
    screenshot(page, "auditor-audit.png")

    with page.expect_download() as download:
        page.get_by_role("link", name="Export CSV").click()
    text = open(download.value.path(), encoding="utf-8").read()  # noqa: SIM115
    records = list(csv.DictReader(io.StringIO(text)))
    assert records and all(r["user"] == "engineer" and r["kind"] == "operator" for r in records)
    assert len(records) == rows.count()

    # looking is all an auditor may do
    assert page.goto(served.url + "/station").status == 403
    assert page.goto(served.url + "/simulation").status == 403
