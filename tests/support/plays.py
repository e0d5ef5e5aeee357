"""The demo's scenarios, each played once per test process for every module that reads them.

A play is deterministic (tests/planner/runner/test_runner.py replays one and compares), so
the modules that check E1-E9, the fault scenarios and the runner's life cycles read the same
events instead of playing each scenario again.  Nothing here may be changed by a test: the
lists are shared.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

from app.station.alarm_grouping import StartUp, rationalise
from app.station.alarms import AlarmBook, conditions
from app.station.cycle import StationCycle
from app.station.player import Planners, play
from app.station.scenario import Scenario, load_scenario
from hw.simulated import SimulatedWorld
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import Action, Event, EventKind, Reject, Runner, RunnerState
from planner.words import Wording
from tests.support.paths import REPOSITORY

MODEL = REPOSITORY / "models" / "demo_station.yaml"
SCENARIOS = REPOSITORY / "models" / "scenarios"


@dataclass(frozen=True)
class Played:
    scenario: Scenario
    events: list[Event]
    states: list[RunnerState] | None  # after each tick, when asked for
    # the root alarms the play raised, in the order they were first raised (a key raised
    # again counts once: a robot arriving late seven times is one fault), as the live
    # station's alarm book would (`app.station.alarm_grouping`, start-up included)
    alarms: list[str]


@functools.cache
def demo() -> tuple[Station, Planners]:
    """The demo station and one pair of planners for every play of this process."""
    station = load_station(MODEL.read_text(), str(MODEL))
    return station, Planners(TransitionPlanner(station.model), OperationPlanner(station))


_PLAYED: dict[str, Played] = {}


def scenario_path(name: str) -> Path:
    """`name` is a scenario's stem in models/scenarios/ or in models/scenarios/faults/."""
    for folder in (SCENARIOS, SCENARIOS / "faults"):
        if (folder / f"{name}.yaml").exists():
            return folder / f"{name}.yaml"
    raise KeyError(f"no scenario {name!r}")


def played(name: str, *, states: bool = False) -> Played:
    """The scenario's play, with the runner's state after each tick if `states` (kept only
    when asked for: a long fault scenario has thousands of ticks)."""
    known = _PLAYED.get(name)
    if known is None or (states and known.states is None):
        known = _PLAYED[name] = _play(name, states)
    return known


def _play(name: str, states: bool) -> Played:
    station, planners = demo()
    path = scenario_path(name)
    scenario = load_scenario(path.read_text(), str(path), station)
    seen: list[RunnerState] = []
    alarms = RootAlarms(Runner(station, planners.transition, planners.operation, scenario.config))

    def watch(state: RunnerState) -> None:
        alarms(state)
        if states:
            seen.append(state)

    events = list(play(station, scenario, planners, watch=watch))
    return Played(scenario, events, seen if states else None, alarms.raised)


class RootAlarms:
    """The alarm book of a play, tick by tick (0.1 s each, the player's clock)."""

    def __init__(self, runner: Runner) -> None:
        self.runner, self.words = runner, Wording(runner.station)  # once: it reads the model
        self.book, self.startup, self.ticks = AlarmBook(), StartUp(), 0
        self.raised: list[str] = []

    def __call__(self, state: RunnerState) -> None:
        now = round(self.ticks * 0.1, 6)
        self.ticks += 1
        found = conditions(self.runner, state, self.words)
        found = rationalise(found, self.book.active(), self.startup.quiet(state, now))
        self.raised += [c.key for c in self.book.update(found, now) if c.before is None]


def declined_e2() -> tuple[StationCycle, float]:
    """E2 with the operator's "I cannot do this" on the filter removal: the cycle when the
    plan offered instead first asks for an approval, and the time."""
    station, planners = demo()
    path = scenario_path("reject_oil_filter_removal")
    scenario = load_scenario(path.read_text(), str(path), station)
    runner = Runner(station, planners.transition, planners.operation, scenario.config)
    world = SimulatedWorld(
        station, delays=scenario.delays, default_delay=scenario.default_delay, start=scenario.start
    )
    start = runner.initial(0.0, scenario.start)
    cycle = StationCycle(runner, world, start, list(scenario.faults))
    now = 0.0
    while now < 60:
        actions: list[Action] = []
        for event in cycle.step(now).events:
            if event.kind is EventKind.INSTRUCTION and event.detail.get("recovery"):
                actions.append(Reject(user="ann", step=int(event.detail["step"])))
            if event.kind is EventKind.APPROVAL:
                return cycle, now
        now = round(now + 0.1, 6)
        if actions:
            cycle.step(now, actions)
            now = round(now + 0.1, 6)
    raise AssertionError("no approval was asked")
