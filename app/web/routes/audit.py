"""The auditor's pages: the audit log, filtered and paged, and its CSV export.

The filter lives in the query string (app.web.audit_log), so a filtered view can be
bookmarked or sent on, and the CSV export takes the same parameters.  The page shows
people's records unless told otherwise: the station's events (hundreds an hour) would bury
them, and are one click away; the CSV export and the API default to everything.  The form's
`datetime-local` inputs are read as UTC.  Exporting is itself audited (kind `audit`), since
it takes the log out of the station.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import Response, StreamingResponse
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from app.store.tables import AuditRecord, User
from app.web.audit_log import (
    LIMITS,
    SHOWN,
    Criteria,
    criteria,
    detail_of,
    iso,
    parse_page,
    record_words,
)
from app.web.deps import AuditCriteria, AuditReader, Caller, LiveDep, StoreDep
from app.web.pages import render
from planner.runner import EventKind
from planner.words import Wording

router = APIRouter(include_in_schema=False)

# kinds shown with the error mark (ISA-101: colour only for what is abnormal)
ABNORMAL_KINDS = frozenset(
    {EventKind.ERROR, AuditKind.ERROR, EventKind.FORBIDDEN, EventKind.UNEXPECTED}
)
SUMMARY_CHARS = 90


@dataclass(frozen=True)
class Row:
    id: int
    time: str
    station: str
    user: str
    kind: str
    subject: str
    resource: str
    summary: str  # the detail on one line, shortened, names in words
    pretty: str  # the detail, indented ("" when there is none)
    abnormal: bool
    subject_words: str = ""  # the subject for people ("operation: robot 2 takes the nutrunner")
    resource_words: str = ""


def subject_words(words: Wording, subject: str, kind: str = "", detail: Any = None) -> str:
    """A record's subject in words: "operation:get_nr_r2" → "operation: robot 2 takes the
    nutrunner", a person's decision as the screen numbered it ("approved step 2 of 6: ...",
    `record_words`); the page keeps the raw subject in the opened detail, as the CSV has it."""
    if kind == EventKind.OPERATOR:
        return record_words(words, kind, subject, detail or {})
    kind, colon, name = subject.partition(":")
    if not colon or not name or " " in name:  # a sentence ("E6: r2 stops answering")
        return words.text(subject)
    return f"{kind}: {words.name(name)}"


def row_of(record: AuditRecord, words: Wording) -> Row:
    detail = detail_of(record)
    parts = [f"{key}: {_compact(value)}" for key, value in detail.items()]
    summary = words.text(", ".join(parts))
    if len(summary) > SUMMARY_CHARS:
        summary = summary[: SUMMARY_CHARS - 1] + "…"
    pretty = json.dumps(detail, indent=2, ensure_ascii=False, default=str) if detail else ""
    return Row(
        record.id,
        iso(record.time),
        record.station,
        record.user,
        record.kind,
        record.subject,
        record.resource,
        summary,
        pretty,
        record.kind in ABNORMAL_KINDS,
        subject_words(words, record.subject, record.kind, detail),
        words.resource(record.resource) if record.resource else "",
    )


def _compact(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "none"
    if isinstance(value, str):
        return value
    return json.dumps(value, ensure_ascii=False, separators=(", ", ": "), default=str)


def time_input(time: float | None) -> str:
    """A time for a `datetime-local` input (UTC, seconds only when there are any)."""
    if time is None:
        return ""
    moment = datetime.fromtimestamp(time, UTC)
    if moment.second or moment.microsecond:
        return moment.strftime("%Y-%m-%dT%H:%M:%S")
    return moment.strftime("%Y-%m-%dT%H:%M")


@dataclass(frozen=True)
class Switch:
    """One choice of which records the page shows: its words, link, and whether it is on."""

    show: str
    words: str
    url: str
    current: bool


def _switch(chosen: Criteria, current: str) -> list[Switch]:
    """The page's choices of records, each keeping the rest of the filter (page 1)."""
    return [
        Switch(key, words, "/audit" + chosen.query(show=key), key == current)
        for key, words in SHOWN.items()
    ]


