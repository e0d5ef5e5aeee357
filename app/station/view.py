"""What the station loop shows the pages: the active model version and a view of a round.

`StationView` is replaced as a whole after every round and never changed in place, so a
page reads one consistent round however long it takes to render.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from app.station import model_cache, supervisor_cache
from app.station.alarms import Alarm
from app.store.tables import ModelVersion
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.runner import Event, Runner, RunnerState
from planner.words import Wording


@dataclass(frozen=True)
class ActiveModel:
    """A model version made ready to run: parsed, its supervisor synthesised."""

    version_id: int
    number: int
    text: str
    station: Station
    transition_planner: TransitionPlanner
    operation_planner: OperationPlanner
    cache: Path | None = None  # where its supervisor is saved (a planning worker loads it)
    # what pages call each of its names, computed once per version (planner.words)
    words: Wording = field(init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "words", Wording(self.station))


@dataclass(frozen=True)
class StationView:
    """What pages read: replaced as a whole after every round, never changed in place."""

    serial: int  # the views made before it: a page tells an old view from a new one
    now: float
    model: ActiveModel
    runner: Runner
    state: RunnerState
    alarms: tuple[Alarm, ...]
    events: tuple[Event, ...]  # the most recent, oldest first
    simulated: bool
    armed_faults: tuple[str, ...] = ()
    experiment: str = ""
    devices: tuple[DeviceLink, ...] = ()


@dataclass(frozen=True)
class DeviceLink:
    """How a device's connection was doing when the view was made (hw.link.LinkStatus)."""

    name: str
    connected: bool
    latency_ms: float | None
    data_age: float | None  # seconds since its last good data
    restarts: int
    error: str


def build_model(version: ModelVersion, cache: Path | None) -> ActiveModel:
    """Parse a stored version and build its planners (seconds, unless the supervisor is cached)."""
    station = model_cache.load(version.text, f"model version {version.number}", cache)
    planner = supervisor_cache.planner(station.model, version.text, "bdd", cache)
    planner.prepare()  # here, beside the loop, rather than in its first tick's plan
    supervisor_cache.remember_order(planner, version.text, cache)
    operations = OperationPlanner(station)
    return ActiveModel(
        version.id, version.number, version.text, station, planner, operations, cache
    )
