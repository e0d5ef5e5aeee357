"""Cycle time: the demo's nominal assembly and E1-E9, operations one at a time or in parallel.

    python -m bench.cycle [--output bench/results/cycle.md]
    python -m bench.cycle --devices models/demo_station.devices.yaml [--only NAME,...]

Each scenario is played headless on the simulated world (`sp run --speed 0`'s player), so its
times are simulated seconds and exact: the cycle is the run's length, from its `started` to
its `ended` record.  Beside each cycle: the recovery types seen after the first fault (the
plan levels and flags of the non-routine planning actions, as seed 000 Table 1 writes them),
whether they contain the paper's (the scenario's `expect.recovery`, in order), and the
operator's maintenance steps against the scenario's `expect.operator`.

The modes: *sequential*, one operation at a time (`sp run --sequential`, the old default);
*parallel*, operations the operation plan calls independent started at once (the runner's
default); *learned*, parallel, and among operation plans of the minimal length the one of
the least expected makespan, each operation's duration learned from the station's history:
here the parallel plays of all the scenarios above, as a station that ran each once
(`app.history.durations`: the median of an operation's last five times).  Issue 25's
targets: nominal <= 52 s and E1-E9 together <= 80 % of their sequential time.

With `--devices FILE` the scenarios (`--only`, by default E2 and E6) are played as
`sp run --devices` plays them: on the device file's emulators, through the real `ur_rtde`
and Modbus clients, in real time, sequential and parallel; the seconds are then wall-clock
seconds and vary a little from run to run (`bench/results/cycle_devices.md`).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from app.history.durations import learned
from app.station import recovery_types
from app.station.player import Planners, play
from app.station.scenario import Scenario, load_scenario
from bench.planning import machine
from bench.runner import revision
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import Event, EventKind, OperationState

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
MODEL = ROOT / "models" / "demo_station.yaml"
SCENARIOS = ROOT / "models" / "scenarios"
NAMES = ("nominal", *sorted(p.stem for p in SCENARIOS.glob("e[1-9]_*.yaml")))
MODES = ("sequential", "parallel", "learned")


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
    at_once: int = 0  # the most operations executing at the same time

    @property
    def recovers_as_the_paper(self) -> bool:
        return recovery_types.as_the_paper(self.paper, self.recovery)


def with_mode(scenario: Scenario, mode: str) -> Scenario:
    return replace(scenario, config=replace(scenario.config, sequential=mode == "sequential"))


def cycle_of(name: str, mode: str, events: Sequence[Event], scenario: Scenario) -> Cycle:
    runs = [e for e in events if e.kind is EventKind.RUN]
    started = next((e.time for e in runs if e.subject == "started"), None)
    ended = next((e for e in runs if e.subject == "ended"), None)
    finished = ended is not None and ended.detail.get("outcome") == "finished"
    seconds = ended.time - started if finished and ended and started is not None else None
    outcome = (
        str(ended.detail.get("outcome")) if ended else f"{events[-1].kind}: {events[-1].subject}"
    )
    recovery = [recovery_types.label(e) for e in recovery_types.recovery(events)]
    expect: dict[str, Any] = dict(scenario.expect)
    operator = tuple(recovery_types.operator_work(events))
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
        most_at_once(events),
    )


def most_at_once(events: Sequence[Event]) -> int:
    """The most operations that were executing at the same time in the play."""
    executing: set[str] = set()
    most = 0
    for e in events:
        if e.kind is EventKind.OPERATION:
            if e.detail.get("after") == OperationState.EXECUTING:
                executing.add(e.subject)
            else:
                executing.discard(e.subject)
            most = max(most, len(executing))
    return most


def measure(names: Sequence[str] = NAMES, modes: Sequence[str] = MODES) -> list[Cycle]:
    """Each scenario in each mode; *learned* plays with what the *parallel* plays taught."""
    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    played: dict[tuple[str, str], list[Event]] = {}
    for mode in ("sequential", "parallel"):
        for name in names:
            if mode in modes or ("learned" in modes and mode == "parallel"):
                played[(name, mode)] = _play(station, planners, name, mode)
    history = [e for name in names for e in played[(name, "parallel")]] if played else []
    if "learned" in modes:
        durations = learned(history)
        for name in names:
            played[(name, "learned")] = _play(station, planners, name, "learned", durations)
    return [
        cycle_of(name, mode, played[(name, mode)], _scenario(station, name))
        for name in names
        for mode in modes
    ]


def measure_on_devices(
    device_path: str, names: Sequence[str], modes: Sequence[str] = ("sequential", "parallel")
) -> list[Cycle]:
    """Each scenario in each mode on emulated devices, in real time (`sp run --devices`)."""
    from app.station.emulated import emulate, read_device_file, start_values
    from app.station.scenario import person_delay_of

    station = load_station(MODEL.read_text(), str(MODEL))
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    planners.transition.prepare()
    devices = read_device_file(device_path, station)
    cycles = []
    for name in names:
        for mode in modes:
            scenario = with_mode(_scenario(station, name), mode)
            start = start_values(station, scenario.start)
            answer = person_delay_of(scenario, station)
            with emulate(station, devices, start, answer_after=answer) as emulated:
                silent = emulated.devices.wait_until_ready(30.0)
                if silent:
                    raise SystemExit(f"{device_path}: no answer from {', '.join(silent)}")
                events = list(
                    play(
                        station,
                        scenario,
                        planners,
                        devices=emulated.devices,
                        clock=time.monotonic,
                    )
                )
            cycles.append(cycle_of(name, mode, events, _scenario(station, name)))
            print(f"{name} {mode}: {_seconds(cycles[-1])} s", flush=True)
    return cycles


def _scenario(station: Station, name: str) -> Scenario:
    path = SCENARIOS / f"{name}.yaml"
    return load_scenario(path.read_text(), str(path), station)


def _play(
    station: Station,
    planners: Planners,
    name: str,
    mode: str,
    durations: Mapping[str, float] | None = None,
) -> list[Event]:
    scenario = with_mode(_scenario(station, name), mode)
    return list(play(station, scenario, planners, learned=durations))


def _seconds(cycle: Cycle) -> str:
    return "did not finish" if cycle.seconds is None else f"{cycle.seconds:.1f}"


def report(cycles: Sequence[Cycle], on: str = "") -> str:
    modes = list(dict.fromkeys(c.mode for c in cycles))
    by = {(c.scenario, c.mode): c for c in cycles}
    names = list(dict.fromkeys(c.scenario for c in cycles))
    lines = [
        f"# Cycle time\n\n`python -m bench.cycle`, {time.strftime('%Y-%m-%d')}, {revision()}. "
        f"Machine: {machine()} "
        + (
            f"(on the {on}: wall-clock seconds)"
            if on
            else "(simulated seconds: the machine does not change them)"
        ),
        "",
        "| scenario | " + " | ".join(f"{m} s" for m in modes) + " | "
        + " | ".join(f"recovery, {m}" for m in modes) + " | operator's work as expected | "
        + " | ".join(f"most at once, {m}" for m in modes) + " |",
        "| --- | " + " | ".join(["---"] * (3 * len(modes))) + " | --- |",
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
        at_once = " | ".join(str(c.at_once) for c in row)
        lines.append(
            f"| {name} | " + " | ".join(seconds) + " | " + " | ".join(recovery) + f" | {said} | "
            + at_once + " |"
        )  # fmt: skip
    experiments = [n for n in names if n != "nominal"]
    lines.append("")
    for mode in modes:
        total = [by[(n, mode)].seconds for n in experiments]
        if experiments and all(t is not None for t in total):
            together = sum(t for t in total if t is not None)
            lines.append(
                f"{', '.join(experiments) if on else 'E1-E9'} together, {mode}: {together:.1f} s."
            )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--output", type=Path, help="bench/results/cycle.md (or cycle_devices.md)")
    parser.add_argument("--devices", help="a device file: play on its emulators, in real time")
    parser.add_argument(
        "--only", help="scenarios, comma-separated (default: all; E2, E6 on devices)"
    )
    args = parser.parse_args()
    only = tuple(args.only.split(",")) if args.only else None
    if args.devices:
        names = only or ("e2_oil_filter_early", "e6_r2_disconnects_above_engine")
        text = report(measure_on_devices(args.devices, names), on=f"devices of {args.devices}")
        output = args.output or RESULTS / "cycle_devices.md"
    else:
        text = report(measure(only or NAMES))
        output = args.output or RESULTS / "cycle.md"
    print(text)
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(text)


if __name__ == "__main__":
    main()
