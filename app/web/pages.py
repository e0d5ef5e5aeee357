"""What every page handler uses to answer: a template with the context every page gets
(`render`), a live fragment that is not sent again when unchanged (`live_fragment`), whether
htmx asked (`htmx`), a required form text (`required`), and where to send a browser back to
(`local_path`, `same_origin_path`).  The routers per area (app.web.routes) build on these;
none of them imports another's helpers.
"""

from __future__ import annotations

import hashlib
from typing import Any
from urllib.parse import urlsplit

from fastapi import HTTPException, Request
from fastapi.responses import HTMLResponse, Response

from app.people.auth import Permission, allowed
from app.web.deps import Caller, page_context, templates

_PORTS = {"http": 80, "https": 443}
FLASH = "flash"  # the session's key for what the last form came to (app.web.outcomes)
FLASH_CHARS = 300


def values_for(request: Request, caller: Caller | None, page: str, **extra: Any) -> dict[str, Any]:
    """The page context (app.web.deps.page_context) and what the caller may change.  A page
    built from one snapshot passes it as `view`: the whole page or fragment reads that one."""
    if request.method == "GET" and not htmx(request) and not {"message", "error"} & extra.keys():
        extra.update(said(request))  # what the form before this page came to, once
    found = page_context(request, caller, page, **extra)
    found["can_control"] = caller is not None and allowed(caller.role, Permission.CONTROL)
    found["can_activate"] = caller is not None and allowed(caller.role, Permission.ACTIVATE)
    return found


def render(
    request: Request,
    template: str,
    caller: Caller | None,
    page: str,
    *,
    status_code: int = 200,
    headers: dict[str, str] | None = None,
    **extra: Any,
) -> Response:
    """`template` with `values_for` and `extra`; `page` names the top bar's current page."""
    response: Response = templates(request).TemplateResponse(
        request,
        template,
        values_for(request, caller, page, **extra),
        status_code=status_code,
        headers=headers,
    )
    return response


def live_fragment(
    request: Request, template: str, caller: Caller, page: str, **extra: Any
) -> Response:
    """A fragment re-fetched on every station change (SSE).  The station changes several
    times a second (heartbeats), a fragment far less often: when the client already shows
    this very text (`seen`: the digest it got last), the answer is 204 and htmx leaves the
    page alone, so an open list, the focus and a selection survive."""
    values = values_for(request, caller, page, **extra)
    text = templates(request).get_template(template).render(values)
    digest = hashlib.blake2b(text.encode(), digest_size=8).hexdigest()
    if request.query_params.get("seen") == digest:
        return Response(status_code=204)
    return HTMLResponse(f'{text}<i hidden data-digest="{digest}"></i>')


def htmx(request: Request) -> bool:
    return bool(request.headers.get("hx-request"))


def say(request: Request, message: str = "", error: str = "") -> None:
    """What the next page shows once (a message, or an error): after a form, carried in the
    session (signed by the station; never in the URL, where anyone could write it)."""
    request.session[FLASH] = {"message": message[:FLASH_CHARS], "error": error[:FLASH_CHARS]}


def said(request: Request) -> dict[str, str]:
    """What the last form came to ({} if nothing), taken out of the session."""
    found = request.session.pop(FLASH, None)
    if not isinstance(found, dict):
        return {}
    return {k: v for k, v in found.items() if k in ("message", "error") and isinstance(v, str)}


def required(text: str, what: str) -> str:
    """`text` stripped, or a 422 before anything reaches the runner."""
    text = text.strip()
    if not text:
        raise HTTPException(422, f"{what} is required")
    return text


def local_path(target: str) -> str:
    """`target` if it is a path on this station, else "/": a "//host" path (or "/\\host",
    which browsers read alike) would leave it."""
    return target if target.startswith("/") and not target.startswith(("//", "/\\")) else "/"


def same_origin_path(request: Request) -> str:
    """Where the form was (the Referer's path and query) if that is this station, else "/":
    following the header as it came made the station an open redirect to any other site."""
    referer, own = urlsplit(request.headers.get("referer", "")), urlsplit(str(request.url))
    try:
        theirs = (referer.scheme, referer.hostname, referer.port or _PORTS.get(referer.scheme))
        ours = (own.scheme, own.hostname, own.port or _PORTS.get(own.scheme))
    except ValueError:  # a port that is not a number
        return "/"
    if theirs != ours:
        return "/"
    return local_path(referer.path + (f"?{referer.query}" if referer.query else ""))
