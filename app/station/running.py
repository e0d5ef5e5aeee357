"""What the station loop owns, and only the loop changes: the station as it runs.

The active model version and its planning worker, the station cycle (runner, devices and
the runner's state), the alarm book, the run tracker, the experiment being played, and the
people's actions waiting for the next round.  Requests (`app.station.requests`) and the
steps after each tick (`app.station.rounds`) change these, always on the loop's thread;
pages read the `StationView` made from them after each round, never these.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from app.history.durations import Durations
from app.station.alarm_grouping import StartUp
from app.station.alarms import AlarmBook, Condition
from app.station.cycle import StationCycle
from app.station.planning_worker import PlanningWorker
from app.station.runs import RunTracker
from app.station.scenario import Scenario
from app.station.view import ActiveModel
from hw.devices import Delays, Devices
from hw.simulated import SimulatedWorld
from planner.model.expressions import Value
from planner.model.station import Station
from planner.runner import Action, Runner, RunnerConfig, RunnerState

# The station's devices for a model, from its start values (the composition root chooses:
# the simulated world, or the drivers of a device file on emulators or real devices).
DeviceSetup = Callable[[Station, Mapping[str, Value]], Devices]


def simulated_devices(station: Station, start: Mapping[str, Value]) -> Devices:
    """The simulated world; a tap on a watch is the person's own (never played by it)."""
    return SimulatedWorld(station, start=start, people_tap=True)


def delays_of(scenario: Scenario) -> Delays:
    """An experiment's delays, as a simulated world takes them."""
    return Delays(scenario.delays, scenario.default_delay)


@dataclass(frozen=True)
class PlanningSetup:
    """How the station's runners plan: in a worker process beside the loop (so that no query
    stalls a round, `app.station.planning_worker`), or inside the tick; `delay` makes every
    query slow on purpose (tests)."""

    in_worker: bool = True
    delay: float = 0.0
    budget: float = 10.0  # seconds a query may take before it is answered over budget

    def worker(self, model: ActiveModel) -> PlanningWorker | None:
        if not self.in_worker:
            return None
        file = f"model version {model.number}"
        return PlanningWorker(model.text, file, model.cache, budget=self.budget, delay=self.delay)


def runner_for(
    model: ActiveModel,
    config: RunnerConfig,
    worker: PlanningWorker | None,
    learned: Mapping[str, float] | None = None,
) -> Runner:
    """A runner for `model` whose planning queries go to `worker` (None: in the tick), and
    that plans with the operations' `learned` durations."""
    runner = Runner(
        model.station,
        model.transition_planner,
        model.operation_planner,
        config,
        time.perf_counter,
        planning=worker,
    )
    runner.learned = dict(learned or {})
    return runner


@dataclass
class Running:
    """The station as the loop runs it (module docstring)."""

    model: ActiveModel
    config: RunnerConfig
    planning: PlanningSetup
    worker: PlanningWorker | None
    cycle: StationCycle
    book: AlarmBook
    runs: RunTracker
    # how long each operation takes here, learned run by run (`app.history.durations`)
    durations: Durations = field(default_factory=Durations)
    experiment: str = ""  # the title of the experiment played last ("" if none)
    # people's actions for the next round's tick: an experiment's intentions, started once
    # the devices had a round to report from their new start
    next_actions: list[Action] = field(default_factory=list)
    # alarm conditions the station's own checks found (a row of its store changed outside
    # it): they hold for the rest of the process, whatever the runner's state
    notices: dict[str, Condition] = field(default_factory=dict)
    startup: StartUp = field(default_factory=StartUp)  # devices not heard since the start

    @property
    def runner(self) -> Runner:
        return self.cycle.runner

    @property
    def state(self) -> RunnerState:
        return self.cycle.state

    @property
    def devices(self) -> Devices:
        return self.cycle.devices

    def runner_with(self, config: RunnerConfig) -> Runner:
        """A runner of the active model with `config`, planning as the station does."""
        return runner_for(self.model, config, self.worker, self.durations.medians())
