"""Faults nobody wrote down: each device of the demo station drops out for a few seconds at
some moment of each of E1-E9, on top of the experiment's own fault.  Whatever the moment, a
good station waits while the device is silent, goes on when it answers, and finishes.

The moments are spread over the runs deterministically (a grid of every device at many
moments of every experiment found two stations that never finished: robots that took turns
for ever, and a way out that was never planned once a robot answered again; both are fault
scenarios now).  Simulated time: each run takes well under a second.
"""

from __future__ import annotations

import dataclasses

import pytest

from app.station.cycle import ScheduledFault
from app.station.player import Planners, play
from app.station.scenario import load_scenario
from hw.faults import Fault, FaultKind
from planner.model.station import ResourceKind, Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import EventKind
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
EXPERIMENTS = sorted((ROOT / "models" / "scenarios").glob("e[1-9]_*.yaml"))
DEVICES = ("r1", "r2", "r1_tc", "r2_tc", "r1_cam", "r2_cam", "nr")


def dropouts() -> list[tuple[str, str, float, float]]:
    """(experiment, device, from, seconds): every device once per experiment, at moments
    from 2 to 47 s that differ between devices and experiments, 3 or 6 s long."""
    runs = []
    for i, path in enumerate(EXPERIMENTS):
        for j, device in enumerate(DEVICES):
            at = 2.0 + 5 * ((3 * i + 4 * j) % 10)
            runs.append((path.stem, device, at, 3.0 if (i + j) % 2 else 6.0))
    return runs


@pytest.fixture(scope="module")
def demo() -> tuple[Station, Planners]:
    station = load_station(MODEL.read_text(), str(MODEL))
    return station, Planners(TransitionPlanner(station.model), OperationPlanner(station))


def test_the_devices_dropped_out_are_the_stations_devices(demo: tuple[Station, Planners]) -> None:
    station, _ = demo
    devices = {r.name for r in station.resources if r.kind is ResourceKind.DEVICE}
    assert devices == set(DEVICES)


@pytest.mark.parametrize(
    ("experiment", "device", "at", "seconds"), dropouts(), ids=lambda v: str(v)
)
def test_a_device_that_drops_out_for_a_while_never_stops_the_station(
    demo: tuple[Station, Planners], experiment: str, device: str, at: float, seconds: float
) -> None:
    station, planners = demo
    path = ROOT / "models" / "scenarios" / f"{experiment}.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    own = [f for f in scenario.faults if f.fault.kind is FaultKind.DISCONNECT]
    already = any(f.fault.resource == device for f in own)  # E5-E7's own robot
    silent = (
        ScheduledFault(Fault(FaultKind.DISCONNECT, resource=device), at=at),
        ScheduledFault(Fault(FaultKind.RECONNECT, resource=device), at=at + seconds),
    )
    scenario = dataclasses.replace(scenario, faults=(*scenario.faults, *silent), until=400.0)
    events = list(play(station, scenario, planners))
    last = events[-1]
    assert last.kind is EventKind.DONE, (last.subject, last.detail)
    # the dropout was long enough for the station to notice it (else the test tests nothing)
    gone = [e.time for e in events if e.kind is EventKind.UNAVAILABLE and e.subject == device]
    noticed = any(at <= t <= at + seconds + 0.2 for t in gone)
    assert noticed or already or last.time < at + 2.0, gone
