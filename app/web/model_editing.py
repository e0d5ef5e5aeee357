"""Validating, saving, comparing and activating model versions; shared by pages and API.

Validation runs the real loader, so the editor shows exactly what `sp check` would say, each
problem at its line and column.  Activation builds the new version's planners first (the
supervisor synthesis can take seconds, in a worker thread) and only then asks the station to
switch, which it refuses unless it is idle or in restart mode.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from fastapi import HTTPException
from starlette.concurrency import run_in_threadpool

from app.station_view import build_model
from app.store import audit, versions
from app.store.audit import AuditEntry
from app.store.tables import ModelVersion
from app.web.actions import answer
from app.web.server import Server
from planner.loading import ModelError
from planner.station import load_station

MAX_MODEL_CHARS = 2_000_000


@dataclass(frozen=True)
class Problem:
    line: int
    column: int
    message: str


def problems(text: str) -> list[Problem]:
    """Every problem the loader finds in `text` (empty when the model is valid)."""
    if len(text) > MAX_MODEL_CHARS:
        return [Problem(1, 1, f"the model is longer than {MAX_MODEL_CHARS} characters")]
    if not text.strip():
        return [Problem(1, 1, "the model is empty")]
    try:
        load_station(text, "model")
    except ModelError as exc:
        return [Problem(d.location.line, d.location.column, d.message) for d in exc.diagnostics]
    return []


def save(
    srv: Server, text: str, author: str, note: str
) -> tuple[ModelVersion | None, list[Problem]]:
    """Save `text` as a new version if it is valid; audited.  (None, problems) otherwise."""
    found = problems(text)
    if found:
        return None, found
    name = srv.live.name
    with srv.store.sessions.begin() as session:
        row = versions.add(session, name, text, author, note)
        audit.append(
            session,
            name,
            [AuditEntry("model", "saved", author, "", {"version": row.number, "note": note})],
            srv.live.wall(),
        )
        session.expunge(row)
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
    """Make version `number` the running model (409 when the station is busy)."""
    row = stored(srv, number)
    if row.id == srv.live.model.version_id:
        raise HTTPException(409, f"version {number} is already active")
    why = srv.live.busy()
    if why:
        raise HTTPException(409, f"{why}; activate when it is idle or in restart mode")
    model = await run_in_threadpool(build_model, row, srv.cache)
    await answer(srv.live.activate(model, user))
    if srv.experiments:
        from app.serve import experiments

        srv.experiments = experiments(model.station)
