"""The model editor: a version's text in the code editor, validation with located problems,
saving as a new version, the versions with their diff to the active one, and activation
(the heading follows it at once).  Split from app.web.engineer, whose page helpers it uses.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Form, Query, Request
from fastapi.responses import RedirectResponse, Response

from app.store import versions
from app.web import model_editing
from app.web.deps import Caller, server
from app.web.engineer import Activator, ModelEditor, htmx, live_fragment, render

router = APIRouter(include_in_schema=False)


def versions_context(request: Request) -> dict[str, Any]:
    srv = server(request)
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


def busy_context(request: Request) -> dict[str, Any]:
    return {"busy": server(request).live.busy()}


def model_page(
    request: Request,
    caller: Caller,
    text: str,
    shown: str,
    status: int = 200,
    **extra: Any,
) -> Response:
    return render(
        request,
        "model.html",
        caller,
        "model",
        server(request).live.view,
        status=status,
        text=text,
        shown=shown,
        **versions_context(request),
        **busy_context(request),
        **extra,
    )


@router.get("/model")
def model_editor(
    request: Request,
    caller: ModelEditor,
    version: Annotated[int | None, Query(ge=1, le=model_editing.MAX_VERSION)] = None,
) -> Response:
    srv = server(request)
    if version is None:
        text, shown = srv.live.model.text, f"version {srv.live.model.number} (active)"
    else:
        text, shown = model_editing.stored(srv, version).text, f"version {version}"
    return model_page(request, caller, text, shown)


Text = Annotated[str, Form(max_length=model_editing.MAX_MODEL_CHARS)]


@router.post(
    "/model/validate",
    max_body_size=model_editing.MODEL_BODY_BYTES,
    form_limits=model_editing.MODEL_FORM_LIMITS,  # type: ignore[arg-type]
)
def validate_model(request: Request, caller: ModelEditor, text: Text = "") -> Response:
    found = model_editing.problems(text)
    return render(
        request, "_model_errors.html", caller, "model", server(request).live.view, problems=found
    )


@router.post(
    "/model/save",
    max_body_size=model_editing.MODEL_BODY_BYTES,
    form_limits=model_editing.MODEL_FORM_LIMITS,  # type: ignore[arg-type]
)
def save_model(
    request: Request,
    caller: ModelEditor,
    text: Text = "",
    note: Annotated[str, Form(max_length=500)] = "",
) -> Response:
    srv = server(request)
    row, found = model_editing.save(srv, text, caller.name, note.strip())
    view = srv.live.view
    if row is None:
        message = f"Not saved: the model has {len(found)} problem{'' if len(found) == 1 else 's'}."
        if not htmx(request):
            return model_page(
                request, caller, text, "unsaved text", 422, problems=found, error=message
            )
        headers = {"HX-Retarget": "#model-errors", "HX-Reswap": "outerHTML"}
        return render(
            request,
            "_model_errors.html",
            caller,
            "model",
            view,
            status=422,
            headers=headers,
            problems=found,
            flash_error=message,
        )
    if not htmx(request):
        return RedirectResponse(f"/model?version={row.number}", status_code=303)
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        view,
        flash=f"Saved as version {row.number}; activate it to run it.",
        problems=[],
        clear_errors=True,
        **versions_context(request),
        **busy_context(request),
    )


@router.get("/model/diff")
def model_diff(
    request: Request,
    caller: ModelEditor,
    version: Annotated[int, Query(ge=1, le=model_editing.MAX_VERSION)],
) -> Response:
    srv = server(request)
    row = model_editing.stored(srv, version)
    active = srv.live.model
    lines = model_editing.diff(
        active.text, row.text, f"version {active.number} (active)", f"version {version}"
    )
    context: dict[str, Any] = {"diff": lines, "diff_version": version, "diff_active": active.number}
    if htmx(request):
        return render(request, "_model_diff.html", caller, "model", srv.live.view, **context)
    return model_page(request, caller, active.text, f"version {active.number} (active)", **context)


@router.post("/model/activate")
async def activate_model(
    request: Request,
    caller: Activator,
    version: Annotated[int, Form(ge=1, le=model_editing.MAX_VERSION)],
) -> Response:
    srv = server(request)
    await model_editing.activate(srv, version, caller.name)
    if not htmx(request):
        return RedirectResponse("/model", status_code=303)
    return render(
        request,
        "_model_versions.html",
        caller,
        "model",
        srv.live.view,
        flash=f"Version {version} is active now.",
        activated=True,
        **versions_context(request),
        **busy_context(request),
    )


@router.get("/model/fragments/station")
def model_station(request: Request, caller: ModelEditor) -> Response:
    view = server(request).live.view
    context = busy_context(request)
    return live_fragment(request, "_model_station.html", caller, "model", view, **context)
