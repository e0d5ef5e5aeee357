"""The headless station loop that plays a scenario (`sp run`, the tests, E1-E9).

`play` runs the runner against the simulated world on a virtual clock (or against emulated
devices in real time) and yields every event as it happens; the simulated operator answers
approvals and maintenance steps as the scenario says.  Each round is one station cycle
(`app.station.cycle`), the round the web station's loop runs too.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass

from app.station.cycle import StationCycle
from app.station.runs import RunTracker
from app.station.scenario import Scenario
from app.station.stand_in import StandIn
from hw.devices import Devices
from hw.simulated import SimulatedWorld
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.runner import (
    Event,
    EventKind,
    IntentionState,
    QueryObserver,
    Runner,
    RunnerState,
)
from planner.runner.answers import Delayed
from planner.runner.waiting import waiting_for
from planner.words import Wording


@dataclass
class Planners:
    transition: TransitionPlanner
    operation: OperationPlanner


def play(
    station: Station,
    scenario: Scenario,
    planners: Planners,
    *,
    step: float = 0.1,
    speed: float = 0.0,
    stopwatch: Callable[[], float] | None = None,
    sleep: Callable[[float], None] = time.sleep,
    watch: Callable[[RunnerState], None] | None = None,
    observer: QueryObserver | None = None,
    devices: Devices | None = None,
    clock: Callable[[], float] | None = None,
    learned: Mapping[str, float] | None = None,
) -> Iterator[Event]:
    """Run the scenario; yields events. `speed` 0 runs as fast as possible, 1 in real time.

    By default the station runs on its simulated world on a virtual clock.  With `devices`
    (emulated devices, `app.station.emulated`) it runs in real time on `clock`: a round
    every `step` seconds, the scenario's times counted from the first round.  `watch` sees
    the runner's state after every tick (for tests and monitors); `observer` sees every
    planning query (for benchmarks).  `learned`: how long each operation takes, as a
    station learns it from its runs (`app.history.durations`).  The play is done when the
    run of the scenario's intentions ended with every one of them finished
    (`app.station.runs`), and stops at the scenario's time limit otherwise, saying what the
    station waits for.
    """
    rounds = _Rounds(step, speed, sleep, clock)
    cycle = _cycle(station, scenario, planners, rounds, stopwatch, observer, devices)
    cycle.runner.learned = dict(learned or {})
    runs = RunTracker(Wording(station))
    while (now := rounds.now()) <= scenario.until:
        result = cycle.step(now)
        if watch is not None:
            watch(cycle.state)
        yield from runs.around(now, cycle.state, result.events, ())
        if not runs.open and _all_finished(cycle.state, scenario):
            yield Event(now, EventKind.DONE, "all intentions finished")
            return
        rounds.next()
    yield from runs.stop(rounds.now(), "time limit")
    waiting = [w.as_json() for w in waiting_for(cycle.runner, cycle.state)]
    yield Event(
        rounds.now(),
        EventKind.STOPPED,
        "time limit",
        {"until": scenario.until, "waiting_for": waiting},
    )


def _cycle(
    station: Station,
    scenario: Scenario,
    planners: Planners,
    rounds: _Rounds,
    stopwatch: Callable[[], float] | None,
    observer: QueryObserver | None,
    devices: Devices | None,
) -> StationCycle:
    """The scenario's runner on its devices (by default its simulated world), at its start
    and with its faults armed; its planning made slow as the scenario says."""
    runner = Runner(
        station, planners.transition, planners.operation, scenario.config, stopwatch, observer
    )
    if devices is None:
        devices = SimulatedWorld(
            station,
            delays=scenario.delays,
            default_delay=scenario.default_delay,
            start=scenario.start,
        )
    if scenario.planning_delay > 0:
        budget = scenario.planning_budget
        runner.planning = Delayed(runner.planning, scenario.planning_delay, budget, rounds.now)
    start = runner.initial(0.0, scenario.start)
    # the world (or the emulated watches) taps the cards; the stand-in answers the rest
    stand_in = StandIn(scenario, station)
    faults, people = list(scenario.faults), list(scenario.actions)
    return StationCycle(runner, devices, start, faults, people, stand_in)


class _Rounds:
    """The player's clock: virtual (a round every `step`, slept `step / speed` when `speed`
    is set), or real (`clock`, rounds every `step` seconds, late rounds not made up)."""

    def __init__(
        self,
        step: float,
        speed: float,
        sleep: Callable[[float], None],
        clock: Callable[[], float] | None,
    ) -> None:
        self.step, self.speed, self.sleep, self.clock = step, speed, sleep, clock
        self.virtual = 0.0
        self.started = clock() if clock is not None else 0.0
        self.due = self.started

    def now(self) -> float:
        if self.clock is None:
            return self.virtual
        return round(self.clock() - self.started, 3)

    def next(self) -> None:
        if self.clock is None:
            self.virtual = round(self.virtual + self.step, 6)
            if self.speed > 0:
                self.sleep(self.step / self.speed)
            return
        self.due = max(self.due + self.step, self.clock())
        self.sleep(max(0.0, self.due - self.clock()))


def _all_finished(state: RunnerState, scenario: Scenario) -> bool:
    """Every intention of the scenario finished: those that start by themselves and those
    its people start."""
    names = scenario.started if scenario.intentions is not None else tuple(state.intentions)
    return bool(names) and all(state.intentions[n] == IntentionState.FINISHED for n in names)