def _choices(session: Session, given: dict[str, str]) -> dict[str, list[str]]:
    """The selects' choices: the values in the log (the users: the station's users, not
    every name someone typed at the sign-in form), and a chosen one even if absent."""
    found = {c: audit.distinct_values(session, c) for c in ("kind", "resource", "station")}
    found["user"] = list(session.scalars(select(User.name).order_by(User.name)))
    return {column: _with(values, given.get(column, "")) for column, values in found.items()}


def _with(values: list[str], chosen: str) -> list[str]:
    return values if not chosen or chosen in values else sorted([*values, chosen])


def _page(request: Request, caller: Caller, status_code: int, **context: Any) -> Response:
    response = render(request, "audit.html", caller, "audit", status_code=status_code, **context)
    response.headers["Cache-Control"] = "no-store"
    return response


@router.get("/audit")
def audit_page(
    request: Request,
    caller: AuditReader,
    live: LiveDep,
    store: StoreDep,
    since: str = "",
    until: str = "",
    user: str = "",
    kind: str = "",
    resource: str = "",
    station: str = "",
    text: str = "",
    show: str = "people",
    page: str = "1",
) -> Response:
    """The log page, people's records unless `show` says otherwise; a filter it cannot read
    comes back as the page itself, with the message and the form as given, so the auditor
    can correct it (422)."""
    raw = {
        "since": since,
        "until": until,
        "user": user,
        "kind": kind,
        "resource": resource,
        "station": station,
        "text": text,
        "show": show.strip() or "people",
    }
    try:
        chosen = criteria(**raw)
        number = parse_page(page)
    except HTTPException as exc:
        return _refused_filter(request, caller, store, raw, exc)
    with store.sessions() as session:
        found = audit.page_of(session, chosen.where, number)
        rows = [row_of(r, live.view.model.words) for r in found.records]
        choices = _choices(session, chosen.given)
    return _page(
        request,
        caller,
        200,
        results=True,
        rows=rows,
        total=found.total,
        page_number=found.page,
        pages=found.pages,
        page_url=lambda n: "/audit" + chosen.query(page=n),
        csv_url="/audit.csv" + chosen.query(),
        filtered=bool(chosen.given.keys() - {"show"}),
        shown=_switch(chosen, chosen.where.show),
        form=_form(chosen),
        choices=choices,
    )


def _form(chosen: Criteria) -> dict[str, str]:
    """The filter's form as the page shows it back, times as its inputs take them."""
    where = chosen.where
    return {
        "since": time_input(where.since),
        "until": time_input(where.until),
        "user": where.user,
        "kind": where.kind,
        "resource": where.resource,
        "station": where.station,
        "text": where.text,
        "show": where.show,
    }


def _refused_filter(
    request: Request, caller: Caller, store: Store, raw: dict[str, str], exc: HTTPException
) -> Response:
    """The page with the message and the form as given (cut to what each field holds)."""
    form = {k: v[: LIMITS[k]] for k, v in raw.items()}
    with store.sessions() as session:
        choices = _choices(session, form)
    return _page(
        request,
        caller,
        exc.status_code,
        error=str(exc.detail),
        form=form,
        choices=choices,
        shown=_switch(criteria(show="people"), "people"),
    )


@router.get("/audit.csv")
def audit_csv(
    caller: AuditReader,
    live: LiveDep,
    store: StoreDep,
    chosen: AuditCriteria,
) -> StreamingResponse:
    """The filtered log as CSV, oldest first; the export is audited before it starts."""
    now = live.wall()
    export = AuditEntry(
        AuditKind.AUDIT, "csv export", caller.name, "", {"filter": chosen.described()}
    )
    audit.write(store, live.name, [export], now)

    words = live.view.model.words

    def said(record: AuditRecord) -> str:
        return record_words(words, record.kind, record.subject, detail_of(record))

    def lines() -> Iterator[str]:
        with store.sessions() as session:
            yield from audit.csv_lines(session, chosen.where, said=said)

    station = re.sub(r"[^A-Za-z0-9_.-]", "_", live.name) or "station"
    stamp = datetime.fromtimestamp(now, UTC).strftime("%Y%m%dT%H%M%SZ")
    headers = {
        "Content-Disposition": f'attachment; filename="audit-{station}-{stamp}.csv"',
        "Cache-Control": "no-store",
    }
    return StreamingResponse(lines(), media_type="text/csv; charset=utf-8", headers=headers)
