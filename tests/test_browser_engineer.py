"""The engineer's flow in a real browser: edit the model with a mistake, see it located at
its line, fix it, save it as a new version and activate it; the station page draws the plan."""

from __future__ import annotations

from typing import Any

import pytest

from tests.stations import RunningStation
from tests.test_browser_operator import screenshot, sign_in

DESKTOP = {"width": 1280, "height": 900}
GOOD = '"card == idle && done == idle"'
BAD = '"card == idle && done == idel"'


@pytest.fixture
def desktop(browser: Any) -> Any:
    context = browser.new_context(viewport=DESKTOP)
    page = context.new_page()
    page.set_default_timeout(20_000)
    page.on("dialog", lambda dialog: dialog.accept())  # the confirmations (hx-confirm)
    yield page
    context.close()


def test_engineer_edits_the_model_sees_the_error_located_fixes_and_activates(
    served: RunningStation, desktop: Any
) -> None:
    page = desktop
    sign_in(page, served, "engineer")
    page.goto(served.url + "/model")
    editor = page.locator("#model-text")
    text = editor.input_value()
    assert text == served.live.model.text
    line = text[: text.index(GOOD)].count("\n") + 1
    column = text.splitlines()[line - 1].index(GOOD) + 1

    editor.fill(text.replace(GOOD, BAD, 1))
    page.get_by_role("button", name="Validate").click()
    error = page.locator(f"#model-errors li[data-line='{line}']")
    error.wait_for()
    assert "idel" in error.inner_text()
    assert int(error.get_attribute("data-column") or 0) >= column
    # the editor marks the line itself, with the message visible at it
    page.wait_for_selector(f".editor-line:nth-child({line}).is-error")
    assert page.locator(".editor-note").first.is_visible()
    screenshot(page, "engineer-model-error.png")

    # saving a broken model is refused and saves nothing
    page.get_by_role("button", name="Save as new version").click()
    page.locator("#model-errors li").first.wait_for()
    assert "tr[data-version='2']" not in page.content()

    fixed = text.replace(
        "place bolt pair {bp} on the ladder frame", "place bolt pair {bp} on the frame", 1
    )
    editor.fill(fixed)
    page.fill("#model-note", "shorter card text")
    page.get_by_role("button", name="Save as new version").click()
    page.locator("tr[data-version='2']").wait_for()
    assert page.locator("#model-errors li").count() == 0

    page.locator("tr[data-version='2']").get_by_role("button", name="Activate").click()
    served.wait(lambda: served.live.view.model.number == 2, 120)
    page.locator("tr[data-version='2'].is-active").wait_for(timeout=60_000)
    assert served.live.model.text == fixed
    screenshot(page, "engineer-model-activated.png")

    page.goto(served.url + "/station")
    page.locator("form[action='/station/intentions/start'] button").first.wait_for()
    served.live.act(_start("assemble_engine")).result(10)  # the plan comes live (SSE)
    page.locator("#station-plans svg").first.wait_for(timeout=30_000)
    screenshot(page, "engineer-station.png")

    page.goto(served.url + "/simulation")
    assert page.get_by_text("E6: r2 stops answering above the engine").count() >= 1
    screenshot(page, "engineer-simulation.png")


def _start(name: str) -> Any:
    from planner.runner import StartIntention

    return StartIntention(user="engineer", name=name)
