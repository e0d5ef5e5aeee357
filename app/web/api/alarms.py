"""The alarms through the API: those active, unacknowledged or shelved (permission
`alarms`), and acknowledging, shelving and unshelving one (permission `acknowledge`)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException
from pydantic import BaseModel, Field, StringConstraints

from app.station.alarms import SHELVE_LIMIT, Alarm, AlarmChange
from app.station.live import LiveStation
from app.web.actions import answer
from app.web.api.common import ACT, BEARER, PREFIX, errors
from app.web.api.schemas import Note, RequestBody
from app.web.deps import Acknowledger, AlarmViewer, LiveDep
from app.web.limits import KEY_CHARS
from planner.reading.yaml_reader import closest

router = APIRouter(prefix=PREFIX, tags=["alarms"], dependencies=BEARER)
AlarmKey = Annotated[str, StringConstraints(min_length=1, max_length=KEY_CHARS)]


class AlarmOut(BaseModel):
    key: str
    priority: Literal["critical", "high", "medium", "low"]
    message: str
    resource: str
    state: str
    active: bool = Field(description="its condition holds now")
    raised_at: datetime
    returned_at: datetime | None
    acked_by: str | None
    acked_at: datetime | None
    note: str
    shelved_by: str | None
    shelved_until: datetime | None
    consequences: list[str] = Field(
        default_factory=list,
        description="what follows from this alarm's cause, in words: grouped under it, not "
        "raised as alarms of their own (an operation in error because a robot is silent)",
    )


class AlarmChangeOut(BaseModel):
    key: str
    before: str | None
    after: str
    user: str | None
    note: str
    at: datetime
    alarm: AlarmOut


class AcknowledgeIn(RequestBody):
    key: AlarmKey
    note: Note = ""


class ShelveIn(RequestBody):
    key: AlarmKey
    minutes: float = Field(ge=1, le=SHELVE_LIMIT, allow_inf_nan=False)
    note: Note = ""


class UnshelveIn(RequestBody):
    key: AlarmKey


def _when(time: float | None) -> datetime | None:
    return None if time is None else datetime.fromtimestamp(time, UTC)


def alarm_out(alarm: Alarm) -> AlarmOut:
    return AlarmOut(
        key=alarm.key,
        priority=alarm.priority.value,
        message=alarm.message,
        resource=alarm.resource,
        state=str(alarm.state),
        active=alarm.active,
        raised_at=datetime.fromtimestamp(alarm.raised_at, UTC),
        returned_at=_when(alarm.returned_at),
        acked_by=alarm.acked_by,
        acked_at=_when(alarm.acked_at),
        note=alarm.note,
        shelved_by=alarm.shelved_by,
        shelved_until=_when(alarm.shelved_until),
        consequences=list(alarm.consequences),
    )


def change_out(change: AlarmChange) -> AlarmChangeOut:
    return AlarmChangeOut(
        key=change.key,
        before=None if change.before is None else str(change.before),
        after=str(change.after),
        user=change.user,
        note=change.note,
        at=datetime.fromtimestamp(change.at, UTC),
        alarm=alarm_out(change.alarm),
    )


def _alarm_key(live: LiveStation, key: str) -> str:
    keys = [a.key for a in live.view.alarms]
    if key in keys:
        return key
    guess = closest(key, keys)
    hint = f"; did you mean '{guess}'?" if guess else ""
    raise HTTPException(404, f"there is no active or shelved alarm '{key}'{hint}")


@router.get(
    "/alarms",
    summary="Active, unacknowledged and shelved alarms",
    responses=errors(401, 403),
)
def get_alarms(_caller: AlarmViewer, live: LiveDep) -> list[AlarmOut]:
    """Unacknowledged first, then by priority, then newest.  Needs `alarms`."""
    return [alarm_out(a) for a in live.view.alarms]


@router.post("/alarms/acknowledge", summary="Acknowledge an alarm", responses=ACT)
async def acknowledge(caller: Acknowledger, live: LiveDep, body: AcknowledgeIn) -> AlarmChangeOut:
    """Keys contain ':' (resource:r2), so they travel in the body.  Needs `acknowledge`."""
    key = _alarm_key(live, body.key)
    return change_out(await answer(live.acknowledge(key, caller.name, body.note.strip())))


@router.post("/alarms/shelve", summary="Shelve an alarm for a while", responses=ACT)
async def shelve(caller: Acknowledger, live: LiveDep, body: ShelveIn) -> AlarmChangeOut:
    """It comes back by itself after `minutes` (at most a shift).  Needs `acknowledge`."""
    key = _alarm_key(live, body.key)
    change = await answer(live.shelve(key, caller.name, body.minutes, body.note.strip()))
    return change_out(change)


@router.post("/alarms/unshelve", summary="Unshelve an alarm", responses=ACT)
async def unshelve(caller: Acknowledger, live: LiveDep, body: UnshelveIn) -> AlarmChangeOut:
    """Needs `acknowledge`."""
    key = _alarm_key(live, body.key)
    return change_out(await answer(live.unshelve(key, caller.name)))
