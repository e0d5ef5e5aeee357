"""The papers' experiments E1-E9 through the API, on a simulated station: which it can play,
and playing one (permission `simulate`; 404 on a station with real devices)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Path
from pydantic import BaseModel, Field

from app.web.actions import answer, known
from app.web.api.common import ACT, BEARER, PREFIX, errors
from app.web.deps import ServerDep, Simulator
from app.web.limits import EXPERIMENT_CHARS
from app.web.server import Server

router = APIRouter(prefix=PREFIX, tags=["simulation"], dependencies=BEARER)


class ExperimentOut(BaseModel):
    """One of the papers' experiments E1-E9, playable on a simulated station."""

    id: str
    title: str
    description: str
    intentions: list[str] = Field(description="the intentions it starts")


class ExperimentStarted(BaseModel):
    id: str
    title: str


def _simulated(srv: Server) -> Server:
    if not srv.live.simulated:
        raise HTTPException(404, "this station runs real devices: there are no experiments")
    return srv


@router.get(
    "/experiments",
    summary="The experiments a simulated station can play",
    responses=errors(401, 403, 404),
)
def list_experiments(_caller: Simulator, srv: ServerDep) -> list[ExperimentOut]:
    """404 on a station with real devices.  Needs `simulate`."""
    return [
        ExperimentOut(
            id=key,
            title=title,
            description=scenario.description,
            intentions=list(scenario.started),
        )
        for key, (title, scenario) in sorted(_simulated(srv).experiments.items())
    ]


@router.post(
    "/experiments/{experiment}/play",
    summary="Reset the simulated station to an experiment's start and play it",
    responses=ACT,
)
async def play_experiment(
    caller: Simulator,
    srv: ServerDep,
    experiment: Annotated[
        str, Path(min_length=1, max_length=EXPERIMENT_CHARS, description="its id")
    ],
) -> ExperimentStarted:
    """The experiment's faults are armed and its intentions started; its operator steps
    appear as task cards.  Needs `simulate`."""
    _simulated(srv)
    key = known(experiment, sorted(srv.experiments), "experiment")
    title, scenario = srv.experiments[key]
    await answer(srv.live.play_experiment(scenario, title, caller.name))
    return ExperimentStarted(id=key, title=title)
