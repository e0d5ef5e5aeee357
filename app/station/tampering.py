"""What the station does when its store was changed outside it (app.store.integrity).

A row it would act on (its state and snapshot, its alarms, its active model version, the
settings) that cannot be trusted stops it from starting: `refuse_start` audits why, leaves a
high alarm in the alarm book for when it runs again, and raises `StoreTampered` for `sp
serve` to say and exit.  Rows it only refuses one by one (users, sessions, other model
versions) let it start, with a high alarm and an audit record naming them.
"""

from __future__ import annotations

from sqlalchemy.orm import Session

from app.station.alarms import Alarm, AlarmState, Condition, Priority
from app.station.records import alarm_to_json
from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from app.store.integrity import RowCheck
from app.store.row_seals import Tampered
from app.store.tables import AlarmRecord

REFUSED_KEY = "store:refused-start"
FOUND_KEY = "store:rows"
SHOWN = 20  # findings named in an audit record or an alarm; the rest counted


class StoreTampered(RuntimeError):
    """The station will not start on a store whose steering rows were changed outside it."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems
        listed = "\n".join(f"  - {p}" for p in problems[:SHOWN])
        more = f"\n  ... and {len(problems) - SHOWN} more" if len(problems) > SHOWN else ""
        super().__init__(
            "the station's store was changed outside the station; it will not start:\n"
            f"{listed}{more}\n"
            "Restore the store from a backup, or, once a person has checked what changed, "
            "accept it with `sp store accept` (audited)."
        )


def refuse_start(store: Store, station: str, check: RowCheck, now: float) -> StoreTampered:
    """Audit the refusal and leave a high alarm for the next start; returns the error."""
    problems = [f.problem for f in check.steering]
    detail = {"problems": problems[:SHOWN], "count": len(problems)}
    entry = AuditEntry(AuditKind.AUDIT, "start refused: store changed outside", "", "", detail)
    message = (
        f"The station refused to start: {len(problems)} of its store's rows were changed "
        f"outside it ({_short(problems[0])}). Check the audit log before going on."
    )

    def leave_alarm(session: Session) -> None:
        if session.get(AlarmRecord, (station, REFUSED_KEY)) is not None:
            return  # said already at an earlier refusal
        alarm = Alarm(REFUSED_KEY, Priority.HIGH, message, "", AlarmState.RTN_UNACKED, False, now)
        session.add(AlarmRecord(station=station, key=REFUSED_KEY, data=alarm_to_json(alarm),
                                updated_at=now))  # fmt: skip

    try:
        audit.write(store, station, [entry], now, also=leave_alarm)
    except Tampered:  # the alarm row itself was changed: the refusal is audited all the same
        audit.write(store, station, [entry], now)
    return StoreTampered(problems)


def found_at_start(store: Store, station: str, check: RowCheck, now: float) -> Condition:
    """Rows refused one by one: audited, and the high alarm that says so while it runs."""
    problems = [f.problem for f in check.findings]
    detail = {"problems": problems[:SHOWN], "count": len(problems)}
    entry = AuditEntry(AuditKind.AUDIT, "rows changed outside the station", "", "", detail)
    audit.write(store, station, [entry], now)
    return Condition(
        FOUND_KEY,
        Priority.HIGH,
        f"{len(problems)} rows of the station's store were changed outside it and are not "
        f"used ({_short(problems[0])}); `sp audit verify` names them all.",
    )


def _short(problem: str) -> str:
    return problem if len(problem) <= 120 else problem[:117] + "..."
