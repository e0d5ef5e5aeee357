"""Server-sent events: the pages' live channel (htmx SSE extension).

Each change of the runner's view is announced as an event named after what changed
(`station`, `alarm`) whose data is the view's version; pages re-fetch the fragments that
listen for it.  A comment every 15 s keeps proxies from closing an idle stream.  Every
connection starts with the view's version and the alarm badge (`badge`, the data of
`alarm`), so that a page that was offline shows the present at once (static/js/hmi.js
re-fetches its live parts too).
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator

from fastapi import APIRouter, Request
from fastapi.responses import StreamingResponse

from app.station.live import LiveStation
from app.web.deps import LiveDep, OptionalCaller, alarm_badge

router = APIRouter()
KEEPALIVE = 15.0
ALARMS = "alarm"  # the area app.station.live announces when an alarm changed


@router.get("/events", include_in_schema=False)
async def events(request: Request, caller: OptionalCaller, live: LiveDep) -> StreamingResponse:
    async def stream() -> AsyncIterator[str]:
        if caller is None:
            yield "event: signed-out\ndata: /login\n\n"
            return
        changes = live.subscribe()
        try:
            yield f"retry: 1000\nevent: station\ndata: {live.view.serial}\n\n"
            # the badge only (static/js/hmi.js); "alarm" would re-fetch every alarm list
            yield f"event: badge\ndata: {_data(live, ALARMS)}\n\n"
            while not await request.is_disconnected():
                try:
                    kind = await asyncio.wait_for(changes.get(), KEEPALIVE)
                except TimeoutError:
                    yield ": keep-alive\n\n"
                    continue
                yield f"event: {kind}\ndata: {_data(live, kind)}\n\n"
        finally:
            live.unsubscribe(changes)

    headers = {"Cache-Control": "no-store", "X-Accel-Buffering": "no"}
    return StreamingResponse(stream(), media_type="text/event-stream", headers=headers)


def _data(live: LiveStation, kind: str) -> str:
    """The alarm event carries the badge's count and highest priority; others the version."""
    if kind != ALARMS:
        return str(live.view.serial)
    count, priority = alarm_badge(live.view)
    return json.dumps({"count": count, "priority": priority})
