"""The station's alarms in the ISA-18.2 sense: the runner's errors that need a person.

`conditions` reads the runner's state after a tick and says which alarm conditions hold;
`AlarmBook` keeps one record per condition key through the ISA-18.2 states and reports every
state change as an `AlarmChange`, so the audit log and the operator pages read the same
history.  Pure: no I/O, and time is passed in as `now` (seconds since the epoch).

    condition appears        none / NORMAL -> UNACKED;  RTN_UNACKED -> UNACKED
    acknowledged             UNACKED -> ACKED;          RTN_UNACKED -> NORMAL
    condition clears         UNACKED -> RTN_UNACKED;    ACKED -> NORMAL
    shelved (time-limited)   any but SHELVED -> SHELVED
    unshelved / expired      SHELVED -> UNACKED if the condition holds, else NORMAL
    its run ended            RTN_UNACKED -> NORMAL  (`end_run`, said why in the note)

A run ends when production finishes (no intention executing or in error any more), when
the station is reset to a start state (an experiment), or when production starts again on
an idle station (alarms raised while it stood): an alarm whose condition came and went in a
run that is over asks nothing of anyone any more, so it is closed with the reason on record
(the audit log keeps it) instead of piling up for a person to acknowledge by rote.  Active
alarms are never closed this way: they wait for a person as ever.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from enum import StrEnum

from app.station.alarm_conditions import Condition, Priority, conditions

__all__ = ["Alarm", "AlarmBook", "AlarmChange", "AlarmError", "AlarmState", "Condition"]
__all__ += ["SHELVE_LIMIT", "Priority", "conditions"]

SHELVE_LIMIT = 8 * 60.0  # minutes: a shelved alarm comes back within a shift


class AlarmState(StrEnum):
    UNACKED = "unacknowledged"
    ACKED = "acknowledged"
    RTN_UNACKED = "returned (unacknowledged)"
    NORMAL = "normal"
    SHELVED = "shelved"


# the states that wait for a person's acknowledgement: what the alarm badge counts
WAITING = frozenset({AlarmState.UNACKED, AlarmState.RTN_UNACKED})


@dataclass(slots=True)
class Alarm:
    """One alarm's record, kept by the book and persisted as one row per key."""

    key: str
    priority: Priority
    message: str
    resource: str
    state: AlarmState
    active: bool  # its condition holds
    raised_at: float  # when the condition last appeared
    returned_at: float | None = None  # when it last cleared
    acked_by: str | None = None
    acked_at: float | None = None
    note: str = ""  # the last note a person gave (acknowledge or shelve)
    shelved_by: str | None = None
    shelved_until: float | None = None
    # the state it was shelved from, for the record: unshelving follows the condition
    shelved_state: AlarmState | None = None
    # what follows from it, in words: grouped under it, not raised (app.station.alarm_grouping)
    consequences: tuple[str, ...] = ()
    grouped: tuple[str, ...] = ()  # their condition keys: they stay under it while they hold

    @property
    def waiting(self) -> bool:
        """Does it wait for a person's acknowledgement (active or returned, not shelved)?"""
        return self.state in WAITING


@dataclass(frozen=True, slots=True)
class AlarmChange:
    """A state change for the audit log; `note` is the person's note, or why for automatic
    changes (user None): "condition appeared", "condition cleared", "shelve expired"."""

    key: str
    before: AlarmState | None  # None: a new alarm
    after: AlarmState
    user: str | None
    note: str
    at: float
    alarm: Alarm  # a copy, as it is after the change


class AlarmError(Exception):
    """An operator's request the book refuses; the message says what to do instead."""


