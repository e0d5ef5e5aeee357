"""The papers' experiments E1-E9 and the fault scenarios through the API, on a simulated
station: which it can play, and playing one, hands-free if asked (permission `simulate`; 404
on a station with real devices)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Path, Query
from pydantic import BaseModel, Field

from app.station.experiments import group_of
from app.web.actions import answer, known
from app.web.api.common import ACT, BEARER, PREFIX, errors
from app.web.deps import ServerDep, Simulator
from app.web.limits import EXPERIMENT_CHARS
from app.web.server import Server

router = APIRouter(prefix=PREFIX, tags=["simulation"], dependencies=BEARER)


class ExperimentOut(BaseModel):
    """An experiment (E1-E9, a fault scenario, a device play), playable on a simulated
    station."""

    id: str
    title: str
    description: str
    intentions: list[str] = Field(description="the intentions it starts")
    group: str = Field(description='"" for E1-E9, "faults" or "devices"')


class ExperimentStarted(BaseModel):
    id: str
    title: str
    hands_free: bool


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
            group=group_of(scenario),
        )
        for key, (title, scenario) in _simulated(srv).experiments.items()
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
    hands_free: Annotated[
        bool, Query(description="the station plays the scenario's operator too")
    ] = False,
) -> ExperimentStarted:
    """The experiment's faults are armed and its intentions started; its operator steps
    appear as task cards (hands-free: the station answers them as the scenario's operator
    would, in the name of "simulated operator").  Needs `simulate`."""
    _simulated(srv)
    key = known(experiment, sorted(srv.experiments), "experiment")
    title, scenario = srv.experiments[key]
    await answer(srv.live.play_experiment(scenario, title, caller.name, hands_free))
    return ExperimentStarted(id=key, title=title, hands_free=hands_free)
