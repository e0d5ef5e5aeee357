"""The audit log as the web edge reads it: a filter from a query string, shared by the audit
page, its CSV export and the API (app.web.routes.audit, app.web.api.audit), and a record's
detail as a mapping.

Which records (`show`): people's records (what a person did, sign-ins, model changes,
alarms), the station's own events, or everything.  Times are UTC throughout: a time without
a zone is read as UTC, and ISO 8601 with a zone is accepted.  A filter that cannot be read
is a 422 that says what to fix.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from typing import Annotated, Any
from urllib.parse import urlencode

from fastapi import HTTPException, Query
from sqlalchemy import Select, and_, or_

from app.store.audit import AuditFilter, AuditKind
from app.store.tables import AuditRecord
from app.web.limits import (
    KIND_CHARS,
    RESOURCE_CHARS,
    SHOW_CHARS,
    STATION_CHARS,
    TEXT_CHARS,
    TIME_CHARS,
    USER_CHARS,
)
from planner.runner import EventKind
from planner.runner.vocabulary import PersonAct
from planner.words import Wording

TIME_EXAMPLE = "2025-05-01T14:30 (UTC) or 2025-05-01T16:30:00+02:00"
# which records (`show`), as the page's switch names them; the page's default first
SHOWN = {"people": "People's records", "station": "Station events", "all": "Everything"}
EARLIEST = datetime(1, 1, 2, tzinfo=UTC).timestamp()
LATEST = datetime(9999, 12, 30, tzinfo=UTC).timestamp()
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


@dataclass(frozen=True)
class ShownFilter(AuditFilter):
    """The store's filter narrowed to people's records or the station's events (`SHOWN`).

    A person's record names its user; alarm changes count as people's records whoever made
    them (an alarm is raised for a person), the station's events are the rest."""

    show: str = "all"

    def apply(self, query: Select[Any]) -> Select[Any]:
        query = super().apply(query)
        people = or_(AuditRecord.user != "", AuditRecord.kind == AuditKind.ALARM)
        if self.show == "people":
            return query.where(people)
        if self.show == "station":
            return query.where(and_(AuditRecord.user == "", AuditRecord.kind != AuditKind.ALARM))
        return query


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


def record_words(words: Wording, kind: str, subject: str, detail: Mapping[str, Any]) -> str:
    """What a record says, in the words and numbering of the screen the person used:
    "approved step 2 of 6: robot 1: move down onto bolt pair 2", "declined step 1 of 1:
    take off the oil filters mounted too early" (the card's "I cannot do this"), "approved
    the recovery plan at once, steps 1-6 of 6: ..."; other records: the subject in words."""
    if kind != EventKind.OPERATOR:
        return words.text(subject)
    transition = str(detail.get("transition", ""))
    if subject in (PersonAct.APPROVE, PersonAct.REJECT) and transition:
        person = subject == PersonAct.REJECT and _persons_step(words, transition)
        verb = "approved" if subject == PersonAct.APPROVE else "declined" if person else "rejected"
        return f"{verb} {_step_number(detail)}: {words.step(transition)}"
    if subject in (PersonAct.APPROVE_PLAN, PersonAct.REJECT_PLAN):
        verb = "approved" if subject == PersonAct.APPROVE_PLAN else "rejected"
        names = [str(n) for n in detail.get("transitions", ()) or ()]
        numbers = [int(n) for n in detail.get("numbers", ()) or () if isinstance(n, int)]
        shown = _numbers(numbers, detail.get("of"))
        steps = "; ".join(words.step(n) for n in names)
        return f"{verb} the recovery plan at once, {shown}: {steps}"
    if subject == PersonAct.MAINTENANCE_DONE and transition:
        return f"done: {words.step(transition)}"
    return words.text(subject)


def _persons_step(words: Wording, transition: str) -> bool:
    """A person's own step (rejecting it is declining it: "I cannot do this")."""
    return words.is_maintenance(transition)


def _step_number(detail: Mapping[str, Any]) -> str:
    """ "step 2 of 6" as the screen numbered it; older records: the plan's step, from 1."""
    number, of = detail.get("number"), detail.get("of")
    if isinstance(number, int) and isinstance(of, int):
        return f"step {number} of {of}"
    step = detail.get("step")
    return f"step {step + 1}" if isinstance(step, int) else "a step"


def _numbers(numbers: list[int], of: object) -> str:
    if not numbers:
        return "its steps"
    total = f" of {of}" if isinstance(of, int) else ""
    if numbers == list(range(numbers[0], numbers[-1] + 1)) and len(numbers) > 1:
        return f"steps {numbers[0]}-{numbers[-1]}{total}"
    listed = ", ".join(map(str, numbers))
    return f"step{'s' if len(numbers) > 1 else ''} {listed}{total}"


def detail_of(record: AuditRecord) -> dict[str, Any]:
    """The record's detail JSON as a mapping (a non-object is kept under "value")."""
    try:
        detail = json.loads(record.detail or "{}")
    except ValueError:
        return {"value": record.detail}
    return detail if isinstance(detail, dict) else {"value": detail}
