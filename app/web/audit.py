"""The auditor's pages: the audit log, filtered and paged, and its CSV export.

The filter lives in the query string, so a filtered view can be bookmarked or sent on, and
the CSV export takes the same parameters.  Which records (`show`): people's records (what a
person did, sign-ins, model changes, alarms), the station's own events, or everything.  The
page shows people's records unless told otherwise: the station's events (hundreds an hour)
would bury them, and are one click away; the CSV export and the API default to everything.
Times are UTC throughout: the form's `datetime-local` inputs are read as UTC, and ISO 8601
with a zone is accepted in the query string.  A filter that cannot be read is a 422 that
says what to fix.  Exporting is itself audited (kind `audit`), since it takes the log out of
the station.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from typing import Annotated, Any
from urllib.parse import urlencode

from fastapi import APIRouter, Depends, HTTPException, Query, Request
from fastapi.responses import Response, StreamingResponse
from sqlalchemy import Select, and_, or_
from sqlalchemy.orm import Session

from app.people.auth import Permission
from app.store import audit
from app.store.audit import AuditEntry, AuditFilter, AuditKind
from app.store.tables import AuditRecord
from app.web.deps import Caller, page_context, require, server
from planner.words import Wording

router = APIRouter(include_in_schema=False)

# the longest a filter value can usefully be: the columns' widths (app.store.tables)
USER_CHARS, KIND_CHARS, RESOURCE_CHARS, STATION_CHARS, TEXT_CHARS = 64, 32, 64, 64, 200
TIME_CHARS = 64
TIME_EXAMPLE = "2025-05-01T14:30 (UTC) or 2025-05-01T16:30:00+02:00"
# kinds shown with the error mark (ISA-101: colour only for what is abnormal)
ABNORMAL_KINDS = frozenset({"error", "forbidden", "unexpected"})
SUMMARY_CHARS = 90
# which records (`show`), as the page's switch names them; the page's default first
SHOWN = {"people": "People's records", "station": "Station events", "all": "Everything"}
SHOW_CHARS = 16


@dataclass(frozen=True)
class ShownFilter(AuditFilter):
    """The store's filter narrowed to people's records or the station's events (`SHOWN`).

    A person's record names its user; alarm changes count as people's records whoever made
    them (an alarm is raised for a person), the station's events are the rest."""

    show: str = "all"

    def apply(self, query: Select[Any]) -> Select[Any]:
        query = super().apply(query)
        people = or_(AuditRecord.user != "", AuditRecord.kind == "alarm")
        if self.show == "people":
            return query.where(people)
        if self.show == "station":
            return query.where(and_(AuditRecord.user == "", AuditRecord.kind != "alarm"))
        return query


# -- the filter ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Criteria:
    """A filter as the store reads it (`where`) and as it was given (`given`, for links)."""

    where: ShownFilter
    given: dict[str, str]

    def query(self, **extra: object) -> str:
        """The query string ("" or "?...") of this filter, with `extra` parameters added."""
        parameters = {**self.given, **{k: str(v) for k, v in extra.items()}}
        return "?" + urlencode(parameters) if parameters else ""

    def described(self) -> dict[str, object]:
        """The filter for the audit record of an export: what was given, times in UTC."""
        out: dict[str, object] = {
            k: v for k, v in asdict(self.where).items() if v not in ("", None)
        }
        for name, time in (("since", self.where.since), ("until", self.where.until)):
            if time is not None:
                out[name] = iso(time)
        return out


EARLIEST = datetime(1, 1, 2, tzinfo=UTC).timestamp()
LATEST = datetime(9999, 12, 30, tzinfo=UTC).timestamp()


def iso(time: float) -> str:
    """A time as UTC ISO 8601 with milliseconds: 2025-05-01T14:30:00.000Z."""
    moment = datetime.fromtimestamp(time, UTC)
    return moment.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def parse_time(name: str, text: str) -> float | None:
    """`text` as seconds since the epoch; no zone means UTC; "" means no limit."""
    text = text.strip()
    if not text:
        return None
    for candidate in _spellings(text):
        try:
            moment = datetime.fromisoformat(candidate)
        except ValueError:
            continue
        if moment.tzinfo is None:
            moment = moment.replace(tzinfo=UTC)
        try:
            seconds = moment.timestamp()
        except (OverflowError, OSError, ValueError):
            break
        if not EARLIEST <= seconds <= LATEST:  # shown back as a UTC date, which must exist
            raise HTTPException(
                422, f"{name}: use a time between the years 1 and 9999, for example {TIME_EXAMPLE}"
            )
        return seconds
    shown = text if len(text) <= 40 else text[:40] + "…"
    raise HTTPException(
        422, f"{name}: '{shown}' is not a date and time; use for example {TIME_EXAMPLE}"
    )


