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
    shown: str,
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
        shown=shown,
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
        text, shown = srv.live.model.text, f"version {srv.live.model.number} (active)"
    else:
        text, shown = model_editing.stored(srv, version).text, f"version {version}"
    return model_page(request, caller, srv, text, shown)


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
) -> Response:
    row, found = model_editing.save(srv, text, caller.name, note.strip())
    view = srv.live.view
    if row is None:
        message = f"Not saved: the model has {len(found)} problem{'' if len(found) == 1 else 's'}."
        if not htmx(request):
            return model_page(
                request, caller, srv, text, "unsaved text", 422, problems=found, error=message
            )
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
    shown = f"version {active.number} (active)"
    return model_page(request, caller, srv, active.text, shown, **context)


@router.post("/model/activate")
async def activate_model(
    request: Request,
    caller: Activator,
    srv: ServerDep,
    version: Annotated[int, Form(ge=1, le=MAX_VERSION)],
) -> Response:
    await model_editing.activate(srv, version, caller.name)
    if not htmx(request):
        return outcomes.done(request, "/model", f"Version {version} is active now.")
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        view=srv.live.view,
        flash=f"Version {version} is active now.",
        activated=True,
        **versions_context(srv),
        busy=srv.live.busy(),
    )


@router.get("/model/fragments/station")
def model_station(request: Request, caller: ModelEditor, live: LiveDep) -> Response:
    view = live.view
    return live_fragment(
        request, "_model_station.html", caller, "model", view=view, busy=live.busy()
    )
