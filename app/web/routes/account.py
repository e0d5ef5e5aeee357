"""A signed-in user's own account page: who they are, and their API tokens (issue one,
shown once; see each live one, when and where it was issued and whether from this session;
revoke one by one).  Tokens issued here end when this browser session signs out
(app.people.sessions, app.web.tokens).  Every form answers with a redirect back to the
page (app.web.outcomes)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import Response

from app.people.sessions import HANDLE_CHARS
from app.web import outcomes, tokens
from app.web.deps import ServerDep, SignedIn, browser_session, client_address
from app.web.pages import render

router = APIRouter(include_in_schema=False)
ISSUED = "issued_token"  # a token just issued, carried to the page that shows it once


def _when(time: float) -> str:
    return datetime.fromtimestamp(time, UTC).strftime("%Y-%m-%d %H:%M UTC")


@router.get("/account")
def account(request: Request, caller: SignedIn, srv: ServerDep) -> Response:
    issued = request.session.pop(ISSUED, "")
    current = str(request.session.get("sid", "")) if not caller.bearer else ""
    found = tokens.listed(srv, caller, current)
    response = render(
        request,
        "account.html",
        caller,
        "account",
        tokens=found,
        issued=issued if isinstance(issued, str) else "",
        when=_when,
    )
    response.headers["Cache-Control"] = "no-store"  # it may show a token
    return response


@router.post("/account/tokens")
def issue_token(request: Request, caller: SignedIn, srv: ServerDep) -> Response:
    """A new API token, linked to this browser session: shown once on the page."""
    found = None if caller.bearer else browser_session(request)
    if found is None:
        raise HTTPException(409, "issue tokens from a browser session (or POST /api/token)")
    request.session[ISSUED] = tokens.issue(srv, found, client_address(request))
    return outcomes.done(request, "/account", "A new API token is issued.")


@router.post("/account/tokens/revoke")
def revoke_token(
    request: Request,
    caller: SignedIn,
    srv: ServerDep,
    token: Annotated[str, Form(min_length=HANDLE_CHARS, max_length=HANDLE_CHARS)],
) -> Response:
    tokens.revoke(srv, caller, token)
    return outcomes.done(request, "/account", f"Token {token}… is revoked.")
