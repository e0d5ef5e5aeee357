"""Server-sent events: the pages' live channel (htmx SSE extension).

Each change of the runner's view is announced as an event named after what changed
(`station`, `alarm`) whose data is the view's version; pages re-fetch the fragments that
listen for it.  A comment every 15 s keeps proxies from closing an idle stream.  Every
connection starts with the view's version and the alarm badge (`badge`, the data of
`alarm`), so that a page that was offline shows the present at once (static/js/hmi.js
re-fetches its live parts too).

A stream lives no longer than its session: every `SESSION_CHECK` seconds it looks the
caller up again, and a session signed out, revoked (a role change, a disabled user, a reset
password) or expired ends the stream with `signed-out`, as a signed-out page's would.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import StreamingResponse

from app.station.live import LiveStation
from app.web.deps import (
    LiveDep,
    OptionalCaller,
    PasswordChangeRequired,
    alarm_badge,
    current_caller,
)

router = APIRouter()
KEEPALIVE = 15.0
SESSION_CHECK = 5.0  # seconds between looking the stream's caller up again
SIGNED_OUT = "event: signed-out\ndata: /login\n\n"
ALARMS = "alarm"  # the area app.station.live announces when an alarm changed


@router.get("/events", include_in_schema=False)
async def events(request: Request, caller: OptionalCaller, live: LiveDep) -> StreamingResponse:
    async def stream() -> AsyncIterator[str]:
        if caller is None:
            yield SIGNED_OUT
            return
        changes = live.subscribe()
        try:
            yield f"retry: 1000\nevent: station\ndata: {live.view.serial}\n\n"
            # the badge only (static/js/hmi.js); "alarm" would re-fetch every alarm list
            yield f"event: badge\ndata: {_data(live, ALARMS)}\n\n"
            sent = checked = time.monotonic()
            while not await request.is_disconnected():
                try:
                    kind: str | None = await asyncio.wait_for(changes.get(), SESSION_CHECK)
                except TimeoutError:
                    kind = None
                now = time.monotonic()
                if now - checked >= SESSION_CHECK:
                    checked = now
                    if not await asyncio.to_thread(_signed_in, request):
                        yield SIGNED_OUT
                        return
                if kind is not None:
                    yield f"event: {kind}\ndata: {_data(live, kind)}\n\n"
                    sent = now
                elif now - sent >= KEEPALIVE:
                    yield ": keep-alive\n\n"
                    sent = now
        finally:
            live.unsubscribe(changes)

    headers = {"Cache-Control": "no-store", "X-Accel-Buffering": "no"}
    return StreamingResponse(stream(), media_type="text/event-stream", headers=headers)


def _signed_in(request: Request) -> bool:
    """Whether the stream's session (or bearer token) still admits its caller."""
    try:
        return current_caller(request) is not None
    except (HTTPException, PasswordChangeRequired):
        return False


def _data(live: LiveStation, kind: str) -> str:
    """The alarm event carries the badge's count and highest priority; others the version."""
    if kind != ALARMS:
        return str(live.view.serial)
    count, priority = alarm_badge(live.view)
    return json.dumps({"count": count, "priority": priority})
