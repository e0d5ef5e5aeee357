"""The model versions through the API: the versions, one with its text, saving a text as a
new version (permission `model`), and activating one (permission `activate`).  What is done
to versions is app.web.model_editing, which the model editor's pages share."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, Path
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field, StringConstraints

from app.store import versions
from app.store.tables import ModelVersion
from app.web import model_editing
from app.web.api.common import BEARER, PREFIX, errors
from app.web.api.schemas import Invalid, Note, ProblemOut, RequestBody
from app.web.deps import Activator, ModelEditor, ServerDep
from app.web.limits import MAX_MODEL_CHARS, MAX_VERSION, MODEL_BODY_BYTES

router = APIRouter(prefix=PREFIX, tags=["models"], dependencies=BEARER)
VersionNumber = Annotated[int, Path(ge=1, le=MAX_VERSION, description="the version's number")]


class ModelVersionOut(BaseModel):
    number: int
    author: str
    created: datetime
    note: str
    sha256: str
    active: bool = Field(description="the version the station runs")


class ModelTextOut(ModelVersionOut):
    text: str


class ModelIn(RequestBody):
    text: Annotated[str, StringConstraints(min_length=1, max_length=MAX_MODEL_CHARS)]
    note: Note = ""
    based_on: int | None = Field(
        default=None,
        ge=1,
        le=MAX_VERSION,
        description="the version the text was edited from (default: the newest one): "
        "identical text is not saved again",
    )


class ModelSaved(BaseModel):
    number: int
    saved: bool = Field(
        default=True, description="false: the text is that of version `number`, nothing saved"
    )
    message: str = ""


class ActivatedOut(BaseModel):
    number: int
    active: bool


def version_out(row: ModelVersion, active_id: int) -> ModelVersionOut:
    return ModelVersionOut(
        number=row.number,
        author=row.author,
        created=datetime.fromtimestamp(row.created_at, UTC),
        note=row.note,
        sha256=row.sha256,
        active=row.id == active_id,
    )


@router.get(
    "/models",
    summary="The saved model versions, newest first",
    responses=errors(401, 403),
)
def list_models(_caller: ModelEditor, srv: ServerDep) -> list[ModelVersionOut]:
    """Needs `model`."""
    active = srv.live.view.model.version_id
    with srv.store.sessions() as session:
        return [version_out(v, active) for v in versions.versions(session, srv.live.name)]


@router.get(
    "/models/{number}",
    summary="One model version with its text",
    responses=errors(401, 403, 404, 422),
)
def get_model(_caller: ModelEditor, srv: ServerDep, number: VersionNumber) -> ModelTextOut:
    """Needs `model`."""
    row = model_editing.stored(srv, number)
    version = version_out(row, srv.live.view.model.version_id)
    return ModelTextOut(**version.model_dump(), text=row.text)


@router.post(
    "/models",
    summary="Save a model text as a new version",
    max_body_size=MODEL_BODY_BYTES,
    status_code=201,
    response_model=ModelSaved,
    responses={
        **errors(400, 401, 403),
        200: {
            "model": ModelSaved,
            "description": "nothing changed: the text is that of the version it was based on",
        },
        422: {
            "model": Invalid,
            "description": "the model is not valid: `problems` lists each at its line and column",
        },
    },
)
def save_model(caller: ModelEditor, srv: ServerDep, body: ModelIn) -> Any:
    """The text is checked as `sp check` would; a valid one becomes the next version (not
    yet active: POST /api/models/{number}/activate).  Text identical to the version it was
    based on is not saved again: 200 with `saved` false and that version's number.  Needs
    `model`."""
    same = model_editing.unchanged(srv, body.text, body.based_on)
    if same is not None:
        message = f"nothing changed: the text is that of version {same}"
        unchanged = ModelSaved(number=same, saved=False, message=message)
        return JSONResponse(unchanged.model_dump(), status_code=200)
    row, problems = model_editing.save(srv, body.text, caller.name, body.note.strip())
    if row is None:
        first = problems[0]
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        invalid = Invalid(
            detail=f"the model is not valid: line {first.line}, column {first.column}: "
            f"{first.message}{more}",
            problems=[
                ProblemOut(line=p.line, column=p.column, message=p.message) for p in problems
            ],
        )
        return JSONResponse(invalid.model_dump(), status_code=422)
    return ModelSaved(number=row.number)


@router.post(
    "/models/{number}/activate",
    summary="Run a saved model version",
    responses=errors(401, 403, 404, 409, 422, 503),
)
async def activate_model(caller: Activator, srv: ServerDep, number: VersionNumber) -> ActivatedOut:
    """Refused (409) while the station runs intentions or operations, unless it is in
    restart mode.  Building the new version's planners can take seconds.  Needs `activate`."""
    await model_editing.activate(srv, number, caller.name)
    return ActivatedOut(number=number, active=True)