def _spellings(text: str) -> list[str]:
    """`text`, upper-cased (RFC 3339 allows 't' and 'z'), and with a zone's '+' restored
    when an unencoded query string turned it into a space."""
    upper = text.upper()
    spellings = [upper]
    zone = re.match(r"^(.*\d{2}:\d{2}(?::\d{2}(?:\.\d+)?)?) (\d{2}(?::?\d{2})?)$", upper)
    if zone:
        spellings.append(f"{zone.group(1)}+{zone.group(2)}")
    return spellings


LIMITS = {
    "since": TIME_CHARS,
    "until": TIME_CHARS,
    "user": USER_CHARS,
    "kind": KIND_CHARS,
    "resource": RESOURCE_CHARS,
    "station": STATION_CHARS,
    "text": TEXT_CHARS,
    "show": SHOW_CHARS,
}


def criteria(
    since: str = "",
    until: str = "",
    user: str = "",
    kind: str = "",
    resource: str = "",
    station: str = "",
    text: str = "",
    show: str = "",
) -> Criteria:
    """The filter from query parameters, or a 422 that says which one to fix and how; no
    `show` means everything."""
    given = {
        "since": since.strip(),
        "until": until.strip(),
        "user": user.strip(),
        "kind": kind.strip(),
        "resource": resource.strip(),
        "station": station.strip(),
        "text": text.strip(),
        "show": show.strip(),
    }
    for name, value in given.items():
        if len(value) > LIMITS[name]:
            raise HTTPException(422, f"{name}: at most {LIMITS[name]} characters, not {len(value)}")
    if given["show"] and given["show"] not in SHOWN:
        shown = given["show"]
        raise HTTPException(422, f"show: '{shown}' is not one of {', '.join(SHOWN)}")
    start, end = parse_time("since", given["since"]), parse_time("until", given["until"])
    if start is not None and end is not None and start > end:
        raise HTTPException(
            422, f"since ({iso(start)}) is after until ({iso(end)}); swap them or widen the range"
        )
    where = ShownFilter(
        since=start,
        until=end,
        user=given["user"],
        kind=given["kind"],
        resource=given["resource"],
        station=given["station"],
        text=given["text"],
        show=given["show"] or "all",
    )
    return Criteria(where, {k: v for k, v in given.items() if v})


def parse_page(text: str) -> int:
    """A 1-based page number from the query string, or a 422."""
    try:
        page = int(text.strip())
    except ValueError:
        shown = text if len(text) <= 20 else text[:20] + "…"
        raise HTTPException(
            422, f"page: '{shown}' is not a whole number; pages are numbered from 1"
        ) from None
    if page < 1:
        raise HTTPException(422, f"page: {page} is not a page; pages are numbered from 1")
    return page


def filter_dependency(
    since: Annotated[
        str,
        Query(
            max_length=TIME_CHARS,
            description="records at or after this time, ISO 8601 (2025-05-01T14:30:00Z); "
            "no zone means UTC, empty means no limit",
        ),
    ] = "",
    until: Annotated[
        str,
        Query(
            max_length=TIME_CHARS,
            description="records at or before this time, ISO 8601; no zone means UTC, "
            "empty means no limit",
        ),
    ] = "",
    user: Annotated[str, Query(max_length=USER_CHARS, description="exactly this user")] = "",
    kind: Annotated[str, Query(max_length=KIND_CHARS, description="exactly this kind")] = "",
    resource: Annotated[
        str, Query(max_length=RESOURCE_CHARS, description="exactly this resource")
    ] = "",
    station: Annotated[
        str, Query(max_length=STATION_CHARS, description="exactly this station")
    ] = "",
    text: Annotated[str, Query(max_length=TEXT_CHARS, description="contained in the subject")] = "",
    show: Annotated[
        str,
        Query(
            max_length=SHOW_CHARS,
            description="people (their actions, sign-ins, model changes, alarms), station "
            "(the station's own events) or all (the default)",
        ),
    ] = "",
) -> Criteria:
    """The filter's query parameters, for /audit.csv and /api/audit (the page reads them
    itself, so that a bad filter comes back in the form)."""
    return criteria(since, until, user, kind, resource, station, text, show)


