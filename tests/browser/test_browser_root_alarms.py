"""One fault, one alarm, in Debian's Chromium on a 320 x 320 watch: while E6 (robot 2 stops
answering above the engine) and E4 (robot 1's connector does not release) have put
operations in error, the alarm page shows one alarm, the fault's, with what it put in error
listed under it; the alarms each run raised are the scenario's `expect.alarms`
(`app.station.alarm_grouping`).  The watch's screenshot is
tests/screenshots/operator-watch-root-alarm.png."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from tests.browser.test_browser_operator import WATCH, sign_in_first_time
from tests.support.paths import SCREENSHOTS
from tests.support.stations import RunningStation, form_token, sign_in_with_forms, start_station
from tests.web.test_web_alarms import alarm_records, raised_since, work_through

EXPERIMENTS = {
    # experiment: (its root alarm, words of a consequence listed under it)
    "e6_r2_disconnects_above_engine": ("resource:r2", "robot 2 takes the nutrunner: in error"),
    "e4_lock_fails_on_release": ("effect:r1_tc.unlock.release", ": in error"),
}


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(tmp_path_factory.mktemp("root-alarms"))
    running.serve()
    yield running
    running.stop()


@pytest.fixture(scope="module")
def watch(browser: Any, station: RunningStation) -> Iterator[Any]:
    page = browser.new_context(viewport=WATCH, has_touch=True, is_mobile=True).new_page()
    page.set_default_timeout(15_000)
    sign_in_first_time(page, station.url, "operator")
    station.changed.add("operator")
    yield page
    page.context.close()


@pytest.mark.parametrize("name", list(EXPERIMENTS))
def test_a_fault_is_one_alarm_with_its_consequences_under_it(
    station: RunningStation, watch: Any, name: str
) -> None:
    root, consequence = EXPERIMENTS[name]
    title, scenario = station.built.server.experiments[name]
    before = len(alarm_records(station))
    station.live.play_experiment(scenario, title, "engineer").result(10)
    station.wait(lambda: station.live.view.experiment == title, 10)

    def grouped() -> bool:
        shown = [a for a in station.live.view.alarms if a.key == root and a.active]
        return bool(shown) and any(consequence in words for words in shown[0].consequences)

    station.wait(grouped, 90)
    watch.goto(station.url + "/alarms")
    lines = watch.locator("#alarms .alarm-list:not(.shelved) > li")
    assert lines.count() == 1, watch.locator("#alarms").inner_text()
    assert lines.first.get_attribute("data-key") == root
    assert "affected)" in lines.first.locator(".alarm-line").inner_text()
    lines.first.locator("summary").click()
    listed = lines.first.locator("[data-testid=consequences]")
    assert consequence in listed.inner_text()
    if name.startswith("e6"):
        watch.screenshot(path=str(SCREENSHOTS / "operator-watch-root-alarm.png"))
    with httpx.Client(base_url=station.url, timeout=15, follow_redirects=True) as operator:
        sign_in_with_forms(operator, "operator", first=False)
        token = form_token(operator.get("/").text)
        for intention in scenario.started:
            work_through(station, operator, token, intention)
    assert raised_since(station, before) == list(scenario.expect["alarms"])