class AlarmBook:
    """Every alarm the station has had, one record per key, through the ISA-18.2 states."""

    def __init__(self, alarms: Iterable[Alarm] = ()) -> None:
        self._alarms: dict[str, Alarm] = {}
        for alarm in alarms:
            if alarm.key in self._alarms:
                raise AlarmError(f"two alarms with key {alarm.key}")
            self._alarms[alarm.key] = replace(alarm)

    def update(self, conditions: Mapping[str, Condition], now: float) -> list[AlarmChange]:
        """Follow the conditions that hold now; expire shelves that ran out."""
        changes: list[AlarmChange] = []
        for key in sorted(conditions):
            condition = conditions[key]
            alarm = self._alarms.get(key)
            new = alarm is None
            if alarm is None:
                alarm = Alarm(key, condition.priority, "", "", AlarmState.NORMAL, False, now)
                self._alarms[key] = alarm
            alarm.priority, alarm.message = condition.priority, condition.message
            alarm.resource, alarm.consequences = condition.resource, condition.consequences
            alarm.grouped = condition.grouped
            if alarm.active:
                continue
            alarm.active, alarm.raised_at, alarm.returned_at = True, now, None
            if alarm.state is not AlarmState.SHELVED:
                change = self._move(alarm, AlarmState.UNACKED, None, "condition appeared", now)
                changes.append(replace(change, before=None) if new else change)
        for key in sorted(self._alarms):
            alarm = self._alarms[key]
            if alarm.active and key not in conditions:
                alarm.active, alarm.returned_at = False, now
                if alarm.state is not AlarmState.SHELVED:
                    after = (
                        AlarmState.NORMAL
                        if alarm.state is AlarmState.ACKED
                        else AlarmState.RTN_UNACKED
                    )
                    changes.append(self._move(alarm, after, None, "condition cleared", now))
            until = alarm.shelved_until
            if alarm.state is AlarmState.SHELVED and until is not None and now >= until:
                changes.append(self._unshelve(alarm, None, "shelve expired", now))
        return changes

    def acknowledge(self, key: str, user: str, note: str, now: float) -> AlarmChange:
        alarm = self._get(key)
        _need_user(user, "acknowledge")
        if alarm.state is AlarmState.UNACKED:
            after = AlarmState.ACKED
        elif alarm.state is AlarmState.RTN_UNACKED:
            after = AlarmState.NORMAL
        elif alarm.state is AlarmState.SHELVED:
            raise AlarmError(f"{_called(alarm)} is shelved; unshelve it to acknowledge it")
        elif alarm.state is AlarmState.ACKED:
            raise AlarmError(f"{_called(alarm)} is already acknowledged")
        else:
            raise AlarmError(f"{_called(alarm)} is normal: there is nothing to acknowledge")
        alarm.acked_by, alarm.acked_at, alarm.note = user, now, note
        return self._move(alarm, after, user, note, now)

    def acknowledge_all(
        self, keys: Iterable[str], user: str, note: str, now: float
    ) -> list[AlarmChange]:
        """Acknowledge those of `keys` (the alarms a person was shown) that still wait, with
        one note; the others were answered or cleared meanwhile and are left alone.  Refused
        when none of them waits: then nothing was acknowledged."""
        _need_user(user, "acknowledge")
        wanted = list(dict.fromkeys(keys))
        waiting = [k for k in wanted if k in self._alarms and self._alarms[k].waiting]
        if not waiting:
            unknown = [k for k in wanted if k not in self._alarms]
            if not wanted:
                why = "no alarm was chosen"
            elif unknown:
                why = f"no alarm {', '.join(unknown)}"
            else:
                why = "they were acknowledged, shelved or closed meanwhile"
            raise AlarmError(f"nothing to acknowledge: {why}")
        return [self.acknowledge(key, user, note, now) for key in waiting]

    def end_run(self, why: str, now: float) -> list[AlarmChange]:
        """A run ended: each alarm that returned unacknowledged is closed (to normal), with
        `why` as its note; active and shelved alarms stay as they are (module docstring)."""
        returned = [a for a in self._alarms.values() if a.state is AlarmState.RTN_UNACKED]
        return [
            self._move(a, AlarmState.NORMAL, None, why, now)
            for a in sorted(returned, key=lambda a: a.key)
        ]

    def shelve(self, key: str, user: str, minutes: float, note: str, now: float) -> AlarmChange:
        """Hide an alarm from the operator's list for a while (a chattering or known one)."""
        alarm = self._get(key)
        _need_user(user, "shelve")
        if not 1 <= minutes <= SHELVE_LIMIT:  # NaN fails too
            raise AlarmError(f"shelve for 1 to {SHELVE_LIMIT:g} minutes, not {minutes:g}")
        if alarm.state is AlarmState.SHELVED:
            raise AlarmError(f"{_called(alarm)} is already shelved; unshelve it first")
        alarm.shelved_by, alarm.shelved_until = user, now + 60 * minutes
        alarm.shelved_state, alarm.note = alarm.state, note
        return self._move(alarm, AlarmState.SHELVED, user, note, now)

    def unshelve(self, key: str, user: str, now: float) -> AlarmChange:
        alarm = self._get(key)
        _need_user(user, "unshelve")
        if alarm.state is not AlarmState.SHELVED:
            raise AlarmError(f"{_called(alarm)} is not shelved")
        return self._unshelve(alarm, user, "unshelved", now)

    def alarms(self, include_normal: bool = False, include_shelved: bool = False) -> list[Alarm]:
        """Copies, active unacknowledged first, then by priority, then newest."""
        shown = [
            a
            for a in self._alarms.values()
            if (include_normal or a.state is not AlarmState.NORMAL)
            and (include_shelved or a.state is not AlarmState.SHELVED)
        ]
        shown.sort(
            key=lambda a: (a.state is not AlarmState.UNACKED, a.priority.rank, -a.raised_at, a.key)
        )
        return [replace(a) for a in shown]

    def active(self) -> dict[str, Alarm]:
        """Copies of the alarms whose condition holds (shelved ones too), by key."""
        return {a.key: replace(a) for a in self._alarms.values() if a.active}

    def first_out(self) -> str | None:
        """The key of the first alarm out among those active and shown: where a cascade began."""
        shown = [a for a in self._alarms.values() if a.active and a.state is not AlarmState.SHELVED]
        if not shown:
            return None
        return min(shown, key=lambda a: (a.raised_at, a.priority.rank, a.key)).key

    def alarm(self, key: str) -> Alarm:
        return replace(self._get(key))

    def active_count(self) -> int:
        """Active alarms the operator sees (shelved ones are hidden)."""
        return sum(a.active and a.state is not AlarmState.SHELVED for a in self._alarms.values())

    def unacknowledged_count(self) -> int:
        return sum(a.waiting for a in self._alarms.values())

    def _get(self, key: str) -> Alarm:
        alarm = self._alarms.get(key)
        if alarm is None:
            raise AlarmError(f"no alarm {key}")
        return alarm

    def _unshelve(self, alarm: Alarm, user: str | None, note: str, now: float) -> AlarmChange:
        alarm.shelved_by = alarm.shelved_until = alarm.shelved_state = None
        after = AlarmState.UNACKED if alarm.active else AlarmState.NORMAL
        return self._move(alarm, after, user, note, now)

    @staticmethod
    def _move(
        alarm: Alarm, after: AlarmState, user: str | None, note: str, now: float
    ) -> AlarmChange:
        """The one place an alarm's state changes, so every change is reported."""
        if after is AlarmState.UNACKED:  # a new occurrence: the last one's answer is history
            alarm.acked_by = alarm.acked_at = None
            alarm.note = ""
        before, alarm.state = alarm.state, after
        return AlarmChange(alarm.key, before, after, user, note, now, replace(alarm))


CALLED_CHARS = 60  # of an alarm's words, in a refusal's message


def _called(alarm: Alarm) -> str:
    """An alarm as a refusal names it: by its words (a person reads them), not its key."""
    words = alarm.message or alarm.key
    if len(words) > CALLED_CHARS:
        words = words[: CALLED_CHARS - 1].rstrip() + "…"
    return f"the alarm “{words}”"


def _need_user(user: str, what: str) -> None:
    if not user.strip():
        raise AlarmError(f"say who you are to {what} an alarm")
