"""The auditor's pages: the audit log filtered and paged, the CSV export, bad filters.

One station for the module (starting one takes seconds); the records the tests read are
appended with known users, kinds, resources and times, in a year the station's own records
cannot reach, and every query that counts them includes that year's time range.
"""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.store import audit
from app.store.audit import AuditEntry
from tests.support.stations import RunningStation, start_station

BASE = datetime(2001, 2, 3, 4, 0, tzinfo=UTC).timestamp()  # record i is at BASE + 60 i
YEAR = {"since": "2001-01-01T00:00", "until": "2001-12-31T23:59:59"}
RECORDS = 130  # more than a page (100)


def entry(i: int) -> AuditEntry:
    user = ("ann", "bob", "cid")[i % 3]
    kind = "operator" if i % 2 else "fault"
    resource = ("r1", "r2", "")[i % 3]
    return AuditEntry(kind, f"step {i:03d}", user, resource, {"i": i, "why": f"test {i}"})


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(Path(tmp_path_factory.mktemp("audit")))
    srv = running.built.server
    for i in range(RECORDS):
        audit.write(srv.store, srv.live.name, [entry(i)], BASE + 60 * i)
    yield running
    running.stop()


@pytest.fixture(scope="module")
def auditor(station: RunningStation) -> TestClient:
    client = station.client()
    station.login(client, "auditor")
    return client


@pytest.fixture(scope="module")
def auditor_token(station: RunningStation, auditor: TestClient) -> str:
    return station.token(auditor, "auditor")


def ids_on(html: str) -> list[int]:
    return [int(n) for n in re.findall(r'<tr id="audit-(\d+)"', html)]


def subjects_on(html: str) -> list[str]:
    """The records' subjects as stored (the cells show them in words)."""
    return re.findall(r'<td data-label="Subject" data-subject="([^"]*)">', html)


def test_only_signed_in_users_with_the_audit_permission_see_the_log(
    station: RunningStation,
) -> None:
    anonymous = station.client()
    response = anonymous.get("/audit", follow_redirects=False)
    assert response.status_code == 303
    assert response.headers["location"].startswith("/login")
    operator = station.client()
    station.login(operator, "operator")
    assert operator.get("/audit").status_code == 403
    assert operator.get("/audit.csv").status_code == 403


def test_the_log_pages_newest_first_and_the_pager_keeps_the_filter(auditor: TestClient) -> None:
    first = auditor.get("/audit", params=YEAR)
    assert first.status_code == 200, first.text
    assert "UTC" in first.text
    assert f"{RECORDS} records match the filter" in first.text
    subjects = subjects_on(first.text)
    assert len(subjects) == 100
    assert subjects[0] == f"step {RECORDS - 1:03d}" and subjects[-1] == f"step {RECORDS - 100:03d}"
    ids = ids_on(first.text)
    assert ids == sorted(ids, reverse=True)
    # the next link carries the filter along
    next_link = re.search(r'<a class="btn" rel="next" href="([^"]+)"', first.text)
    assert next_link, "no pager"
    href = next_link.group(1).replace("&amp;", "&")
    assert "since=2001-01-01T00%3A00" in href and "page=2" in href
    second = auditor.get(href)
    assert subjects_on(second.text) == [f"step {i:03d}" for i in range(RECORDS - 101, -1, -1)]
    assert "Page 2 of 2" in second.text


def test_a_row_shows_time_user_kind_subject_resource_and_detail(auditor: TestClient) -> None:
    page = auditor.get("/audit", params={**YEAR, "text": "step 007"}).text
    row = re.search(r'<tr id="audit-\d+".*?</tr>', page, re.S)
    assert row, page
    cells = row.group(0)
    assert '<time datetime="2001-02-03T04:07:00.000Z">' in cells
    assert '<td data-label="User">bob</td>' in cells
    assert '<td data-label="Kind">operator</td>' in cells
    assert '<td data-label="Resource" data-resource="r2">robot 2</td>' in cells
    assert "<details>" in cells and "i: 7, why: test 7" in cells
    assert "&#34;why&#34;: &#34;test 7&#34;" in cells or '"why": "test 7"' in cells


