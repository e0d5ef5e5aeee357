"""Issue 26: API tokens are listed on their user's account page and through the API, revoked
one by one, and a token issued from a browser session ends when that session signs out
(before: tokens survived sign-out, and only a password change could end them, all at once)."""

from __future__ import annotations

import json
import re
from typing import Any

from starlette.testclient import TestClient

from tests.support.stations import RunningStation, form_token


def issue_on_the_page(client: TestClient) -> str:
    """Issue a token with the account page's form; the token the page shows once."""
    page = client.get("/account")
    answer = client.post(
        "/account/tokens", data={"csrf_token": form_token(page.text)}, follow_redirects=False
    )
    assert (answer.status_code, answer.headers["location"]) == (303, "/account")
    shown = client.get("/account")
    assert shown.headers["cache-control"] == "no-store"
    token = re.search(r'<input class="mono" readonly value="([^"]+)"', shown.text)
    assert token, shown.text
    assert token.group(1) not in client.get("/account").text, "shown more than once"
    return token.group(1)


def bearer(station: RunningStation, token: str) -> int:
    headers = {"Authorization": f"Bearer {token}"}
    return station.client().get("/api/station", headers=headers).status_code


def test_a_token_issued_from_a_session_ends_when_it_signs_out(station: RunningStation) -> None:
    browser = station.client()
    station.login(browser, "engineer")
    issued = issue_on_the_page(browser)
    by_password = station.token(station.client(), "engineer")  # a line system's, not linked
    assert bearer(station, issued) == 200 and bearer(station, by_password) == 200
    page = browser.get("/account").text
    assert page.count("data-token=") == 2 and "this session" in page
    browser.post("/logout", data={"csrf_token": form_token(page)})
    assert bearer(station, issued) == 401
    assert bearer(station, by_password) == 200
    [signed_out] = [
        r for r in station.audit_records("login", "signed out") if r["user"] == "engineer"
    ]
    assert signed_out["tokens_ended"] == 1


def test_tokens_are_listed_and_revoked_one_by_one_on_the_page(station: RunningStation) -> None:
    browser = station.client()
    station.login(browser, "operator")
    first, second = issue_on_the_page(browser), issue_on_the_page(browser)
    page = browser.get("/account").text
    handles = re.findall(r'data-token="([0-9a-f]{16})"', page)
    assert len(handles) == 2
    newest = handles[0]  # newest first: the second token
    form = {"token": newest, "csrf_token": form_token(page)}
    answer = browser.post("/account/tokens/revoke", data=form, follow_redirects=False)
    assert (answer.status_code, answer.headers["location"]) == (303, "/account")
    after = browser.get("/account").text
    assert f"Token {newest}… is revoked." in after
    assert re.findall(r'data-token="([0-9a-f]{16})"', after) == handles[1:]
    assert bearer(station, second) == 401 and bearer(station, first) == 200
    [revoked] = station.audit_records("login", "api token revoked")
    assert revoked == {"user": "operator", "token": newest}
    # revoking it again: refused, said on the page, audited as refused
    again = browser.post("/account/tokens/revoke", data=form, follow_redirects=False)
    assert again.status_code == 303
    assert "no live API token" in browser.get("/account").text
    [refused] = station.audit_records("login", "tokens/revoke refused")
    assert refused["user"] == "operator" and refused["status"] == 404


def test_tokens_through_the_api(station: RunningStation) -> None:
    one = station.token(station.client(), "engineer")
    two = station.token(station.client(), "engineer")
    other = station.token(station.client(), "operator")
    api = station.client()
    api.headers["Authorization"] = f"Bearer {one}"
    listed = api.get("/api/tokens")
    assert listed.status_code == 200
    ids = [t["id"] for t in listed.json()]
    assert len(ids) == 2 and all(t["from_session"] == "" for t in listed.json())
    operators = station.client()
    operators.headers["Authorization"] = f"Bearer {other}"
    [operator_id] = [t["id"] for t in operators.get("/api/tokens").json()]
    assert operator_id not in ids
    # someone else's token is none of theirs: 404, and it keeps working
    assert api.delete(f"/api/tokens/{operator_id}").status_code == 404
    assert bearer(station, other) == 200
    # the newest (two) revoked: one works on
    assert api.delete(f"/api/tokens/{ids[0]}").status_code == 200
    assert bearer(station, two) == 401 and bearer(station, one) == 200
    assert [t["id"] for t in api.get("/api/tokens").json()] == ids[1:]


def test_the_link_to_the_session_is_sealed_and_older_rows_keep_their_seals() -> None:
    """A token's `issued_by` is in its seal: blanking it in the database (so that the
    token outlives its session's sign-out) breaks the seal.  A row from before the column
    (empty) is sealed as it was."""
    from app.store.keys import ephemeral_keys
    from app.store.row_seals import SESSIONS

    row: dict[str, Any] = {
        "id": "a" * 64,
        "user_id": 2,
        "kind": "api",
        "created_at": 1.0,
        "expires_at": 2.0,
        "revoked_at": None,
        "revoked_why": "",
        "address": "10.0.0.1",
        "issued_by": "",
        "seq": 3,
    }
    before = ["a" * 64, 2, "api", "1.0", "2.0", None, "", "10.0.0.1", 3]
    assert SESSIONS.text(row) == json.dumps(before, separators=(",", ":"))
    keys = ephemeral_keys()
    linked = {**row, "issued_by": "b" * 64}
    sealed = {**linked, "mac": SESSIONS.mac(keys, linked)}
    assert SESSIONS.intact(keys, sealed)
    assert not SESSIONS.intact(keys, {**sealed, "issued_by": ""})
    assert not SESSIONS.intact(keys, {**sealed, "issued_by": "c" * 64})
