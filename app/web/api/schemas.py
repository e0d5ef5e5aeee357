"""The Pydantic models every area of the API shares (app.web.api: each area's own are beside
its routes): request bodies' base, errors, and the runner's events.

Requests carry constraints (lengths, ranges, literals) so that junk is refused with a 422
that names the field before any handler runs; answers say what the station did.  Times in
answers are UTC date-times, except the runner's own clock (seconds since the station
started) in events.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, StringConstraints

from app.web.limits import NAME_CHARS, NOTE_CHARS
from planner.runner import Event

Name = Annotated[str, StringConstraints(min_length=1, max_length=NAME_CHARS)]
Note = Annotated[str, StringConstraints(max_length=NOTE_CHARS)]


class RequestBody(BaseModel):
    """A request body: unknown fields are refused rather than silently ignored."""

    model_config = ConfigDict(extra="forbid")


class Message(BaseModel):
    """An error: what went wrong and, where possible, what to do instead."""

    detail: str


class FieldError(BaseModel):
    loc: list[str | int]
    msg: str


class ProblemOut(BaseModel):
    """A problem in a model text, where the editor would show it."""

    line: int
    column: int
    message: str


class Invalid(BaseModel):
    """A 422: `detail` says what to fix; `errors` locate bad request fields, `problems`
    locate errors in a model text (POST /api/models)."""

    detail: str
    errors: list[FieldError] = []
    problems: list[ProblemOut] = []


class EventOut(BaseModel):
    """One thing the runner did (its kind is one of planner.runner.EventKind)."""

    time: float = Field(description="the runner's clock: seconds since the station started")
    kind: str
    subject: str
    detail: dict[str, Any] = {}
    millis: float | None = Field(None, description="planning time, for a plan event")


class ActionAnswer(BaseModel):
    """An action the station took: the runner's events of the tick that carried it out."""

    events: list[EventOut]


def _json_ready(detail: Mapping[str, Any]) -> dict[str, Any]:
    """Event details are plain values, but sets or tuples may appear: make them JSON."""
    ready: dict[str, Any] = json.loads(json.dumps(dict(detail), default=_jsonable))
    return ready


def _jsonable(value: object) -> object:
    if isinstance(value, set | frozenset):
        return sorted(value, key=str)
    return str(value)


def events_out(events: Iterable[Event]) -> list[EventOut]:
    return [
        EventOut(
            time=round(e.time, 3),
            kind=e.kind,
            subject=e.subject,
            detail=_json_ready(e.detail),
            millis=None if e.millis is None else round(e.millis, 2),
        )
        for e in events
    ]