@pytest.mark.parametrize(
    ("query", "expected"),
    [
        ({"user": "ann"}, [i for i in range(RECORDS) if i % 3 == 0]),
        ({"kind": "fault"}, [i for i in range(RECORDS) if i % 2 == 0]),
        ({"resource": "r2", "kind": "operator"}, [i for i in range(RECORDS) if i % 6 == 1]),
        # both ends included; the form's datetime-local value is read as UTC
        ({"since": "2001-02-03T04:10", "until": "2001-02-03T04:12"}, [10, 11, 12]),
        ({"since": "2001-02-03T05:10:00+01:00", "until": "2001-02-03T04:11:00Z"}, [10, 11]),
        ({"text": "step 12"}, list(range(120, 130))),
    ],
)
def test_filters(auditor: TestClient, query: dict[str, str], expected: list[int]) -> None:
    params = {**YEAR, **query}
    shown: list[str] = []
    for page in (1, 2):
        html = auditor.get("/audit", params={**params, "page": str(page)}).text
        shown += subjects_on(html)
        if len(shown) >= len(expected):
            break
    assert shown == [f"step {i:03d}" for i in sorted(expected, reverse=True)]


def test_the_filter_form_offers_the_stations_users_and_keeps_the_choice(
    auditor: TestClient,
) -> None:
    html = auditor.get("/audit", params={**YEAR, "user": "bob", "kind": "fault"}).text
    users = re.search(r'<select id="f-user" name="user">(.*?)</select>', html, re.S)
    assert users
    assert '<option value="bob" selected>' in users.group(1)
    # the station's users are offered; a name only the log holds (typed at the sign-in
    # form, say) is not, unless chosen
    assert '<option value="auditor">' in users.group(1)
    assert '<option value="ann">' not in users.group(1)
    assert 'value="2001-01-01T00:00"' in html and 'value="2001-12-31T23:59:59"' in html


def test_the_csv_export_has_the_header_and_the_filtered_rows_and_is_audited(
    station: RunningStation, auditor: TestClient
) -> None:
    query = {**YEAR, "user": "cid", "resource": ""}
    response = auditor.get("/audit.csv", params=query)
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/csv")
    disposition = response.headers["content-disposition"]
    assert re.fullmatch(
        r'attachment; filename="audit-demo_station-\d{8}T\d{6}Z\.csv"', disposition
    ), disposition
    rows = list(csv.reader(io.StringIO(response.text)))
    assert rows[0] == list(audit.CSV_COLUMNS)
    expected = [f"step {i:03d}" for i in range(RECORDS) if i % 3 == 2]  # oldest first
    assert [r[5] for r in rows[1:]] == expected
    assert {r[3] for r in rows[1:]} == {"cid"} and {r[6] for r in rows[1:]} == {""}
    assert json.loads(rows[1][7]) == {"i": 2, "why": "test 2"}
    assert rows[1][1] == "2001-02-03T04:02:00.000+00:00"
    # the export itself is in the log, with its filter
    with station.built.server.store.sessions() as session:
        found = audit.page_of(session, audit.AuditFilter(kind="audit", user="auditor"))
        assert found.records, "the export was not audited"
        newest = found.records[0]
        assert newest.subject == "csv export"
        detail = json.loads(newest.detail)["filter"]
    assert detail["user"] == "cid"
    assert detail["since"] == "2001-01-01T00:00:00.000Z"
    assert detail["until"] == "2001-12-31T23:59:59.000Z"


def test_a_page_shows_the_export_in_the_log(auditor: TestClient) -> None:
    auditor.get("/audit.csv", params={"kind": "fault"})
    html = auditor.get("/audit", params={"kind": "audit"}).text
    assert "csv export" in html and "filter: " in html


@pytest.mark.parametrize(
    ("query", "message"),
    [
        ({"since": "yesterday"}, "since: 'yesterday' is not a date and time"),
        ({"until": "2001-13-01T00:00"}, "until: '2001-13-01T00:00' is not a date and time"),
        ({"page": "0"}, "pages are numbered from 1"),
        ({"page": "two"}, "page: 'two' is not a whole number"),
        ({"since": "2001-02-03T05:00", "until": "2001-02-03T04:00"}, "is after until"),
        ({"user": "x" * 65}, "user"),
    ],
)
def test_a_bad_filter_is_a_422_that_says_what_to_fix(
    station: RunningStation,
    auditor: TestClient,
    auditor_token: str,
    query: dict[str, str],
    message: str,
) -> None:
    page = auditor.get("/audit", params={**query, "kind": "fault"})
    assert page.status_code == 422
    assert message in page.text.replace("&#39;", "'")
    # the page comes back with the form as given, to correct it
    assert '<option value="fault" selected>' in page.text
    assert "audit-total" not in page.text
    if "page" not in query:
        assert auditor.get("/audit.csv", params=query).status_code == 422
        headers = {"Authorization": f"Bearer {auditor_token}"}
        answer = station.client().get("/api/audit", params=query, headers=headers)
        assert answer.status_code == 422
        assert message in answer.json()["detail"]


