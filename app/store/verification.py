"""`sp audit verify`: what an auditor can rely on, in plain words.

Checked, with the station's key file and its checkpoints:

- every audit record's hash (its fields and the previous record's hash): a record changed in
  place, or inserted or removed in the middle, breaks the chain;
- every record's seal (an HMAC of its hash under the key): a forged record, or a chain
  recomputed from some record on, does not match without the key;
- the signed checkpoints: a log shorter than a checkpoint saw (the newest records, or all of
  them, deleted), or a record at a checkpoint's count whose hash changed (history rewritten);
- every sealed row (users, sessions and API tokens, model versions, each station's state with
  its snapshot, alarms, settings; app.store.row_seals): its seal (changed outside the
  station), its counter against the newest signed checkpoint (an older sealed copy written
  back), a row the station never deletes still there, a model version's text against its
  hash, and each station's state against the audit record it follows;
- the users' names against the users the log recorded as added (a row inserted or deleted
  outside the station);
- values of the wrong type (binary data where text or numbers belong).

Not detectable: records deleted, or rows put back to an older sealed copy, after the newest
checkpoint (a change to people's rights is checkpointed at once, the station's state and
alarms every period, 60 s, and when the station stops), a database and checkpoints file both
put back to an older copy, and anything done with the key file in hand (the running station,
or whoever can read the key).  Keep the key file and the checkpoints where the database's
writers cannot reach them.
"""

from __future__ import annotations

import hmac
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.store import checkpoints, integrity, seals
from app.store.audit import GENESIS, AuditKind, record_hash
from app.store.db import Store
from app.store.keys import StationKeys

AUDIT_COLUMNS = (
    "id", "time", "station", "user", "kind", "subject", "resource", "detail", "previous", "hash",
    "mac",
)  # fmt: skip
TEXT = ("station", "user", "kind", "subject", "resource", "detail", "previous", "hash", "mac")


@dataclass
class Report:
    """What `verify` found: `problems` make the log untrustworthy; `notes` say what could not
    be checked."""

    records: int = 0
    head: str = GENESIS
    newest: float | None = None
    sealed_from: int | None = None  # the first sealed record
    checkpoints: int = 0
    checked_up_to: int = 0  # records covered by the newest valid checkpoint
    users: int = 0
    rows: int = 0  # sealed rows checked (users, sessions, model versions, state, alarms...)
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def intact(self) -> bool:
        return not self.problems


@dataclass
class _Runs:
    """Consecutive records with the same problem, said once as a range."""

    said: list[str] = field(default_factory=list)
    open: tuple[str, int, int] | None = None

    def add(self, what: str, record: int) -> None:
        if self.open is not None and self.open[0] == what and self.open[2] == record - 1:
            self.open = (what, self.open[1], record)
            return
        self.close()
        self.open = (what, record, record)

    def close(self) -> None:
        if self.open is None:
            return
        what, first, last = self.open
        where = f"record {first}" if first == last else f"records {first}-{last}"
        self.said.append(f"{where}: {what}")
        self.open = None


def _wrong_type(row: dict[str, Any], numbers: Sequence[str], texts: Sequence[str]) -> str:
    for name in numbers:
        value = row[name]
        if isinstance(value, bool) or not isinstance(value, int | float):
            return f"its {name} is {_kind_of(value)}, not a number"
    for name in texts:
        if not isinstance(row[name], str):
            return f"its {name} is {_kind_of(row[name])}, not text"
    return ""


def _kind_of(value: object) -> str:
    if isinstance(value, bytes | bytearray | memoryview):
        return "binary data"
    if value is None:
        return "empty (NULL)"
    return type(value).__name__


def verify(store: Store, keys: StationKeys | None) -> Report:
    report = Report()
    runs = _Runs()
    added: dict[str, int] = {}  # user name -> the record that added it
    hashes: dict[int, str] = {}
    previous, expected_id = GENESIS, 1
    for row in integrity.raw_rows(store, "audit", AUDIT_COLUMNS, "id"):
        report.records += 1
        wrong = _wrong_type(row, ("id", "time"), TEXT)
        record = row["id"] if isinstance(row["id"], int) else expected_id
        if wrong:
            runs.add(f"{wrong}: written outside the station", record)
            previous, expected_id = str(row["hash"]), record + 1
            continue
        if record != expected_id:
            runs.close()
            gap = f"{expected_id}-{record - 1}" if record - 1 > expected_id else f"{expected_id}"
            report.problems.append(f"record {gap} missing (deleted from the middle of the log)")
        if row["previous"] != previous:
            runs.add("does not follow the record before it (inserted, or one removed)", record)
        digest = record_hash(*(row[c] for c in AUDIT_COLUMNS[:9]))
        if digest != row["hash"]:
            runs.add("its content does not match its hash (changed after it was written)", record)
        else:
            if row["mac"] and report.sealed_from is None:
                report.sealed_from = record
            if keys is not None:
                _check_seal(keys, row, record, report, runs)
        hashes[record] = row["hash"]
        report.newest = float(row["time"])
        _note_users(row, record, added)
        previous, expected_id = row["hash"], record + 1
    runs.close()
    report.problems[:0] = runs.said
    report.head = previous
    if keys is None:
        if report.sealed_from is not None:
            report.problems.append(
                "the log is sealed, but without its key file the seals, checkpoints and users "
                "cannot be checked: a chain recomputed by someone with write access would look "
                "intact (name the key file with --keys)"
            )
        else:
            report.notes.append("no seals: only the hash chain was checked")
        return report
    _check_checkpoints(keys, report, hashes)
    _check_users(store, report, added)
    _check_rows(store, keys, report)
    return report


