"""The alarms page (ISA-18.2), watch first: one line per alarm with its priority, words and
raise time, its details and forms opened on a tap; acknowledge one, or all those shown with
one note; shelve one for a while (its end shown), unshelve it.

Every change goes through the live station's request queue (`app.station.live`), audited
per alarm in the round that makes it.  A form's answer to htmx is the refreshed list with
the top bar's badge (`_alarm_badge.html`, out of band), so the count never lags the list.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import RedirectResponse, Response

from app.people.auth import Permission, allowed
from app.station.alarms import Alarm, AlarmState
from app.station.live import LiveStation
from app.web.actions import answer
from app.web.deps import Acknowledger, AlarmViewer, Caller, LiveDep, OptionalCaller
from app.web.limits import KEY_CHARS, MOST_KEYS, NOTE_CHARS, SHELVE_MINUTES
from app.web.outcomes import done
from app.web.pages import htmx, render

router = APIRouter(include_in_schema=False)
Key = Annotated[str, Form(max_length=KEY_CHARS)]
Note = Annotated[str, Form(max_length=NOTE_CHARS)]


@dataclass(frozen=True, slots=True)
class Moment:
    """A time as a person reads it: the time of day, and how long ago (or until)."""

    at: float  # seconds since the epoch (the page's script keeps `ago` true from it)
    iso: str  # for <time datetime>
    clock: str  # "14:03", or "3 May 14:03" when not today
    ago: str  # "5 min ago", "in 25 min"


@dataclass(frozen=True, slots=True)
class AlarmRow:
    """One alarm as the page shows it."""

    key: str
    priority: str
    message: str
    state: str
    active: bool
    waiting: bool  # waits for a person's acknowledgement
    shelved: bool
    raised: Moment
    returned: Moment | None
    acked_by: str
    acked: Moment | None
    note: str
    shelved_by: str
    shelved_until: Moment | None
    consequences: tuple[str, ...] = ()  # what follows from its cause, listed under it
    first_out: bool = False  # the first of the active alarms out: where a cascade began


def relative(seconds: float) -> str:
    """How long ago (positive) or until (negative), in whole minutes, hours or days
    (static/js/alarms.js says the same words)."""
    if 0 <= seconds < 45:
        return "just now"
    minutes = max(1, int((abs(seconds) + 30) // 60))
    if minutes < 60:
        span = f"{minutes} min"
    elif minutes < 24 * 60:
        span = f"{minutes // 60} h"
    else:
        span = f"{minutes // (24 * 60)} d"
    return f"{span} ago" if seconds >= 0 else f"in {span}"


def moment(at: float, now: float) -> Moment:
    """`at` in the station's local time (its clock is the plant's)."""
    local, today = datetime.fromtimestamp(at).astimezone(), datetime.fromtimestamp(now).astimezone()
    clock = local.strftime("%H:%M")
    if local.date() != today.date():
        clock = f"{local.day} {local.strftime('%b')} {clock}"
    return Moment(at, local.isoformat(timespec="seconds"), clock, relative(now - at))


def rows(alarms: Iterable[Alarm], now: float) -> list[AlarmRow]:
    """The rows in the book's order (unacknowledged first, then priority, then newest)."""

    def maybe(at: float | None) -> Moment | None:
        return None if at is None else moment(at, now)

    alarms = list(alarms)
    shown = [a for a in alarms if a.active and a.state is not AlarmState.SHELVED]
    first = min(shown, key=lambda a: (a.raised_at, a.priority.rank, a.key)) if shown else None
    return [
        AlarmRow(
            key=a.key,
            priority=str(a.priority),
            message=a.message,
            state=str(a.state),
            active=a.active,
            waiting=a.waiting,
            shelved=a.state is AlarmState.SHELVED,
            raised=moment(a.raised_at, now),
            returned=maybe(a.returned_at),
            acked_by=a.acked_by or "",
            acked=maybe(a.acked_at),
            note=a.note,
            shelved_by=a.shelved_by or "",
            shelved_until=maybe(a.shelved_until),
            consequences=a.consequences,
            first_out=first is not None and a.key == first.key and len(shown) > 1,
        )
        for a in alarms
        if a.state is not AlarmState.NORMAL
    ]


def alarms_page(
    request: Request,
    template: str,
    caller: Caller | None,
    live: LiveStation,
    fragment: bool = False,
    acted: bool = False,
) -> Response:
    """The page or its list; a fragment carries the badge, and after a form that succeeded
    an empty flash (htmx swaps both out of band: an earlier refusal's message goes)."""
    now = live.wall()
    return render(
        request,
        template,
        caller,
        "alarms",
        alarms=rows(live.view.alarms, now),
        now=round(now, 3),
        may_act=caller is not None and allowed(caller.role, Permission.ACKNOWLEDGE),
        badge_oob=fragment,
        flash_clear=acted,
    )


@router.get("/alarms")
def alarms(request: Request, caller: OptionalCaller, live: LiveDep) -> Response:
    if caller is None:
        return RedirectResponse("/login?next=/alarms", status_code=303)
    return alarms_page(request, "alarms.html", caller, live)


@router.get("/fragments/alarms")
async def alarms_fragment(request: Request, caller: AlarmViewer, live: LiveDep) -> Response:
    return alarms_page(request, "_alarms.html", caller, live, fragment=True)


@router.post("/alarms/acknowledge")
async def acknowledge(
    request: Request, caller: Acknowledger, live: LiveDep, key: Key, note: Note = ""
) -> Response:
    await answer(live.acknowledge(key, caller.name, note.strip()))
    return _back(request, caller, live, "Acknowledged.")


@router.post("/alarms/acknowledge-all")
async def acknowledge_all(
    request: Request,
    caller: Acknowledger,
    live: LiveDep,
    keys: Annotated[list[str], Form(max_length=MOST_KEYS)],
    note: Note = "",
) -> Response:
    """The alarms the page showed as waiting (its hidden `keys`), with one note: one
    that arrived after the page was drawn is not acknowledged unseen."""
    if any(len(key) > KEY_CHARS for key in keys):
        raise HTTPException(422, f"keys: an alarm's key has at most {KEY_CHARS} characters")
    changed = await answer(live.acknowledge_all(keys, caller.name, note.strip()))
    return _back(request, caller, live, f"Acknowledged {len(changed)}.")


@router.post("/alarms/shelve")
async def shelve(
    request: Request,
    caller: Acknowledger,
    live: LiveDep,
    key: Key,
    minutes: Annotated[float, Form(gt=0, le=SHELVE_MINUTES)],
    note: Note = "",
) -> Response:
    await answer(live.shelve(key, caller.name, minutes, note.strip()))
    return _back(request, caller, live, f"Shelved for {minutes:g} min.")


@router.post("/alarms/unshelve")
async def unshelve(request: Request, caller: Acknowledger, live: LiveDep, key: Key) -> Response:
    await answer(live.unshelve(key, caller.name))
    return _back(request, caller, live, "Unshelved.")


def _back(request: Request, caller: Caller, live: LiveStation, message: str = "") -> Response:
    """After a form: htmx gets the refreshed list (and badge), a plain browser a redirect
    to the page, which says `message` once."""
    if htmx(request):
        return alarms_page(request, "_alarms.html", caller, live, fragment=True, acted=True)
    return done(request, "/alarms", message)