def test_the_page_shows_peoples_records_and_the_stations_events_one_click_away(
    station: RunningStation, auditor: TestClient
) -> None:
    """Issue 16: station records (hundreds an hour) buried people's; the page now shows what
    people did, sign-ins, model changes and alarms (the station's own alarm changes too),
    and links to the station's events and to everything, keeping the rest of the filter."""
    srv = station.built.server
    at = datetime(2003, 4, 5, 6, 0, tzinfo=UTC).timestamp()
    kept = [
        AuditEntry("started", "r1.goto_bp1", "", "r1", {"station_time": 1.0}),  # the station's
        AuditEntry("login", "signed in", "ann", "", {"address": "10.0.0.7"}),
        AuditEntry("alarm", "resource:r2", "", "r2", {"after": "unacknowledged"}),
        AuditEntry("model", "activated", "bob", "", {"version": 2}),
    ]
    for k, one in enumerate(kept):
        audit.write(srv.store, srv.live.name, [one], at + k)
    when = {"since": "2003-04-05T06:00", "until": "2003-04-05T06:59"}
    page = auditor.get("/audit", params=when).text
    assert subjects_on(page) == ["activated", "resource:r2", "signed in"]
    assert '<td data-label="Subject" data-subject="resource:r2">resource: robot 2</td>' in page
    assert "subject: resource:r2" in page  # as stored, in the record's opened detail
    switch = dict(re.findall(r'href="([^"]+)" data-show="(\w+)"', page))
    links = {show: href.replace("&amp;", "&") for href, show in switch.items()}
    assert set(links) == {"people", "station", "all"}
    assert 'data-show="people" aria-current="page"' in page
    assert "since=2003-04-05T06%3A00" in links["station"]
    assert subjects_on(auditor.get(links["station"]).text) == ["r1.goto_bp1"]
    assert len(subjects_on(auditor.get(links["all"]).text)) == 4
    # the page's export takes what the page shows; the CSV and the API default to everything
    csv_link = re.search(r'href="(/audit\.csv[^"]*)"', page)
    assert csv_link and "show=people" in csv_link.group(1)
    exported = auditor.get(csv_link.group(1).replace("&amp;", "&")).text
    assert len(list(csv.reader(io.StringIO(exported)))) == 1 + 3
    everything = auditor.get("/audit.csv", params=when).text
    assert len(list(csv.reader(io.StringIO(everything)))) == 1 + 4
    wrong = auditor.get("/audit", params={**when, "show": "robots"})
    assert wrong.status_code == 422 and "one of people, station, all" in wrong.text


def test_people_s_decisions_are_exported_in_the_screen_s_words_and_numbering(
    station: RunningStation, auditor: TestClient
) -> None:
    """Issue 29: "approved step 2 of 6", "declined" for "I cannot do this", a plan approved
    at once with its steps; the resource of an approval or maintenance step is filled in
    when the station records it."""
    from app.station.records import event_entry
    from planner.runner import Event, EventKind

    srv = station.built.server
    runner = srv.live.runner
    approve = {"step": 3, "transition": "r1.goto_bp2", "number": 2, "of": 6}
    decline = {"step": 0, "transition": "operator.remove_oil_filters", "number": 1, "of": 1}
    plan = {"steps": [1, 2], "transitions": ["nr.run_nut", "r1.goto_bp2"], "numbers": [1, 2]}
    done = {"transition": "operator.move_r2_home"}
    said_by = [
        ("approve", approve),
        ("reject", decline),
        ("approve plan", {**plan, "of": 2}),
        ("maintenance done", done),
    ]
    events = [
        Event(k + 1.0, EventKind.OPERATOR, subject, {"user": "dee", **detail})
        for k, (subject, detail) in enumerate(said_by)
    ]
    entries = [event_entry(runner, e) for e in events]
    assert [e.resource for e in entries] == ["r1", "operator", "", "operator"]
    when = datetime(2002, 5, 6, 7, 0, tzinfo=UTC).timestamp()
    audit.write(srv.store, srv.live.name, entries, when)
    year = {"since": "2002-01-01T00:00", "until": "2002-12-31T23:59:59"}
    rows = list(csv.reader(io.StringIO(auditor.get("/audit.csv", params=year).text)))
    assert rows[0][-1] == "in words"
    said = [r[-1] for r in rows[1:]]
    assert said == [
        "approved step 2 of 6: robot 1: move down onto bolt pair 2",
        "declined step 1 of 1: the operator: take off the oil filters mounted too early",
        "approved the recovery plan at once, steps 1-2 of 2: the nutrunner: start tightening; "
        "robot 1: move down onto bolt pair 2",
        "done: the operator: move robot 2 home by hand",
    ]
    page = auditor.get("/audit", params={**year, "show": "people"}).text
    assert "declined step 1 of 1" in page and "approved step 2 of 6" in page