def _check_seal(
    keys: StationKeys, row: dict[str, Any], record: int, report: Report, runs: _Runs
) -> None:
    if row["mac"]:
        if not hmac.compare_digest(row["mac"], seals.record_mac(keys, row["hash"])):
            runs.add("its seal does not match (forged or re-chained without the key)", record)
    elif report.sealed_from is not None:
        runs.add("has no seal although sealed records come before it (added outside)", record)


def _note_users(row: dict[str, Any], record: int, added: dict[str, int]) -> None:
    if row["kind"] not in (AuditKind.USER, AuditKind.AUDIT):
        return
    try:
        detail = json.loads(row["detail"])
    except ValueError:
        return
    if not isinstance(detail, dict):
        return
    if row["kind"] == AuditKind.USER and row["subject"] == "added":
        added[str(detail.get("name", ""))] = record
    elif row["kind"] == AuditKind.AUDIT and row["subject"] == "sealed":
        for name in detail.get("users", ()):
            added[str(name)] = record


def _check_checkpoints(keys: StationKeys, report: Report, hashes: dict[int, str]) -> None:
    path = keys.checkpoints
    if path is None:
        return
    if not path.exists():
        if report.sealed_from is not None:
            report.problems.append(
                f"there is no checkpoints file at {path}: whether the newest records were "
                "deleted cannot be checked"
            )
        return
    found, damaged = checkpoints.read_lines(path)
    report.problems.extend(damaged)
    for line, checkpoint in found:
        when = _when(checkpoint.time)
        if not checkpoint.valid(keys):
            report.problems.append(
                f"the checkpoint of {when} (line {line}) is not signed with the station's key"
            )
            continue
        report.checkpoints += 1
        if checkpoint.count > report.records:
            report.problems.append(
                f"the log has {report.records} records, but the checkpoint of {when} saw "
                f"{checkpoint.count}: the newest {checkpoint.count - report.records} were deleted"
            )
        elif checkpoint.count and hashes.get(checkpoint.count) != checkpoint.head:
            report.problems.append(
                f"record {checkpoint.count} is not the one the checkpoint of {when} saw: the "
                "history up to it was rewritten"
            )
        report.checked_up_to = max(report.checked_up_to, checkpoint.count)


def _check_users(store: Store, report: Report, added: dict[str, int]) -> None:
    """The users' names against the log: a row inserted or deleted outside the station."""
    seen = set()
    for row in integrity.raw_rows(store, "users", ("id", "name"), "id"):
        report.users += 1
        name = str(row["name"])
        seen.add(name)
        if name not in added and report.sealed_from is not None:
            report.problems.append(
                f"user '{name}' was never added by the station (no record of it in the log): "
                "inserted outside the station"
            )
    for name, record in sorted(added.items(), key=lambda item: item[1]):
        if name not in seen:
            report.problems.append(
                f"user '{name}', added in record {record}, is no longer in the users table: "
                "deleted outside the station"
            )


def _check_rows(store: Store, keys: StationKeys, report: Report) -> None:
    """Every sealed row (app.store.row_seals): its seal, its counter against the newest
    checkpoint of each station, a row the station would not delete still there; each
    station's state against the log."""
    stations = [str(r["name"]) for r in integrity.raw_rows(store, "stations", ("name",), "name")]
    known: dict[str, int] = {}
    for station in stations:
        for identity, seq in checkpoints.newest_rows(keys, station).items():
            known[identity] = max(seq, known.get(identity, 0))
    check = integrity.check_rows(store, keys, "", known, None)
    report.rows = check.rows
    report.problems.extend(f.problem for f in check.findings)
    for station in stations:
        why = integrity.check_snapshot(store, station)
        if why:
            report.problems.append(f"station {station}: {why}")


def _when(seconds: float) -> str:
    from datetime import UTC, datetime

    return datetime.fromtimestamp(seconds, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def describe(report: Report, keys_path: Path | None) -> list[str]:
    """The report as lines for a person."""
    lines = [f"problem: {p}" for p in report.problems]
    lines += [f"note: {n}" for n in report.notes]
    newest = f", the newest of {_when(report.newest)}" if report.newest is not None else ""
    summary = f"{report.records} records{newest}; {report.users} users"
    summary += f"; {report.rows} sealed rows"
    if report.checkpoints:
        summary += (
            f"; {report.checkpoints} signed checkpoints, the newest covering "
            f"{report.checked_up_to} records"
        )
    if keys_path is not None:
        summary += f" (key file {keys_path})"
    if report.intact:
        lines.append(f"audit log intact: {summary}")
    else:
        lines.append(f"audit log NOT intact: {len(report.problems)} problem(s); {summary}")
    return lines
