"""What every area of the API shares: its prefix and bearer scheme, the documented error
answers, and the path parameter of a name in the model."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Depends, Path
from fastapi.security import HTTPBearer

from app.web.api.schemas import ActionAnswer, Invalid, Message, events_out
from app.web.limits import NAME_CHARS
from planner.runner import Event

PREFIX = "/api"
# documents the scheme (Swagger's "Authorize"); `Requires` does the checking
bearer = HTTPBearer(auto_error=False, description="a token from POST /api/token")
BEARER = [Depends(bearer)]  # every area's router's dependencies (not the token's own route)

DESCRIBED = {
    400: (Message, "the body is not readable (not UTF-8 JSON)"),
    401: (Message, "not signed in, or the bearer token is invalid or expired"),
    403: (Message, "the caller's role lacks the permission"),
    404: (Message, "no such name or number; the message suggests the closest"),
    409: (Message, "the station refuses it now; the message gives the runner's reason"),
    422: (Invalid, "the request does not fit; the message says what to fix"),
    503: (Message, "the station did not answer in time"),
}


def errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """The OpenAPI `responses` of the error answers `codes`."""
    return {c: {"model": DESCRIBED[c][0], "description": DESCRIBED[c][1]} for c in codes}


ACT = errors(400, 401, 403, 404, 409, 422, 503)  # what an action may answer instead

NamePath = Annotated[
    str, Path(min_length=1, max_length=NAME_CHARS, description="a name in the model")
]


def acted(events: list[Event]) -> ActionAnswer:
    return ActionAnswer(events=events_out(events))
