"""Validating, saving, comparing and activating model versions; shared by pages and API.

Validation runs the real loader, so the editor shows exactly what `sp check` would say, each
problem at its line and column, in a child process within the model budget
(`app.station.model_budget`), and is audited.  Activation builds the new version's
supervisor first, in such a child too (over budget: "the supervisor is too large to build
within N s", and the running model goes on), then its planners from the cache the child
filled, and only then asks the station to switch, which it refuses unless it is idle or in
restart mode.
"""

from __future__ import annotations

import contextlib
import difflib
import gc
import hashlib
from dataclasses import dataclass

from fastapi import HTTPException
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from app.station.experiments import experiments
from app.station.model_budget import OverBudget
from app.station.requests import StationError
from app.station.view import build_model
from app.store import audit, integrity, versions
from app.store.audit import AuditEntry, AuditKind
from app.store.tables import ModelVersion
from app.web.actions import answer
from app.web.limits import MAX_MODEL_CHARS
from app.web.server import Server


@dataclass(frozen=True)
class Problem:
    line: int
    column: int
    message: str


def problems(srv: Server, text: str) -> list[Problem]:
    """Every problem the loader finds in `text` (empty when the model is valid), read in a
    child process within the model budget (over it: a problem at line 1, column 1)."""
    if len(text) > MAX_MODEL_CHARS:
        return [Problem(1, 1, f"the model is longer than {MAX_MODEL_CHARS} characters")]
    if not text.strip():
        return [Problem(1, 1, "the model is empty")]
    try:
        found = srv.models.problems(text, "model")
    except OverBudget as exc:
        return [Problem(1, 1, exc.message)]
    return [Problem(line, column, message) for line, column, message in found]


def validate(srv: Server, text: str, user: str) -> list[Problem]:
    """`problems`, audited: who validated which text (its SHA-256) and what was found."""
    found = problems(srv, text)
    detail: dict[str, object] = {"sha256": hashlib.sha256(text.encode()).hexdigest()}
    if found:
        first = found[0]
        detail["problems"] = len(found)
        detail["first"] = f"line {first.line}, column {first.column}: {first.message}"[:300]
    subject = "validation refused" if found else "validated"
    entry = AuditEntry(AuditKind.MODEL, subject, user, "", detail)
    audit.write(srv.store, srv.live.name, [entry], srv.live.wall())
    return found


def unchanged(srv: Server, text: str, based_on: int | None) -> int | None:
    """The number of the version `text` is identical to (line ends aside): the one it was
    based on, or else the newest one (None if it differs, or there is no such version)."""
    with srv.store.sessions() as session:
        if based_on is not None:
            row = versions.version(session, srv.live.name, based_on)
        else:
            row = versions.newest(session, srv.live.name)
        if row is not None and _lines(row.text) == _lines(text):
            return row.number
    return None


def _lines(text: str) -> str:
    return text.replace("\r\n", "\n")


def save(
    srv: Server, text: str, author: str, note: str
) -> tuple[ModelVersion | None, list[Problem]]:
    """Save `text` as a new version if it is valid; audited (its validation too).
    (None, problems) otherwise."""
    found = validate(srv, text, author)
    if found:
        return None, found
    name = srv.live.name

    def add(session: Session) -> ModelVersion:
        row = versions.add(session, name, text, author, note)
        session.flush()
        return row

    def saved(row: ModelVersion) -> list[AuditEntry]:
        return [
            AuditEntry(AuditKind.MODEL, "saved", author, "", {"version": row.number, "note": note})
        ]

    row = audit.write(srv.store, name, saved, srv.live.wall(), also=add)
    assert row is not None
    return row, []


def diff(old: str, new: str, old_name: str, new_name: str) -> list[tuple[str, str]]:
    """A unified diff as (kind, line) pairs: kind is "add", "del", "hunk" or "same"."""
    lines = []
    for line in difflib.unified_diff(
        old.splitlines(), new.splitlines(), old_name, new_name, lineterm="", n=3
    ):
        if line.startswith(("+++", "---")):
            continue
        kind = {"+": "add", "-": "del", "@": "hunk"}.get(line[:1], "same")
        lines.append((kind, line))
    return lines


def stored(srv: Server, number: int) -> ModelVersion:
    with srv.store.sessions() as session:
        row = versions.version(session, srv.live.name, number)
        if row is None:
            raise HTTPException(404, f"there is no model version {number}")
        session.expunge(row)
        return row


async def activate(srv: Server, number: int, user: str) -> None:
    """Make version `number` the running model (409 when the station is busy, or while
    another activation is under way: one at a time, however many engineers press it)."""
    if not srv.activation.acquire(blocking=False):
        raise HTTPException(409, "another activation is under way; try again when it is done")
    try:
        await _activate(srv, number, user)
    finally:
        srv.activation.release()


async def _refuse_tampered(srv: Server, row: ModelVersion, why: str, user: str) -> None:
    """A version changed outside the station never runs: audited, a high alarm, and 409."""
    detail = {"version": row.number, "why": why}
    entry = AuditEntry(AuditKind.MODEL, "activation refused: changed outside", user, "", detail)
    await run_in_threadpool(audit.write, srv.store, srv.live.name, [entry], srv.live.wall())
    what = f"{why}: its activation by {user} was refused. Check the audit log."
    with contextlib.suppress(HTTPException, StationError):  # a stopped station: audited
        await answer(srv.live.report_tampering(f"model-version:{row.number}", what, user))
    raise HTTPException(409, f"{why}; it is not activated (the refusal is audited)")


async def _built_within_budget(srv: Server, row: ModelVersion, user: str) -> None:
    """The version's supervisor synthesised in a child within the budget (into the cache,
    which `build_model` then reads); over budget, the refusal is audited and said (422),
    and the running model is untouched."""
    file = f"model version {row.number}"
    try:
        found = await run_in_threadpool(srv.models.build, row.text, file, srv.cache)
        why = "; ".join(f"line {line}, column {column}: {m}" for line, column, m in found[:3])
    except OverBudget as exc:
        why = f"{file}: {exc.message}"
    if not why:
        return
    detail = {"version": row.number, "why": why[:500]}
    entry = AuditEntry(AuditKind.MODEL, "activation refused: over budget", user, "", detail)
    await run_in_threadpool(audit.write, srv.store, srv.live.name, [entry], srv.live.wall())
    raise HTTPException(422, f"{why}; it is not activated, version {srv.live.model.number} runs on")


async def _activate(srv: Server, number: int, user: str) -> None:
    row = stored(srv, number)
    refused = integrity.version_problem(srv.store, row)
    if refused:
        await _refuse_tampered(srv, row, refused, user)
    if row.id == srv.live.model.version_id:
        raise HTTPException(409, f"version {number} is already active")
    why = srv.live.busy()
    if why:
        raise HTTPException(409, f"{why}; activate when it is idle or in restart mode")
    await _built_within_budget(srv, row, user)
    model = await run_in_threadpool(build_model, row, srv.cache)
    prepared = await run_in_threadpool(srv.live.prepare, model)
    await answer(srv.live.activate(prepared, user))
    if gc.get_freeze_count():  # `sp serve` froze the old model's objects: let them go
        gc.unfreeze()
        gc.collect()  # one long collection, while the station is idle or in restart mode
        gc.freeze()
    if srv.live.simulated:  # those that fit the new model (none may, and all may again)
        srv.experiments = experiments(model.station, srv.live.emulated)
