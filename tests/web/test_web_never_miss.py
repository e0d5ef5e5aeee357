"""Issue 29, an operator never misses work (the server's side; the browser's is
tests/browser/test_browser_never_miss.py): the task count on every page and in the event
stream, a card the station has reminded the person of marked overdue, a tap that lost a
same-round race refused and not recorded, a 404 page in the site's frame, a role's refusal
said once, and a password form the browser can check before it is sent."""

from __future__ import annotations

import contextlib
import json
import re
from collections.abc import Iterator
from dataclasses import replace

import httpx
import pytest

from app.pages.cards import CardKind, task_cards
from app.people.auth import MIN_PASSWORD
from app.station.live import StationError
from tests.support.stations import RunningStation, sign_in_with_forms, start_station


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(tmp_path_factory.mktemp("never-miss"), speed=8.0)
    running.serve()
    yield running
    running.stop()


def play(station: RunningStation, experiment: str, reminder: float | None = None) -> None:
    """`experiment` from its start; with `reminder`, people are reminded after that long."""
    title, scenario = station.built.server.experiments[experiment]
    if reminder is not None:
        scenario = replace(scenario, config=replace(scenario.config, reminder=reminder))
    station.live.play_experiment(scenario, title, "engineer").result(10)


def command_card(station: RunningStation) -> str:
    """The card value of the first command card, once there is one."""
    station.wait(lambda: any(c.kind is CardKind.COMMAND for c in task_cards(station.live.view)))
    return next(c.card for c in task_cards(station.live.view) if c.kind is CardKind.COMMAND)


@contextlib.contextmanager
def signed_in(station: RunningStation, name: str) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=station.url, timeout=30) as client:
        sign_in_with_forms(client, name, first=name not in station.changed)
        station.changed.add(name)
        yield client


def counted(station: RunningStation, client: httpx.Client, path: str) -> tuple[str, int]:
    """The page at `path` and the task cards waiting when it was made (read before and
    after: a page made while a card came is read again)."""
    for _ in range(20):
        before = len(task_cards(station.live.view))
        page = client.get(path)
        if len(task_cards(station.live.view)) == before:
            return page.text, before
    raise AssertionError("the cards kept changing")


def first_event(lines: Iterator[str], name: str) -> dict[str, object]:
    for line in lines:
        if line == f"event: {name}":
            data = next(lines)
            found: dict[str, object] = json.loads(data.removeprefix("data: "))
            return found
    raise AssertionError(f"no {name} event")


def test_every_page_counts_the_task_cards_in_its_tab_title_and_event_stream(
    station: RunningStation,
) -> None:
    play(station, "e1_bolt_undone")
    command_card(station)
    with signed_in(station, "operator") as operator, signed_in(station, "auditor") as auditor:
        for path, title in (("/alarms", "Alarms"), ("/", "Tasks"), ("/today", "Done today")):
            page, count = counted(station, operator, path)
            assert count >= 1
            assert re.search(rf"<title>\({count}\) {title} · ", page), (path, page[:600])
            tab = re.findall(r'<span class="nav-count" data-task-count="(\d+)"> \((\d+)\)<', page)
            assert tab and all(a == b == str(count) for a, b in tab), (path, tab)
    with signed_in(station, "engineer") as engineer:
        # many pages: on a narrow screen the tabs fold into the Menu, which carries the count
        page, count = counted(station, engineer, "/station")
        menu = re.search(r"<summary><span>Menu(.*?)</summary>", page)
        assert menu and f'data-task-count="{count}"> ({count})<' in menu.group(1), menu
    with signed_in(station, "operator") as operator, signed_in(station, "auditor") as auditor:
        with operator.stream("GET", "/events") as events:
            badge = first_event(events.iter_lines(), "badge")
        assert badge["tasks"] == len(task_cards(station.live.view)) >= 1, badge
        # an auditor sees no tasks: no count anywhere
        page = auditor.get("/alarms").text
        assert "data-task-count" not in page and re.search(r"<title>Alarms · ", page)
        with auditor.stream("GET", "/events") as events:
            assert "tasks" not in first_event(events.iter_lines(), "badge")


def test_a_card_is_overdue_once_the_station_reminded_the_person(
    station: RunningStation,
) -> None:
    with signed_in(station, "operator") as operator:
        play(station, "e1_bolt_undone")  # reminders after 120 s: not yet
        command_card(station)
        card = operator.get("/fragments/tasks").text
        assert 'data-kind="command"' in card and "data-overdue" not in card, card
        play(station, "e1_bolt_undone", reminder=1.0)
        command_card(station)
        station.wait(lambda: any(c.overdue for c in task_cards(station.live.view)), 15)
        card = operator.get("/fragments/tasks").text
        assert 'data-overdue="true"' in card and "overdue</span>" in card, card
        assert "The station has been waiting for you for" in card


def test_both_taps_of_a_same_round_race_are_answered_and_one_is_recorded(
    station: RunningStation,
) -> None:
    """Two Done on one card handed to the loop together (the same round): one is taken, the
    other is refused as confirmed already, and only one tap is recorded."""
    play(station, "e1_bolt_undone")
    card = command_card(station)
    before = len(station.audit_records("operator", "card done"))
    taps = [station.live.confirm_card(name, card) for name in ("operator", "engineer")]
    answers = []
    for tap in taps:
        try:
            answers.append(tap.result(10))
        except StationError as exc:
            answers.append(str(exc))
    assert answers[0] is True, answers
    # not taken: confirmed already (the same round), or no longer shown (a later one)
    assert answers[1] is False or "is no longer shown" in str(answers[1]), answers
    records = station.audit_records("operator", "card done")[before:]
    assert [r["user"] for r in records] == ["operator"], records


def test_an_unknown_page_is_a_page_of_the_site_and_the_api_keeps_its_json(
    station: RunningStation,
) -> None:
    with signed_in(station, "operator") as operator:
        page = operator.get("/no/such/page")
        assert page.status_code == 404 and page.headers["content-type"].startswith("text/html")
        assert '<header class="topbar"' in page.text and "No such page" in page.text
        assert 'href="/" data-testid="home"' in page.text
        assert "There is no page at /no/such/page." in page.text
        marked = operator.get("/x%3Cb%3Ey").text  # the path is said, never run as markup
        assert "<b>y" not in marked and "/x&lt;b&gt;y" in marked
        api = operator.get("/api/no/such/thing")
        assert api.status_code == 404 and api.json() == {"detail": "Not Found"}
        static = operator.get("/static/css/none.css")
        assert static.status_code == 404 and static.json() == {"detail": "Not Found"}
    with httpx.Client(base_url=station.url) as nobody:
        page = nobody.get("/nothing-here")
        assert page.status_code == 404 and "No such page" in page.text
        assert 'href="/login"' in page.text


def test_a_role_refusal_is_said_once(station: RunningStation) -> None:
    with signed_in(station, "auditor") as auditor:
        page = auditor.get("/station").text.replace("&#39;", "'")
        assert page.count("Your role (auditor) cannot see this page.") == 1, page


def test_the_password_form_tells_the_browser_the_shortest_password(
    station: RunningStation,
) -> None:
    with signed_in(station, "operator") as operator:
        page = operator.get("/password").text
        for field in ("new_password", "repeat"):
            tag = re.search(rf'<input id="{field}"[^>]*>', page, re.S)
            assert tag and f'minlength="{MIN_PASSWORD}"' in tag.group(0), tag
        assert 'id="current_password"' in page and "data-new-password" in page
