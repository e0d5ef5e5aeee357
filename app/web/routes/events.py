"""Server-sent events: the pages' live channel (htmx SSE extension).

Each change of the runner's view is announced as an event named after what changed
(`station`, `alarm`, `tasks`) whose data is the view's version; pages re-fetch the fragments
that listen for it.  The `alarm` event carries the alarm badge instead (JSON: count,
priority) and, like the `tasks` event, the task cards waiting (`tasks`) for a caller who sees
tasks: the Tasks tab and the title of every page follow them (static/js/hmi.js).  A comment
every 15 s keeps proxies from closing an idle stream.  Every connection starts with the
view's version and the alarm badge (`badge`, the data of `alarm`), so that a page that was
offline shows the present at once (static/js/hmi.js re-fetches its live parts too).

A stream lives no longer than its session: every `SESSION_CHECK` seconds it looks the
caller up again, and a session signed out, revoked (a role change, a disabled user, a reset
password) or expired ends the stream with `signed-out`, as a signed-out page's would; the
page then goes to the sign-in page (static/js/hmi.js), and opens again under the new role.
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
    Caller,
    LiveDep,
    OptionalCaller,
    PasswordChangeRequired,
    alarm_badge,
    current_caller,
    task_count,
)

router = APIRouter()
KEEPALIVE = 15.0
SESSION_CHECK = 5.0  # seconds between looking the stream's caller up again
SIGNED_OUT = "event: signed-out\ndata: /login\n\n"
ALARMS = "alarm"  # the area app.station.live announces when an alarm changed
TASKS = "tasks"  # the task page's area (app.serve), announced when the cards change


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
            yield f"event: badge\ndata: {_data(live, ALARMS, caller)}\n\n"
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
                    yield f"event: {kind}\ndata: {_data(live, kind, caller)}\n\n"
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


def _data(live: LiveStation, kind: str, caller: Caller) -> str:
    """The alarm event carries the badge's count and highest priority, and the task cards
    waiting (for a caller who sees tasks); the tasks event the latter; others the version."""
    view = live.view
    tasks = task_count(view, caller)
    if kind == TASKS and tasks is not None:
        return json.dumps({"tasks": tasks})
    if kind != ALARMS:
        return str(view.serial)
    count, priority = alarm_badge(view)
    found: dict[str, object] = {"count": count, "priority": priority}
    if tasks is not None:
        found["tasks"] = tasks
    return json.dumps(found)
