"""The API's documentation page (`sp serve --api-docs`, issue 26) in Debian's Chromium: the
vendored Swagger UI renders every area's operations and opens one under the page's policy
(no inline script or style, nothing from elsewhere) without a single violation, and the
browser asks no other host for anything."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any
from urllib.parse import urlsplit

import pytest

from tests.support.paths import SCREENSHOTS
from tests.support.stations import RunningStation, start_station

DESKTOP = {"width": 1280, "height": 800}
# every policy violation, as the page's own listener hears it
RECORD_VIOLATIONS = """
window.__violations = [];
document.addEventListener("securitypolicyviolation", (e) => {
  const where = `${e.sourceFile}:${e.lineNumber}`;
  window.__violations.push(`${e.violatedDirective} ${e.blockedURI} ${where}`);
});
"""


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(tmp_path_factory.mktemp("api-docs"), api_docs=True)
    running.serve()
    yield running
    running.stop()


def test_swagger_ui_renders_without_a_policy_violation(
    station: RunningStation, browser: Any
) -> None:
    context = browser.new_context(viewport=DESKTOP)
    context.add_init_script(RECORD_VIOLATIONS)
    page = context.new_page()
    page.set_default_timeout(15_000)
    errors: list[str] = []
    elsewhere: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on(
        "console",
        lambda m: errors.append(m.text) if m.type in ("error", "warning") else None,
    )
    own = urlsplit(station.url).netloc
    page.on(
        "request",
        lambda r: (
            elsewhere.append(r.url)
            if urlsplit(r.url).scheme in ("http", "https") and urlsplit(r.url).netloc != own
            else None
        ),
    )
    try:
        page.goto(f"{station.url}/docs")
        page.wait_for_selector(".opblock-summary")
        assert page.locator(".opblock").count() >= 23  # the API's operations
        assert "Sequence Planner station" in page.locator(".info .title").inner_text()
        page.locator(".opblock-summary").first.click()  # an operation opened: its details
        page.wait_for_selector(".opblock-body")
        page.wait_for_timeout(300)
        violations = page.evaluate("window.__violations")
        assert violations == [], violations
        assert [e for e in errors if "Content Security Policy" in e] == []
        assert errors == [], errors
        assert elsewhere == [], elsewhere
    except BaseException:
        SCREENSHOTS.mkdir(exist_ok=True)
        page.screenshot(path=str(SCREENSHOTS / "failed-api-docs.png"), full_page=True)
        raise
    finally:
        context.close()
