"""The engineer's flow in a real browser: edit the model with a mistake, see it located at
its line, fix it, save it as a new version and activate it; the station page draws the plan."""

from __future__ import annotations

from typing import Any

import pytest

from tests.browser.test_browser_operator import screenshot, sign_in
from tests.support.paths import SCREENSHOTS
from tests.support.stations import RunningStation, new_password

DESKTOP = {"width": 1280, "height": 800}
GOOD = '"card == idle && done == idle"'
BAD = '"card == idle && done == idel"'


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """One station for the module: the model flow first, then E6 (it puts the station back)."""
    from tests.support.stations import start_station

    running = start_station(tmp_path_factory.mktemp("engineer"))
    running.serve()
    yield running
    running.stop()


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
    # the heading says so at once, without a reload
    page.locator("#model-running[data-active='2']").wait_for()
    assert page.locator("#model-running").inner_text() == "version 2 runs"
    # the editor holds version 2 (saved from it), now the active one: the heading says so
    assert page.locator("#model-editing").inner_text() == "Editing version 2 (active)"
    assert "against the active version 2" in page.locator("#model-diff").inner_text()
    page.locator("tr[data-version='1']").get_by_role("link", name="Diff to active").click()
    changed = page.locator("#model-diff pre.diff .add").first
    changed.wait_for()
    assert "on the ladder frame" in changed.inner_text()  # in version 1 only
    assert "on the frame" in page.locator("#model-diff pre.diff .del").first.inner_text()
    diff = page.locator("#model-diff pre.diff")
    assert diff.evaluate("e => e.scrollWidth <= e.clientWidth"), "the diff is cut"
    no_horizontal_scroll(page)
    screenshot(page, "engineer-model-activated.png")

    page.goto(served.url + "/station")
    page.locator("form[action='/station/intentions/start'] button").first.wait_for()
    # a Start whose precondition does not hold says why, before and after the click
    bolts = page.locator("#station-overview [data-intention='tighten_bolts']")
    needs = "the ladder frame is on the engine"
    assert bolts.locator("[data-waits-for]").inner_text() == f"Cannot start until {needs}"
    bolts.get_by_role("button", name="Start").click()
    page.locator("#flash").get_by_text(f"not yet: {needs}").wait_for()
    bolts = page.locator("#station-overview [data-intention='tighten_bolts']")
    bolts.locator("[data-waits-for]", has_text=f"Starts once {needs}").wait_for()
    bolts.get_by_role("button", name="Cancel").click()
    served.wait(lambda: "tighten_bolts" not in served.live.view.state.auto_start, 10)
    served.live.act(_start("assemble_engine")).result(10)
    page.locator("#station-overview [data-intention='assemble_engine'][data-state='e']").wait_for()
    screenshot(page, "engineer-station-overview.png")
    overview = page.evaluate("document.documentElement.scrollHeight")
    assert overview <= DESKTOP["height"], f"the overview is {overview} px tall"
    page.goto(served.url + "/station/details")  # the plan comes live (SSE)
    page.locator("#station-plans svg").first.wait_for(timeout=30_000)
    screenshot(page, "engineer-station.png")

    page.goto(served.url + "/simulation")
    assert page.get_by_text("E6: robot 2 stops answering above the engine").count() >= 1
    screenshot(page, "engineer-simulation.png")

    browser = page.context.browser
    phone = browser.new_context(viewport={"width": 390, "height": 844}).new_page()
    watch = browser.new_context(viewport={"width": 320, "height": 320}).new_page()
    for other in (phone, watch):
        other.context.add_cookies(page.context.cookies())
    for viewed in (page, phone, watch):
        for path in ("/station", "/station/details", "/model", "/station/timeline", "/simulation"):
            viewed.goto(served.url + path)
            viewed.locator("main h1").wait_for()
            no_horizontal_scroll(viewed)
    phone.context.close()
    watch.context.close()


def _start(name: str) -> Any:
    from planner.runner import StartIntention

    return StartIntention(user="engineer", name=name)


def work_the_cards(station: RunningStation, done: Any, seconds: float = 240) -> None:
    """The operator, without a browser: each card's action as the tasks page sends it."""
    import time

    from app.pages.cards import CardKind, task_cards
    from planner.runner import Approve, MaintenanceDone

    deadline = time.monotonic() + seconds
    while not done():
        assert time.monotonic() < deadline, "the run did not end"
        cards = task_cards(station.live.view)
        if not cards:
            time.sleep(0.05)
            continue
        card = cards[0]
        if card.kind is CardKind.APPROVAL:
            station.live.act(Approve(user="operator", step=card.step)).result(10)
        elif card.kind is CardKind.INSTRUCTION:
            action = MaintenanceDone(user="operator", transition=card.transition)
            station.live.act(action).result(10)
        else:
            station.live.confirm_card("operator", card.card).result(10)


