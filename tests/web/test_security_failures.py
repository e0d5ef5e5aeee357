"""Issue 26: failures of people not signed in (failed sign-ins, throttled ones, bad bearer
tokens) are audited one record per window per address block (IPv4 /24, IPv6 /64) with a
count, written by a thread of their own, in bounded memory; the auditor's filter lists the
station's users, not every name an attacker typed; and one address spraying many names is
stopped by the per-address limit."""

from __future__ import annotations

import re

from app.people.failures import OTHERS, FailureLog, address_block
from app.people.throttle import Attempt, Refused, SignInThrottle
from tests.support.stations import RunningStation
from tests.web.test_security_throttle import client_at, try_password


def test_failed_sign_ins_are_one_record_per_address_block_with_a_count(
    station: RunningStation,
) -> None:
    for k in range(6):  # rotating through one /24, a new name each time
        assert try_password(client_at(station, f"10.8.8.{k}"), f"guess{k}", "wrong-one") == 401
    assert try_password(client_at(station, "10.8.9.1"), "other", "wrong-one") == 401
    assert try_password(client_at(station, "10.8.8.9"), "engineer", "wrong-one") == 401
    # nothing written while the requests were answered: counted, summarised later
    assert station.audit_records("login", "failed") == []
    station.built.server.failure_writer.flush(everything=True)
    records = station.audit_records("login", "failed")
    by_block = {(r["addresses"], r["user"]): r for r in records}
    assert len(records) == 3, records
    unknown = by_block[("10.8.8.0/24", "")]
    assert unknown["count"] == 6 and unknown["why"] == {"unknown user": 6}
    assert len(unknown["names"]) <= 5 and set(unknown["names"]) <= {f"guess{k}" for k in range(6)}
    assert by_block[("10.8.9.0/24", "")]["count"] == 1
    # a real user's failures name them, so the auditor finds them under that user
    assert by_block[("10.8.8.0/24", "engineer")]["why"] == {"wrong password": 1}


def test_the_auditors_filter_lists_real_users_not_typed_names(station: RunningStation) -> None:
    for k in range(3):
        client = client_at(station, f"10.9.{k}.1")
        assert try_password(client, f"intruder{k}", "wrong-one") == 401
    station.built.server.failure_writer.flush(everything=True)
    auditor = station.client()
    station.login(auditor, "auditor")
    page = auditor.get("/audit", params={"show": "all"})
    assert page.status_code == 200
    select = re.search(r'<select[^>]*name="user".*?</select>', page.text, re.S)
    assert select is not None
    options = set(re.findall(r'<option value="([^"]*)"', select.group(0))) - {""}
    assert options == {"operator", "engineer", "auditor", "admin"}


def test_bad_bearer_tokens_are_one_record_per_block(station: RunningStation) -> None:
    for k in range(5):
        client = client_at(station, f"2001:db8:1:2::{k + 1}")
        answer = client.get("/api/station", headers={"Authorization": f"Bearer forged-{k}"})
        assert answer.status_code == 401
    station.built.server.failure_writer.flush(everything=True)
    records = station.audit_records("login", "bad token")
    assert [(r["addresses"], r["count"]) for r in records] == [("2001:db8:1:2::/64", 5)]


def test_the_summaries_memory_is_bounded() -> None:
    failures = FailureLog(max_blocks=50, clock=lambda: 0.0)
    for k in range(5000):
        failures.note("failed", f"10.{k // 250 % 250}.{k % 250}.1", 0.0, name=f"n{k}" * 20)
    assert failures.open_summaries() <= 51
    found = failures.due(everything=True)
    assert sum(s.count for s in found) == 5000
    assert next(s for s in found if s.block == OTHERS).count == 5000 - 50
    assert all(len(s.names) <= 5 and all(len(n) <= 64 for n in s.names) for s in found)


def test_a_summary_is_due_once_its_window_is_over() -> None:
    now = [0.0]
    failures = FailureLog(window=60.0, clock=lambda: now[0])
    failures.note("failed", "10.0.0.1", 1.0)
    now[0] = 59.0
    failures.note("failed", "10.0.0.2", 2.0)
    assert failures.due() == []
    now[0] = 60.0
    [summary] = failures.due()
    assert summary.count == 2 and summary.block == "10.0.0.0/24"
    assert failures.open_summaries() == 0


def test_address_blocks() -> None:
    assert address_block("192.0.2.77") == "192.0.2.0/24"
    assert address_block("::ffff:192.0.2.77") == "192.0.2.0/24"
    assert address_block("2001:db8:a:b:c:d:e:f") == "2001:db8:a:b::/64"
    assert address_block("testclient") == "testclient"


def test_one_address_spraying_names_is_stopped_at_the_address_limit(
    station: RunningStation,
) -> None:
    """Many names from one address, each below its own limit: the per-address limit (30
    failures in the window) refuses the next one, even for a real user's right password."""
    limit = 30
    sprayer = client_at(station, "10.10.10.10")
    statuses = [try_password(sprayer, f"spray{k}", "wrong-one") for k in range(limit)]
    assert statuses == [401] * limit
    assert try_password(sprayer, f"spray{limit}", "wrong-one") == 429
    assert try_password(sprayer, "operator", "operator-demo-1") == 429
    # another address is not held by it
    assert try_password(client_at(station, "10.11.11.11"), "spray-next", "wrong-one") == 401


def test_the_address_limit_counts_every_name() -> None:
    throttle = SignInThrottle(clock=lambda: 0.0)
    for k in range(30):
        attempt = throttle.begin(f"name{k}", "10.0.0.1")
        assert isinstance(attempt, Attempt)
        throttle.end(attempt, False)
    assert isinstance(throttle.begin("one-more", "10.0.0.1"), Refused)
