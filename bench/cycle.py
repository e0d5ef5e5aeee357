"""Cycle time: the demo's nominal assembly and E1-E9, operations one at a time or in parallel.

    python -m bench.cycle [--output bench/results/cycle.md]

Each scenario is played headless on the simulated world (`sp run --speed 0`'s player), so its
times are simulated seconds and exact: the cycle is the run's length, from its `started` to
its `ended` record.  Beside each cycle: the recovery types seen after the first fault (the
plan levels and flags of the non-routine planning actions, as seed 000 Table 1 writes them),
whether they contain the paper's (the scenario's `expect.recovery`, in order), and the
operator's maintenance steps against the scenario's `expect.operator`.

The modes: *sequential*, one operation at a time (the runner's default today); *parallel*,
operations the operation plan calls independent started at once (`parallel_operations`).
Issue 25 adds a third, parallel with durations learned from the station's history, and
targets nominal <= 52 s and E1-E9 together <= 80 % of their sequential time.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from app.station.player import Planners, play
from app.station.scenario import Scenario, load_scenario
from bench.planning import machine
from bench.runner import revision
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import Event, EventKind

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
MODEL = ROOT / "models" / "demo_station.yaml"
SCENARIOS = ROOT / "models" / "scenarios"
NAMES = ("nominal", *sorted(p.stem for p in SCENARIOS.glob("e[1-9]_*.yaml")))
MODES = ("sequential", "parallel")


@dataclass(frozen=True)
class Cycle:
    scenario: str
    mode: str
    seconds: float | None  # the run's length; None when it did not finish
    outcome: str  # the run's outcome, or what the play ended with
    recovery: tuple[str, ...]  # "TP w/ETO", ... after the first fault
    paper: tuple[str, ...]  # the scenario's expected recovery types
    operator: tuple[str, ...]  # maintenance steps the operator reported done
    expected_operator: tuple[str, ...] | None

    @property
    def recovers_as_the_paper(self) -> bool:
        """Ours begin with the paper's first type and hold all of them in order, as
        tests/planner/runner/test_runner.py checks Table 1."""
        if not self.paper:
            return True
        if not self.recovery or not _matches(self.paper[0], self.recovery[0]):
            return False
        ours = iter(self.recovery)
        return all(any(_matches(p, o) for o in ours) for p in self.paper)


def _label(event: Event) -> str:
    flags = " ".join(f"w/{f}" for f in event.detail.get("flags", ()))
    return f"{event.detail['level']} {flags}".strip()


def _matches(paper: str, ours: str) -> bool:
    level, *flags = paper.replace(" w/", " ").split()
    our_level, *our_flags = ours.replace(" w/", " ").split()
    return level == our_level and set(flags) <= set(our_flags)


def with_mode(scenario: Scenario, mode: str) -> Scenario:
    return replace(
        scenario, config=replace(scenario.config, parallel_operations=mode != "sequential")
    )


def cycle_of(name: str, mode: str, events: Sequence[Event], scenario: Scenario) -> Cycle:
    runs = [e for e in events if e.kind is EventKind.RUN]
    started = next((e.time for e in runs if e.subject == "started"), None)
    ended = next((e for e in runs if e.subject == "ended"), None)
    finished = ended is not None and ended.detail.get("outcome") == "finished"
    seconds = ended.time - started if finished and ended and started is not None else None
    outcome = (
        str(ended.detail.get("outcome")) if ended else f"{events[-1].kind}: {events[-1].subject}"
    )
    faults = [k for k, e in enumerate(events) if e.kind is EventKind.FAULT]
    recovery: list[str] = []
    if faults:
        routine = ("goals", "intentions")
        recovery = [
            _label(e)
            for e in events[faults[0] :]
            if e.kind is EventKind.PLAN and e.detail["reason"] not in routine
        ]
    expect: dict[str, Any] = dict(scenario.expect)
    operator = tuple(
        str(e.detail["transition"])
        for e in events
        if e.kind is EventKind.OPERATOR and e.subject == "maintenance done"
    )
    expected = expect.get("operator")
    return Cycle(
        name,
        mode,
        seconds,
        outcome,
        tuple(recovery),
        tuple(expect.get("recovery", ())),
        operator,
        tuple(expected) if expected is not None else None,
    )


def measure(names: Sequence[str] = NAMES, modes: Sequence[str] = MODES) -> list[Cycle]:
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    return [_play(station, planners, name, mode) for name in names for mode in modes]


def _play(station: Station, planners: Planners, name: str, mode: str) -> Cycle:
    path = SCENARIOS / f"{name}.yaml"
    scenario = with_mode(load_scenario(path.read_text(), str(path), station), mode)
    events = list(play(station, scenario, planners))
    return cycle_of(name, mode, events, scenario)


def _seconds(cycle: Cycle) -> str:
    return "did not finish" if cycle.seconds is None else f"{cycle.seconds:.1f}"


def report(cycles: Sequence[Cycle]) -> str:
    modes = list(dict.fromkeys(c.mode for c in cycles))
    by = {(c.scenario, c.mode): c for c in cycles}
    names = list(dict.fromkeys(c.scenario for c in cycles))
    lines = [
        f"# Cycle time\n\n`python -m bench.cycle`, {time.strftime('%Y-%m-%d')}, {revision()}. "
        f"Machine: {machine()} (simulated seconds: the machine does not change them)",
        "",
        "| scenario | " + " | ".join(f"{m} s" for m in modes) + " | "
        + " | ".join(f"recovery, {m}" for m in modes) + " | operator's work as expected |",
        "| --- | " + " | ".join(["---"] * (2 * len(modes))) + " | --- |",
    ]  # fmt: skip
    for name in names:
        row = [by[(name, m)] for m in modes]
        seconds = [_seconds(c) for c in row]
        recovery = [
            ("—" if not c.recovery else ", ".join(c.recovery))
            + ("" if not c.paper or c.recovers_as_the_paper else " (**not the paper's**)")
            for c in row
        ]
        operator = [
            m for m, c in zip(modes, row, strict=True)
            if c.expected_operator is not None and c.operator != c.expected_operator
        ]  # fmt: skip
        said = "yes" if not operator else "**no** in " + ", ".join(operator)
        lines.append(
            f"| {name} | " + " | ".join(seconds) + " | " + " | ".join(recovery) + f" | {said} |"
        )
    experiments = [n for n in names if n != "nominal"]
    lines.append("")
    for mode in modes:
        total = [by[(n, mode)].seconds for n in experiments]
        if experiments and all(t is not None for t in total):
            lines.append(f"E1-E9 together, {mode}: {sum(t for t in total if t is not None):.1f} s.")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--output", type=Path, default=RESULTS / "cycle.md", help="%(default)s")
    args = parser.parse_args()
    text = report(measure())
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)


if __name__ == "__main__":
    main()
