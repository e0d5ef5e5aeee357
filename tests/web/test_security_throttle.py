"""Issue 15, point 3: sign-in throttling that slows guessing without locking the real user
out.  X-Forwarded-For counts only from a trusted proxy (none by default; with one, only
from it: issue 26, on a real server with clients at their own addresses); concurrent guesses
are checked no more often than the limit allows; a real user elsewhere still signs in; an
unknown name costs a password check like a known one; the throttle's memory is bounded;
throttled attempts do not flood the audit log."""

from __future__ import annotations

import itertools
import json
from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest
from starlette.testclient import TestClient

from app.people.throttle import Attempt, Refused, SignInThrottle
from app.web import sign_in
from app.web.server import parse_networks
from tests.support.stations import RunningStation, form_token, new_password


def client_at(station: RunningStation, address: str) -> TestClient:
    return TestClient(station.built.app, base_url="http://127.0.0.1", client=(address, 40000))


def try_password(client: httpx.Client, name: str, password: str, **headers: str) -> int:
    token = form_token(client.get("/login").text)
    form = {"name": name, "password": password, "csrf_token": token}
    return client.post("/login", data=form, headers=headers, follow_redirects=False).status_code


def audited(station: RunningStation, subject: str, user: str) -> int:
    """Failures of `subject` for `user` the audit log counts (one record per window and
    address block, each with how many: app.people.failures)."""
    station.built.server.failure_writer.flush(everything=True)
    with station.built.server.store.engine.connect() as connection:
        details = connection.exec_driver_sql(
            "SELECT detail FROM audit WHERE kind = 'login' AND subject = ? AND user = ?",
            (subject, user),
        ).scalars()
        return sum(int(json.loads(d).get("count", 1)) for d in details)


def test_x_forwarded_for_from_an_untrusted_client_changes_nothing(
    station: RunningStation,
) -> None:
    attacker = client_at(station, "10.1.1.1")
    for k in range(5):
        assert (
            try_password(attacker, "engineer", "guess", **{"X-Forwarded-For": f"10.9.9.{k}"}) == 401
        )
    spoofed = try_password(attacker, "engineer", "guess", **{"X-Forwarded-For": "10.9.9.99"})
    assert spoofed == 429


