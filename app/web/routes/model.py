"""The model editor: a version's text in the code editor, validation with located problems,
saving as a new version, the versions with their diff to the active one, and activation
(the heading follows it at once).  What it does to versions is app.web.model_editing, which
the API shares.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Form, Query, Request
from fastapi.responses import Response

from app.store import versions
from app.web import model_editing, outcomes
from app.web.deps import Activator, Caller, LiveDep, ModelEditor, ServerDep
from app.web.limits import (
    MAX_MODEL_CHARS,
    MAX_VERSION,
    MODEL_BODY_BYTES,
    MODEL_FORM_LIMITS,
    NOTE_CHARS,
)
from app.web.pages import htmx, live_fragment, render
from app.web.server import Server

router = APIRouter(include_in_schema=False)
Text = Annotated[str, Form(max_length=MAX_MODEL_CHARS)]


def versions_context(srv: Server) -> dict[str, Any]:
    active_id = srv.live.model.version_id
    with srv.store.sessions() as session:
        rows = [
            {
                "number": v.number,
                "author": v.author,
                "note": v.note,
                "saved": datetime.fromtimestamp(v.created_at).astimezone(),
                "active": v.id == active_id,
            }
            for v in versions.versions(session, srv.live.name)
        ]
    return {"versions": rows, "active_number": srv.live.model.number}


def model_page(
    request: Request,
    caller: Caller,
    srv: Server,
    text: str,
    editing: int,
    status_code: int = 200,
    **extra: Any,
) -> Response:
    return render(
        request,
        "model.html",
        caller,
        "model",
        view=srv.live.view,
        status_code=status_code,
        text=text,
        editing=editing,
        **versions_context(srv),
        busy=srv.live.busy(),
        **extra,
    )


@router.get("/model")
def model_editor(
    request: Request,
    caller: ModelEditor,
    srv: ServerDep,
    version: Annotated[int | None, Query(ge=1, le=MAX_VERSION)] = None,
) -> Response:
    if version is None:
        text, editing = srv.live.model.text, srv.live.model.number
    else:
        text, editing = model_editing.stored(srv, version).text, version
    return model_page(request, caller, srv, text, editing)


@router.post(
    "/model/validate",
    max_body_size=MODEL_BODY_BYTES,
    form_limits=MODEL_FORM_LIMITS,  # type: ignore[arg-type]
)
def validate_model(
    request: Request, caller: ModelEditor, srv: ServerDep, text: Text = ""
) -> Response:
    found = model_editing.validate(srv, text, caller.name)
    view = srv.live.view
    return render(request, "_model_errors.html", caller, "model", view=view, problems=found)


@router.post(
    "/model/save",
    max_body_size=MODEL_BODY_BYTES,
    form_limits=MODEL_FORM_LIMITS,  # type: ignore[arg-type]
)
def save_model(
    request: Request,
    caller: ModelEditor,
    srv: ServerDep,
    text: Text = "",
    note: Annotated[str, Form(max_length=NOTE_CHARS)] = "",
    based_on: Annotated[int, Form(ge=0, le=MAX_VERSION)] = 0,
) -> Response:
    """Save as the next version; text identical to the version it was based on is not
    saved again, and the answer says so (an information, not a refusal)."""
    same = model_editing.unchanged(srv, text, based_on or None)
    if same is not None:
        return nothing_changed(request, caller, srv, same)
    row, found = model_editing.save(srv, text, caller.name, note.strip())
    view = srv.live.view
    if row is None:
        message = f"Not saved: the model has {len(found)} problem{'' if len(found) == 1 else 's'}."
        if not htmx(request):
            return model_page(request, caller, srv, text, 0, 422, problems=found, error=message)
        headers = {"HX-Retarget": "#model-errors", "HX-Reswap": "outerHTML"}
        return render(
            request,
            "_model_errors.html",
            caller,
            "model",
            view=view,
            status_code=422,
            headers=headers,
            problems=found,
            flash_error=message,
        )
    if not htmx(request):
        saved = f"Saved as version {row.number}; activate it to run it."
        return outcomes.done(request, f"/model?version={row.number}", saved)
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        view=view,
        flash=f"Saved as version {row.number}; activate it to run it.",
        problems=[],
        clear_errors=True,
        editing=row.number,
        editing_oob=True,
        **versions_context(srv),
        busy=srv.live.busy(),
    )


def nothing_changed(request: Request, caller: Caller, srv: Server, same: int) -> Response:
    """The text is that of version `same`: nothing saved, said as a message."""
    message = f"Nothing changed: the text is that of version {same}; no new version was saved."
    if not htmx(request):
        return outcomes.done(request, f"/model?version={same}", message)
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        view=srv.live.view,
        flash=message,
        editing=same,
        **versions_context(srv),
        busy=srv.live.busy(),
    )


@router.get("/model/diff")
def model_diff(
    request: Request,
    caller: ModelEditor,
    srv: ServerDep,
    version: Annotated[int, Query(ge=1, le=MAX_VERSION)],
) -> Response:
    row = model_editing.stored(srv, version)
    active = srv.live.model
    lines = model_editing.diff(
        active.text, row.text, f"version {active.number} (active)", f"version {version}"
    )
    context: dict[str, Any] = {"diff": lines, "diff_version": version, "diff_active": active.number}
    if htmx(request):
        return render(request, "_model_diff.html", caller, "model", view=srv.live.view, **context)
    return model_page(request, caller, srv, active.text, active.number, **context)


@router.post("/model/activate")
async def activate_model(
    request: Request,
    caller: Activator,
    srv: ServerDep,
    version: Annotated[int, Form(ge=1, le=MAX_VERSION)],
    editing: Annotated[int, Form(ge=0, le=MAX_VERSION)] = 0,
) -> Response:
    """Activate; htmx gets the versions, and out of band the heading (which text the editor
    holds, which version runs) and the diff of the version that ran before to the new one."""
    before = srv.live.model
    await model_editing.activate(srv, version, caller.name)
    if not htmx(request):
        return outcomes.done(request, "/model", f"Version {version} is active now.")
    lines = model_editing.diff(
        srv.live.model.text, before.text, f"version {version} (active)", f"version {before.number}"
    )
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        view=srv.live.view,
        flash=f"Version {version} is active now.",
        activated=True,
        editing=editing,
        editing_oob=True,
        diff=lines,
        diff_version=before.number,
        diff_active=version,
        **versions_context(srv),
        busy=srv.live.busy(),
    )


@router.get("/model/fragments/station")
def model_station(request: Request, caller: ModelEditor, live: LiveDep) -> Response:
    view = live.view
    return live_fragment(
        request, "_model_station.html", caller, "model", view=view, busy=live.busy()
    )