# -- rows as the page shows them -----------------------------------------------------------------


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


def subject_words(words: Wording, subject: str) -> str:
    """A record's subject in words: "operation:get_nr_r2" → "operation: robot 2 takes the
    nutrunner"; the page keeps the raw subject in the opened detail, as the CSV has it."""
    kind, colon, name = subject.partition(":")
    if not colon or not name or " " in name:  # a sentence ("E6: r2 stops answering")
        return words.text(subject)
    return f"{kind}: {words.name(name)}"


def detail_of(record: AuditRecord) -> dict[str, Any]:
    """The record's detail JSON as a mapping (a non-object is kept under "value")."""
    try:
        detail = json.loads(record.detail or "{}")
    except ValueError:
        return {"value": record.detail}
    return detail if isinstance(detail, dict) else {"value": detail}


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
        subject_words(words, record.subject),
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


# -- routes --------------------------------------------------------------------------------------


@router.get("/audit")
def audit_page(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.AUDIT))],
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
    srv = server(request)
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
        form = {k: v[: LIMITS[k]] for k, v in raw.items()}
        with srv.store.sessions() as session:
            choices = _choices(session, form)
        context = page_context(
            request,
            caller,
            "audit",
            error=str(exc.detail),
            form=form,
            choices=choices,
            shown=_switch(criteria(show="people"), "people"),
        )
        return _page(request, context, exc.status_code)
    with srv.store.sessions() as session:
        found = audit.page_of(session, chosen.where, number)
        rows = [row_of(r, srv.live.view.model.words) for r in found.records]
        choices = _choices(session, chosen.given)
    where = chosen.where
    context = page_context(
        request,
        caller,
        "audit",
        results=True,
        rows=rows,
        total=found.total,
        page_number=found.page,
        pages=found.pages,
        page_url=lambda n: "/audit" + chosen.query(page=n),
        csv_url="/audit.csv" + chosen.query(),
        filtered=bool(chosen.given.keys() - {"show"}),
        shown=_switch(chosen, where.show),
        form={
            "since": time_input(where.since),
            "until": time_input(where.until),
            "user": where.user,
            "kind": where.kind,
            "resource": where.resource,
            "station": where.station,
            "text": where.text,
            "show": where.show,
        },
        choices=choices,
    )
    return _page(request, context, 200)


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


def _page(request: Request, context: dict[str, Any], status: int) -> Response:
    response: Response = server(request).templates.TemplateResponse(
        request, "audit.html", context, status_code=status
    )
    response.headers["Cache-Control"] = "no-store"
    return response


def _choices(session: Session, given: dict[str, str]) -> dict[str, list[str]]:
    """The selects' choices: the values in the log, and a chosen one even if absent."""
    return {
        column: _with(audit.distinct_values(session, column), given.get(column, ""))
        for column in ("user", "kind", "resource", "station")
    }


def _with(values: list[str], chosen: str) -> list[str]:
    return values if not chosen or chosen in values else sorted([*values, chosen])


@router.get("/audit.csv")
def audit_csv(
    request: Request,
    caller: Annotated[Caller, Depends(require(Permission.AUDIT))],
    chosen: Annotated[Criteria, Depends(filter_dependency)],
) -> StreamingResponse:
    """The filtered log as CSV, oldest first; the export is audited before it starts."""
    srv = server(request)
    now = srv.live.wall()
    export = AuditEntry(
        AuditKind.AUDIT, "csv export", caller.name, "", {"filter": chosen.described()}
    )
    audit.write(srv.store, srv.live.name, [export], now)

    def lines() -> Iterator[str]:
        with srv.store.sessions() as session:
            yield from audit.csv_lines(session, chosen.where)

    station = re.sub(r"[^A-Za-z0-9_.-]", "_", srv.live.name) or "station"
    stamp = datetime.fromtimestamp(now, UTC).strftime("%Y%m%dT%H%M%SZ")
    headers = {
        "Content-Disposition": f'attachment; filename="audit-{station}-{stamp}.csv"',
        "Cache-Control": "no-store",
    }
    return StreamingResponse(lines(), media_type="text/csv; charset=utf-8", headers=headers)