def test_a_trusted_proxy_is_believed_about_its_clients(
    station: RunningStation, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(station.built.server, "trusted_proxies", parse_networks(["10.0.0.0/24"]))
    proxy = client_at(station, "10.0.0.5")
    for _ in range(5):
        assert try_password(proxy, "auditor", "guess", **{"X-Forwarded-For": "192.0.2.7"}) == 401
    assert try_password(proxy, "auditor", "guess", **{"X-Forwarded-For": "192.0.2.7"}) == 429
    # another client behind the same proxy is another address
    assert try_password(proxy, "auditor", "guess", **{"X-Forwarded-For": "192.0.2.8"}) == 401
    # a throttled client cannot escape by sending a header of its own: the proxy appends
    # the address it saw, and that is the one believed
    forged = {"X-Forwarded-For": "192.0.2.9, 192.0.2.7"}
    assert try_password(proxy, "auditor", "guess", **forged) == 429


def test_concurrent_guesses_are_checked_no_more_often_than_the_limit(
    station: RunningStation,
) -> None:
    attacker = client_at(station, "10.2.2.2")
    token = form_token(attacker.get("/login").text)
    form = {"name": "operator", "password": "guess-guess", "csrf_token": token}

    def guess(_: int) -> int:
        return attacker.post("/login", data=form, follow_redirects=False).status_code

    with ThreadPoolExecutor(max_workers=20) as pool:
        statuses = list(pool.map(guess, range(40)))
    assert statuses.count(401) <= station.built.server.throttle.pair_limit
    assert set(statuses) <= {401, 429}
    assert audited(station, "failed", "operator") == statuses.count(401)


def test_the_real_user_signs_in_from_elsewhere_while_someone_guesses(
    station: RunningStation,
) -> None:
    real = station.client()
    station.login(real, "engineer")  # the real user's own device is known from now on
    real.post("/logout", data={"csrf_token": form_token(real.get("/login").text)})
    for k in range(12):  # many addresses, each below its own limit: the name is slowed
        attacker = client_at(station, f"10.3.3.{k // 4}")
        status = try_password(attacker, "engineer", "guess")
        assert status in (401, 429)
    assert try_password(real, "engineer", new_password("engineer")) == 303
    # a new device is only slowed (a bounded wait), never locked out for the window
    elsewhere = client_at(station, "10.4.4.4")
    token = form_token(elsewhere.get("/login").text)
    form = {"name": "engineer", "password": new_password("engineer"), "csrf_token": token}
    page = elsewhere.post("/login", data=form, follow_redirects=False)
    if page.status_code == 429:  # the wait it says, read from this very answer (a second
        # attempt may come after the wait ended, on a loaded machine)
        wait = int(page.text.split("try again in ")[1].split(" s")[0])
        assert wait <= station.built.server.throttle.max_delay + 1
    else:
        assert page.status_code == 303


def test_an_unknown_name_costs_a_password_check_like_a_known_one(
    station: RunningStation, monkeypatch: pytest.MonkeyPatch
) -> None:
    checked: list[str] = []
    real = sign_in.password_matches

    def counting(stored: str, password: str) -> bool:
        checked.append(stored)
        return real(stored, password)

    monkeypatch.setattr(sign_in, "password_matches", counting)
    client = client_at(station, "10.5.5.5")
    assert try_password(client, "nobody-here", "guess") == 401
    assert try_password(client, "operator", "guess") == 401
    assert len(checked) == 2
    assert all(stored.startswith("$argon2") for stored in checked)  # the same work either way


def test_the_throttles_memory_is_bounded() -> None:
    clock = itertools.count()
    throttle = SignInThrottle(max_keys=1000, clock=lambda: float(next(clock)))
    for k in range(20_000):
        attempt = throttle.begin(f"name{k}", f"10.{k % 250}.{k // 250 % 250}.1")
        assert isinstance(attempt, Attempt)
        throttle.end(attempt, False)
    assert throttle.keys() <= 1000


def test_counters_leave_with_the_window() -> None:
    now = [0.0]
    throttle = SignInThrottle(window=300.0, clock=lambda: now[0])
    for k in range(50):
        attempt = throttle.begin(f"n{k}", f"10.0.0.{k}")
        assert isinstance(attempt, Attempt)
        throttle.end(attempt, False)
        now[0] += 1
    now[0] += 1000.0
    for k in range(20):  # new counters sweep the expired ones out
        attempt = throttle.begin(f"m{k}", "10.0.0.2")
        assert isinstance(attempt, Attempt)
        throttle.end(attempt, True)
    assert throttle.keys() < 100


def test_throttled_attempts_leave_one_record_per_window(station: RunningStation) -> None:
    attacker = client_at(station, "10.6.6.6")
    statuses = [try_password(attacker, "admin", "guess") for _ in range(60)]
    assert statuses.count(401) == 5 and statuses.count(429) == 55
    assert audited(station, "throttled", "") == 55  # counted in one record, named nobody
    assert audited(station, "failed", "admin") == 5
    with station.built.server.store.engine.connect() as connection:
        records = connection.exec_driver_sql(
            "SELECT count(*) FROM audit WHERE kind = 'login' AND subject IN ('failed', 'throttled')"
        ).scalar()
    assert records == 2


def test_a_throttled_name_and_address_stay_refused_until_the_window_ends() -> None:
    now = [0.0]
    throttle = SignInThrottle(window=300.0, clock=lambda: now[0])
    for _ in range(5):
        attempt = throttle.begin("anna", "10.0.0.1")
        assert isinstance(attempt, Attempt)
        throttle.end(attempt, False)
    refused = throttle.begin("anna", "10.0.0.1")
    assert isinstance(refused, Refused) and 0 < refused.wait <= 300
    now[0] = 301.0
    assert isinstance(throttle.begin("anna", "10.0.0.1"), Attempt)


PROXY, OUTSIDER = "127.0.0.2", "127.0.0.3"  # all of 127/8 is this host's (Linux)


def client_from(url: str, address: str) -> httpx.Client:
    """A client whose connections come from `address` (its socket bound there)."""
    transport = httpx.HTTPTransport(local_address=address)
    return httpx.Client(base_url=url, transport=transport)


def login_addresses(station: RunningStation, user: str) -> list[str]:
    """The detail of each audited sign-in record of `user`, as text."""
    with station.built.server.store.engine.connect() as connection:
        rows = connection.exec_driver_sql(
            "SELECT detail FROM audit WHERE kind = 'login' AND user = ?", (user,)
        ).all()
    return [json.dumps(json.loads(detail)) for (detail,) in rows]


def test_with_a_trusted_proxy_only_the_proxy_is_believed(
    station: RunningStation, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A real server behind a trusted proxy at 127.0.0.2, and a client at 127.0.0.3 that
    reaches the station directly and sends X-Forwarded-For of its own: its real address is
    what the throttle counts and the audit records, while the proxy's word is believed."""
    monkeypatch.setattr(station.built.server, "trusted_proxies", parse_networks([PROXY]))
    url = station.serve()
    with client_from(url, OUTSIDER) as outsider, client_from(url, PROXY) as proxy:
        limit = station.built.server.throttle.pair_limit
        statuses = [
            try_password(outsider, "operator", "guess", **{"X-Forwarded-For": f"192.0.2.{k}"})
            for k in range(limit + 1)
        ]
        assert statuses == [401] * limit + [429], "each forged address counted as a new one"
        for forged in ("192.0.2.99", f"192.0.2.1, {PROXY}"):
            spoofed = {"X-Forwarded-For": forged}
            assert try_password(outsider, "operator", "guess", **spoofed) == 429
        # the proxy's client is someone else, and believed: not throttled, audited as itself
        forwarded = {"X-Forwarded-For": "198.51.100.7"}
        assert try_password(proxy, "operator", "guess", **forwarded) == 401
        assert try_password(proxy, "engineer", "guess", **forwarded) == 401
    # failures are audited per address block (app.people.failures): the outsider's under
    # its own (127.0.0.0/24), never a forged one; the proxy's client's under its block
    station.built.server.failure_writer.flush(everything=True)
    outsiders = [d for d in login_addresses(station, "operator") if "198.51.100." not in d]
    assert outsiders and all("127.0.0.0/24" in d and "192.0.2." not in d for d in outsiders)
    behind = login_addresses(station, "engineer")
    assert behind and all("198.51.100.0/24" in d and "127.0.0." not in d for d in behind), behind