def signed_in_as_engineer(page: Any, station: RunningStation) -> None:
    """The first sign-in of the module changes the password; later ones use the new one."""
    if "engineer" not in station.changed:
        sign_in(page, station, "engineer")
        return
    page.goto(station.url + "/login")
    page.fill("input[name=name]", "engineer")
    page.fill("input[name=password]", new_password("engineer"))
    page.locator("form[action='/login'] button[type=submit]").click()
    page.wait_for_url(lambda url: not url.endswith("/login"))


def no_horizontal_scroll(page: Any) -> None:
    width, inner = page.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
    assert width <= inner, f"{page.url} is {width} px wide on a {inner} px screen"


def test_an_estimate_that_makes_the_state_forbidden_is_confirmed_first_on_a_phone(
    served: RunningStation, browser: Any
) -> None:
    context = browser.new_context(viewport={"width": 390, "height": 844}, has_touch=True)
    page = context.new_page()
    page.set_default_timeout(20_000)
    page.on("dialog", lambda dialog: dialog.accept())
    live = served.live
    try:
        signed_in_as_engineer(page, served)
        page.goto(served.url + "/station/details")
        page.fill("#restart-reason", "checking the oil filters")
        page.get_by_role("button", name="Enter restart mode").click()
        served.wait(lambda: live.view.state.restart_mode, 10)
        page.goto(served.url + "/station/details?variable=oil_filter1.state")
        page.select_option("#set-variable-value", "mounted")
        page.fill("#set-variable-reason", "seen mounted")
        page.get_by_role("button", name="Set variable").click()
        warning = page.locator("#set-variable [data-forbidden-warning]")
        warning.wait_for()
        assert "oil filters only after every bolt pair is tightened" in warning.inner_text()
        assert warning.bounding_box()["width"] <= 390
        no_horizontal_scroll(page)
        shot = SCREENSHOTS / "engineer-set-forbidden-warning.png"
        page.locator("#set-variable").screenshot(path=str(shot))
        assert live.view.state.values["oil_filter1.state"] == "none"  # not done yet
        page.get_by_role("button", name="Set it anyway").click()
        served.wait(lambda: live.view.state.values["oil_filter1.state"] == "mounted", 10)
    finally:
        context.close()


def test_the_timeline_shows_a_run_of_e6(served: RunningStation, browser: Any) -> None:
    """E6 played to its end: r2's row shows its failed move and that it waited for a person,
    and the time lost is given to its silence, in words."""
    title, scenario = served.built.server.experiments["e6_r2_disconnects_above_engine"]
    served.live.play_experiment(scenario, title, "engineer").result(10)
    work_the_cards(served, lambda: served.live.view.state.intentions.get("tighten_bolts") == "f")
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    page.set_default_timeout(20_000)
    try:
        signed_in_as_engineer(page, served)
        page.goto(served.url + "/station/timeline")
        page.locator(".timeline[data-outcome='finished']").wait_for()
        r2 = ".timeline-chart .tl-bar[data-lane='r2']"
        assert page.locator(f"{r2}[data-kind='failed']").count() >= 1
        assert page.locator(f"{r2}[data-kind='maintenance']").count() >= 1
        assert page.locator(f"{r2}[data-kind='outage']").count() >= 1
        label = page.locator(".tl-row[data-lane='r2'] .tl-label tspan").all_text_contents()
        assert " ".join(label) == "robot 2"
        causes = page.locator("#losses td[data-cause]").all_inner_texts()
        assert "robot 2 stopped answering" in causes, causes
        chart = page.locator(".timeline-chart").bounding_box()
        assert chart is not None and chart["width"] <= 1280
        no_horizontal_scroll(page)
        screenshot(page, "engineer-timeline-e6.png")

        phone = browser.new_context(viewport={"width": 390, "height": 844}).new_page()
        phone.context.add_cookies(context.cookies())
        phone.goto(served.url + "/station/timeline")
        phone.locator(".timeline-chart").wait_for()
        no_horizontal_scroll(phone)
        phone.context.close()
    finally:
        context.close()
