"""Runner benchmark: recovery planning in E1-E9 against seed 000, every planning query the
runner makes per scenario, and tick time versus size.

    python -m bench.runner [--runs 5] [--only e3 e7] [--sizes 100 1000 3000 10000] [--quick]
    python -m bench.runner --recovery-only [--recovery-runs 3] [--play-limit 120] [--only reject]

Part 1 plays the nine Table 1 scenarios on the demo station `--runs` times and times each
planning action the paper lists (matched in order among our non-routine planning actions
after the first fault), against the paper's nuXmv times and the issue's 20 ms target.
It then plays E1-E9 and the scenarios of models/scenarios/faults (operators who reject recovery
steps, double faults, faults that never clear) `--recovery-runs` times each, every play an
`sp run --speed 0 --json` in a child process killed after `--play-limit` wall seconds, and
times every planning query the runner makes (its plan events, and the queries it makes
without one): per scenario their count, median and max, the slowest, how the play ended,
and issue 11's target for recovery queries (median under 50 ms, max under 500 ms).
`--recovery-only` runs only these plays.

Part 2 drives the runner against the simulated world on the demo station (the nominal
assembly) and on generated models of ~100 ... 10,000 transitions (bench/cells.py), timing
`Runner.tick` alone: idle ticks, ticks of a running station that emit no plan, and ticks that
replan.  Building the transition planner (supervisor synthesis included) is timed
separately on growing models, stage by stage, each in a child process killed after
`--synthesis-limit` seconds.

Prints Markdown and writes it to bench/results/runner.md.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import io
import itertools
import json
import math
import pstats
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any
from unittest import mock

from app.station import recovery_types
from bench import cells, process
from bench.planning import machine
from planner.runner import Event

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
DEMO = ROOT / "models" / "demo_station.yaml"
SCENARIOS = ROOT / "models" / "scenarios"

# seed 000 Table 1: the planning actions of each experiment and nuXmv's times (ms, a laptop)
PAPER_MS: dict[str, list[tuple[str, float]]] = {
    "e1": [("OP", 223)],
    "e2": [("TP w/MT", 181)],
    "e3": [("TP w/ETO", 787), ("OP w/DO", 245)],
    "e4": [("TP w/ETO", 747), ("OP w/DO", 498), ("TP w/MT", 579)],
    "e5": [("TP w/RTO", 926), ("OP w/DO", 661)],
    "e6": [("TP w/RTO", 1071), ("OP w/DO", 512), ("TP w/MT", 632)],
    "e7": [("TP w/RTO", 855), ("OP w/DO", 637), ("TP w/MT", 1343)],
    "e8": [("TP", 642)],
    "e9": [("TP", 895)],
}
RECOVERY_TARGET_MS = 20.0  # the issue: every recovery planning action
DEMO_TICK_TARGET_MS = 1.0  # the issue: a tick without replanning on the demo station
LARGE_TICK_TARGET_MS = 10.0  # ... and at 10,000 transitions


# ---- part 1: E1-E9 ---------------------------------------------------------------------------


def recovery(events: Sequence[Event]) -> list[Event]:
    """Planning actions that recovered from the first fault (app.station.recovery_types)."""
    return [e for e in recovery_types.recovery(events) if isinstance(e, Event)]


def matches(paper: str, event: Event) -> bool:
    return recovery_types.matches(paper, recovery_types.label(event))


def match_paper(paper: Sequence[str], ours: Sequence[Event]) -> list[int | None]:
    """For each paper action in order, the index of the first matching event after the last."""
    out: list[int | None] = []
    at = 0
    for action in paper:
        found = next((k for k, e in enumerate(ours) if k >= at and matches(action, e)), None)
        out.append(found)
        if found is not None:
            at = found + 1
    return out


@dataclass
class Experiment:
    name: str
    paper: list[tuple[str, float]]
    finished: list[bool] = field(default_factory=list)
    # per paper action: our times over the runs, and what it matched (label, reason, status)
    times: list[list[float]] = field(default_factory=list)
    matched: list[str] = field(default_factory=list)
    # all our recovery planning actions, from the last run, and their total per run
    ours: list[str] = field(default_factory=list)
    totals: list[float] = field(default_factory=list)
    problem: str = ""


def describe(event: Event) -> str:
    return f"{event.subject} ({event.detail['reason']}, {event.detail['status']})"


def run_experiment(station: Any, planners: Any, path: Path, runs: int) -> Experiment:
    from app.station.player import play
    from app.station.scenario import load_scenario

    key = path.name.split("_")[0]
    scenario = load_scenario(path.read_text(), str(path), station)
    expected = list(scenario.expect.get("recovery", []))
    result = Experiment(path.stem, PAPER_MS.get(key, [(a, math.nan) for a in expected]))
    if [a for a, _ in result.paper] != expected:
        result.problem = f"scenario expects {expected}, the paper table {result.paper}"
    result.times = [[] for _ in result.paper]
    result.matched = ["" for _ in result.paper]
    for _ in range(runs):
        events = list(play(station, scenario, planners, stopwatch=time.perf_counter))
        result.finished.append(events[-1].kind == "done")
        ours = recovery(events)
        for k, found in enumerate(match_paper([a for a, _ in result.paper], ours)):
            if found is not None:
                result.times[k].append(ours[found].millis or 0.0)
                result.matched[k] = describe(ours[found])
        result.ours = [f"{describe(e)} {e.millis or 0.0:.1f}" for e in ours]
        result.totals.append(sum(e.millis or 0.0 for e in ours))
    return result


def experiments_table(rows: list[Experiment]) -> str:
    out = [
        "| experiment | paper action | our planning action | paper ms (nuXmv) "
        "| our median ms | our max ms | paper / ours | under 20 ms |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        for (action, paper_ms), times, matched in zip(
            row.paper, row.times, row.matched, strict=True
        ):
            if not times:
                out.append(
                    f"| {row.name} | {action} | **not found** | {paper_ms:,.0f} | | | | **no** |"
                )
                continue
            median = statistics.median(times)
            under = "yes" if median < RECOVERY_TARGET_MS else "**no**"
            out.append(
                f"| {row.name} | {action} | {matched} | {paper_ms:,.0f} | {median:.1f} "
                f"| {max(times):.1f} | {paper_ms / median:,.0f}x | {under} |"
            )
    return "\n".join(out) + "\n"


def taken_table(rows: list[Experiment]) -> str:
    out = [
        "| experiment | finished | paper actions "
        "| recovery planning actions we took (ms, last run) | count | total ms (median of runs) |",
        "|---|---|---|---|---|---|",
    ]
    for row in rows:
        finished = f"{sum(row.finished)}/{len(row.finished)}"
        paper = ", ".join(a for a, _ in row.paper) + (f" ({row.problem})" if row.problem else "")
        total = statistics.median(row.totals) if row.totals else math.nan
        out.append(
            f"| {row.name} | {finished} | {paper} | {'; '.join(row.ours)} | {len(row.ours)} "
            f"| {total:.1f} |"
        )
    return "\n".join(out) + "\n"


# ---- part 1, continued: every planning query of a play, each play in a child process -------

BENCH_SCENARIOS = SCENARIOS / "faults"  # these need not finish
QUERY_MEDIAN_TARGET_MS = 50.0  # issue 11: every recovery query of the runner, median ...
QUERY_MAX_TARGET_MS = 500.0  # ... and max


@dataclass(frozen=True)
class Query:
    """One planning query of the runner: announced by a plan event, or made without one."""

    time: float  # simulated seconds
    label: str  # the plan event's subject (`TP w/MT`); the planner (`TP`, `OP`) if unannounced
    reason: str  # the plan event's reason; what an unannounced query asks
    status: str
    millis: float
    announced: bool
    recovery: bool  # after the first fault, and not routine planning

    def kind(self) -> str:
        return f"{self.label} ({self.reason}, {self.status})"

    def describe(self) -> str:
        return f"{self.kind()} {self.millis:,.1f} ms at {self.time:g} s"


@dataclass
class Play:
    """What one child process playing a scenario reported, and how it ended."""

    scenario: str
    until: float
    end: str = "failed"  # done | stopped (the scenario's time limit) | cut off | failed
    end_time: float = 0.0  # simulated seconds of the last line
    queries: list[Query] = field(default_factory=list)
    waiting_for: list[dict[str, Any]] = field(default_factory=list)
    # at a cut: the query that had not finished, when it started (simulated s), and for how
    # long it had been running (wall s)
    running: tuple[str, float, float] | None = None
    since_last: float = 0.0  # at a cut with no query running: wall s since the last started
    wall: float = 0.0
    error: str = ""

    def recovery(self) -> list[Query]:
        return [q for q in self.queries if q.recovery]


class QueryReporter:
    """Reports every planning query of the runner as it starts and as it ends (a
    `planner.runner.QueryObserver`), and which were announced by a plan event.
    A query that starts and never ends shows where a cut-off play hung."""

    def __init__(self, emit: Callable[[dict[str, Any]], None]) -> None:
        self.emit = emit
        self.numbers = itertools.count()
        self.last = -1

    def asked(self, now: float, level: Any, purpose: str) -> None:
        self.last = next(self.numbers)
        self.emit(
            {
                "bench": "query",
                "id": self.last,
                "time": now,
                "planner": str(level),
                "purpose": purpose,
                "clock": time.time(),  # wall clock: the parent compares it with its own
            }
        )

    def answered(self, result: Any, millis: float | None) -> None:
        status = getattr(getattr(result, "status", None), "value", "?")
        self.emit({"bench": "answer", "id": self.last, "status": status, "millis": millis})

    def announced(self) -> None:
        self.emit({"bench": "announced", "id": self.last})


def child_play(model: Path, scenario: Path) -> int:
    """Child process: `sp run MODEL --scenario FILE --speed 0 --json --quiet`, with the
    runner's planning queries reported on the same stream (lines with a `bench` key)."""
    from app.cli.main import main as sp

    def emit(record: dict[str, Any]) -> None:
        print(json.dumps(record), flush=True)

    command = ["run", str(model), "--scenario", str(scenario), "--speed", "0", "--json"]
    return sp([*command, "--quiet"], observer=QueryReporter(emit))


def read_play(lines: Sequence[str], scenario: str, until: float, cut: float | None) -> Play:
    """A play from its child's output; `cut`: the wall clock (time.time) when it was killed."""
    play = Play(scenario, until)
    started: dict[int, dict[str, Any]] = {}
    answers: dict[int, dict[str, Any]] = {}
    announced: set[int] = set()
    fault = False  # seen the first fault: what follows may be recovery
    last_clock = None
    for line in lines:
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            break  # a line cut by the kill
        if not isinstance(record, dict):
            continue
        bench = record.get("bench")
        if bench is not None:
            if bench == "query":
                started[record["id"]] = {**record, "fault": fault}
                last_clock = record["clock"]
                play.end_time = max(play.end_time, float(record["time"]))
            elif bench == "answer":
                answers[record["id"]] = record
            elif bench == "announced":
                announced.add(record["id"])
            continue
        kind = record.get("kind")
        play.end_time = max(play.end_time, float(record.get("time", 0.0)))
        if kind == "fault":
            fault = True
        elif kind == "plan":
            reason = str(record.get("reason", ""))
            play.queries.append(
                Query(
                    float(record["time"]),
                    str(record["subject"]),
                    reason,
                    str(record.get("status", "")),
                    float(record.get("millis") or 0.0),
                    announced=True,
                    recovery=fault
                    and recovery_types.recovering(reason, str(record.get("status", ""))),
                )
            )
        elif kind in ("done", "stopped"):
            play.end = str(kind)
            play.waiting_for = list(record.get("waiting_for", []))
    for number, query in started.items():
        if number in announced:
            continue
        what = f"{query['planner']}: {query['purpose']}"
        if number not in answers:
            if cut is not None:
                play.running = (what, float(query["time"]), cut - float(query["clock"]))
            continue
        answer = answers[number]
        play.queries.append(
            Query(
                float(query["time"]),
                str(query["planner"]),
                str(query["purpose"]),
                str(answer["status"]),
                float(answer["millis"] or 0.0),
                announced=False,
                recovery=bool(query["fault"]),
            )
        )
    play.queries.sort(key=lambda q: q.time)  # stable: in the order the runner made them
    if cut is not None:
        play.end = "cut off"
        if last_clock is not None and play.running is None:
            play.since_last = cut - last_clock
    return play


def warm_cache(model: Path, directory: Path, limit: float) -> float:
    """Synthesise the model's supervisor into `directory` (what `sp` caches); seconds taken."""
    command = [sys.executable, "-m", "app.cli.main", "plan", str(model), "--goal", "true", "--json"]
    run = process.run(command, limit, cwd=ROOT, env={"SP_CACHE_DIR": str(directory)})
    if run.returncode != 0:
        reason = "timed out" if run.timed_out else run.stderr.strip()[-500:]
        raise SystemExit(f"error: synthesising {model} for the plays failed: {reason}")
    return run.wall


def play_in_child(model: Path, path: Path, until: float, limit: float, cache: Path) -> Play:
    """Play one scenario in a child process killed after `limit` wall seconds; the child
    starts from a copy of `cache`, so that no play tunes the supervisor of the next."""
    command = [sys.executable, "-m", "bench.runner", "--child", "play"]
    command += ["--model", str(model), "--scenario", str(path)]
    with tempfile.TemporaryDirectory(prefix="bench-play-") as tmp:
        own = Path(tmp) / "cache"
        shutil.copytree(cache, own)
        run = process.run(command, limit, cwd=ROOT, env={"SP_CACHE_DIR": str(own)})
    cut = time.time() if run.timed_out else None
    play = read_play(run.stdout.splitlines(), path.stem, until, cut)
    play.wall = run.wall
    if not run.timed_out and (run.returncode not in (0, 1) or play.end == "failed"):
        lines = run.stderr.strip().splitlines()
        play.end = "failed"
        play.error = lines[-1] if lines else f"exit status {run.returncode}"
    return play


def recovery_scenarios(only: Sequence[str] | None) -> list[Path]:
    """E1-E9 of seed 000 Table 1, then the scenarios of models/scenarios/faults."""
    paths = sorted(SCENARIOS.glob("e[1-9]_*.yaml")) + sorted(BENCH_SCENARIOS.glob("*.yaml"))
    return [p for p in paths if not only or any(o in p.stem for o in only)]


def play_scenarios(
    paths: Sequence[Path], runs: int, limit: float, model: Path = DEMO
) -> tuple[list[list[Play]], float]:
    """Every scenario played `runs` times (once if it was cut off or failed), and how long
    the supervisor synthesis the plays start from took."""
    from app.station.scenario import load_scenario
    from planner.reading import load_station

    station = load_station(model.read_text(), str(model))
    scenarios = [load_scenario(p.read_text(), str(p), station) for p in paths]
    out = []
    with tempfile.TemporaryDirectory(prefix="bench-plays-") as tmp:
        cache = Path(tmp) / "supervisor"
        synthesis = warm_cache(model, cache, max(limit, 600.0))
        for path, scenario in zip(paths, scenarios, strict=True):
            plays: list[Play] = []
            while len(plays) < runs and all(p.end in ("done", "stopped") for p in plays):
                plays.append(play_in_child(model, path, scenario.until, limit, cache))
            out.append(plays)
            last = plays[-1]
            print(
                f"  {path.stem}: {last.end} ({len(last.queries)} queries, {last.wall:.1f} s)",
                file=sys.stderr,
            )
    return out, synthesis


def spread(values: Sequence[int]) -> str:
    return f"{min(values)}" if min(values) == max(values) else f"{min(values)}-{max(values)}"


def stats(queries: Sequence[Query]) -> str:
    if not queries:
        return "none"
    times = [q.millis for q in queries]
    return f"{statistics.median(times):,.1f} / {max(times):,.1f}"


def describe_end(play: Play) -> str:
    if play.end == "done":
        return f"done at {play.end_time:g} s"
    if play.end == "stopped":
        text = f"stopped at its time limit ({play.until:g} s)"
        waiting = "; ".join(
            f"{w.get('who', '?')}: {w.get('subject', '?')} ({w.get('what', '')})"
            for w in play.waiting_for
        )
        return text + (f", waiting for {waiting}" if waiting else "")
    if play.end == "cut off":
        text = (
            f"**cut off** after {play.wall:,.0f} s wall, at {play.end_time:g} s of "
            f"{play.until:g} s simulated"
        )
        if play.running is not None:
            what, at, seconds = play.running
            return text + (
                f": the next query ({what}, at {at:g} s) ran over {seconds:,.1f} s "
                "without finishing"
            )
        return text + f", {play.since_last:,.1f} s after its last query started (none running)"
    return f"**failed**: {play.error}"


def target(plays: Sequence[Play]) -> str:
    queries = [q for p in plays for q in p.recovery()]
    running = [p.running[2] for p in plays if p.running is not None]
    misses = []
    if queries:
        median = statistics.median(q.millis for q in queries)
        slowest = max(queries, key=lambda q: q.millis)
        if median >= QUERY_MEDIAN_TARGET_MS:
            misses.append(f"median {median:,.1f} ms")
        if slowest.millis >= QUERY_MAX_TARGET_MS:
            misses.append(f"max {slowest.millis:,.1f} ms")
    if running and max(running) * 1000 >= QUERY_MAX_TARGET_MS:
        misses.append(f"a query ran over {max(running):,.1f} s")
    if misses:
        return "**not met**: " + ", ".join(misses)
    return "met" if queries else "no recovery query"


def queries_table(rows: Sequence[Sequence[Play]]) -> str:
    out = [
        "| scenario | end | plays | queries per play (recovery; unannounced) "
        "| all queries median / max ms | recovery queries median / max ms "
        "| slowest query | target: recovery median < 50 ms, max < 500 ms |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for plays in rows:
        ends: dict[str, int] = {}
        for play in plays:
            ends[describe_end(play)] = ends.get(describe_end(play), 0) + 1
        end = "; ".join(
            text + (f" ({n} of {len(plays)})" if len(ends) > 1 else "") for text, n in ends.items()
        )
        everything = [q for p in plays for q in p.queries]
        recovering = [q for p in plays for q in p.recovery()]
        counts = (
            f"{spread([len(p.queries) for p in plays])} "
            f"({spread([len(p.recovery()) for p in plays])}; "
            + spread([sum(not q.announced for q in p.queries) for p in plays])
            + ")"
        )
        slowest = max(everything, key=lambda q: q.millis) if everything else None
        text = slowest.describe() if slowest is not None else "none"
        if slowest is not None and not slowest.recovery and recovering:
            text += "; slowest recovery: " + max(recovering, key=lambda q: q.millis).describe()
        out.append(
            f"| {plays[0].scenario} | {end} | {len(plays)} | {counts} | {stats(everything)} "
            f"| {stats(recovering)} | {text} | {target(plays)} |"
        )
    return "\n".join(out) + "\n"


def slow_kinds_table(rows: Sequence[Sequence[Play]]) -> str:
    """The kinds of recovery query to look at first (a median of 50 ms or more, or one query
    of 500 ms or more), per scenario, costliest first."""
    out = [
        "| scenario | recovery query (reason, status) | announced | count per play "
        "| median ms | max ms | total ms per play |",
        "|---|---|---|---|---|---|---|",
    ]
    for plays in rows:
        kinds: dict[tuple[str, bool], list[float]] = {}
        for play in plays:
            for q in play.recovery():
                kinds.setdefault((q.kind(), q.announced), []).append(q.millis)
        ranked = sorted(kinds.items(), key=lambda item: -sum(item[1]))
        for (kind, announced), times in ranked:
            median = statistics.median(times)
            if median < QUERY_MEDIAN_TARGET_MS and max(times) < QUERY_MAX_TARGET_MS:
                continue
            n = len(plays)
            out.append(
                f"| {plays[0].scenario} | {kind} | {'yes' if announced else 'no'} "
                f"| {len(times) / n:g} | {median:,.1f} | {max(times):,.1f} "
                f"| {sum(times) / n:,.0f} |"
            )
    if len(out) == 2:
        return "None: every kind of recovery query met both targets.\n"
    return "\n".join(out) + "\n"


def queries_section(
    rows: Sequence[Sequence[Play]], runs: int, limit: float, synthesis: float
) -> str:
    return (
        "\n## Every planning query of the runner, per scenario (demo station)\n\n"
        "Each scenario (E1-E9 of models/scenarios, then models/scenarios/faults: slow "
        "planning, endless retries, errors that must clear, dead ends, rejected recovery, "
        "slow people and devices) is played by "
        "`sp run models/demo_station.yaml --scenario FILE --speed 0 --json --quiet` in a child "
        f"process killed after {limit:g} s wall, {runs} play{'s' * (runs != 1)} per scenario "
        "(one if it was cut off). Every "
        "play starts from the same supervisor, synthesised once for the plays "
        f"({synthesis:,.1f} s) in a private cache, so that no play tunes the next one's BDD "
        "variable order. Queries: every `plan` event's `millis`, and (unannounced) the "
        "queries the runner makes without a plan event: which operations or intentions fail, "
        "one at a time, after a failed plan, and the background check of errors. Recovery "
        "queries: after the first fault, all but routine planning (reason `goals` or "
        "`intentions`). Target (issue 11): recovery queries under "
        f"{QUERY_MEDIAN_TARGET_MS:g} ms median and {QUERY_MAX_TARGET_MS:g} ms max. Medians "
        "and maxima are over all plays of a scenario.\n\n"
        + queries_table(rows)
        + "\nThe kinds of recovery query to look at first: those whose median is "
        f"{QUERY_MEDIAN_TARGET_MS:g} ms or more or of which one took {QUERY_MAX_TARGET_MS:g} ms "
        "or more, per scenario, costliest first:\n\n" + slow_kinds_table(rows)
    )


# ---- part 2: ticks -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Tick:
    phase: str  # "idle": no intention armed yet; "running": after the first start
    millis: float
    plans: tuple[tuple[str, float], ...]  # (label, planning ms) of the plan events
    profile: Any = field(default=None, compare=False)  # cProfile.Profile of the tick, if asked


def drive(
    station: Any,
    planners: Any,
    intentions: Sequence[str],
    *,
    ticks: int,
    idle: int,
    cycle: bool,
    config: Any = None,
    delays: dict[str, float] | None = None,
    default_delay: float = 1.0,
    start: dict[str, Any] | None = None,
    step: float = 0.1,
    profile: bool = False,
) -> Iterator[Tick]:
    """The loop of app.station.player.play, timing `Runner.tick` alone (not the simulated world).

    `idle` ticks with no intention armed come first; then the intentions are started one
    after another as each finishes (over and over if `cycle`), until `ticks` ticks in all or,
    without `cycle`, the last one finished.
    """
    from hw.simulated import SimulatedWorld
    from planner.runner import (
        EventKind,
        Inputs,
        IntentionState,
        Runner,
        RunnerConfig,
        StartIntention,
    )

    base = config or RunnerConfig()
    runner = Runner(
        station,
        planners.transition,
        planners.operation,
        replace(base, auto_intentions=frozenset()),
        time.perf_counter,
    )
    world = SimulatedWorld(station, delays=delays, default_delay=default_delay, start=start)
    now = 0.0
    state = runner.initial(now, start)
    current = -1
    for k in range(ticks):
        world.write(runner.commands(state))
        world.follow_estimates(state.values)
        world.advance(now)
        report = world.read()
        actions: tuple[Any, ...] = ()
        finished = current >= 0 and state.intentions[intentions[current]] == IntentionState.FINISHED
        if k >= idle and (current < 0 or finished):
            if current + 1 >= len(intentions) and not cycle:
                return
            current = (current + 1) % len(intentions)
            actions = (StartIntention(name=intentions[current]),)
        inputs = Inputs(report.measured, report.observed, report.heartbeats, actions)
        profiler = cProfile.Profile() if profile else None
        if profiler is not None:
            profiler.enable()
        started = time.perf_counter()
        result = runner.tick(state, inputs, now)
        millis = (time.perf_counter() - started) * 1000
        if profiler is not None:
            profiler.disable()
        state = result.state
        plans = tuple(
            (e.subject, e.millis or 0.0) for e in result.events if e.kind is EventKind.PLAN
        )
        yield Tick("idle" if current < 0 else "running", millis, plans, profiler)
        now = round(now + step, 6)


def build_cells(count: int, emit: Callable[[dict[str, Any]], None]) -> tuple[Any, Any]:
    """Station and planners for `count` cells, each stage's time emitted as it ends."""
    from app.station.player import Planners
    from planner.planning.operation_planner import OperationPlanner
    from planner.planning.transition_planner import TransitionPlanner
    from planner.reading import load_station

    started = time.perf_counter()
    station = load_station(cells.station_text(count), f"cells_{count}.yaml")
    emit({"stage": "load", "s": time.perf_counter() - started})
    started = time.perf_counter()
    tp = TransitionPlanner(station.model)
    emit({"stage": "transition planner", "s": time.perf_counter() - started})
    started = time.perf_counter()
    op = OperationPlanner(station)
    emit({"stage": "operation planner", "s": time.perf_counter() - started})
    sizes = {
        "transitions": len(station.model.transitions),
        "variables": len(station.model.variables),
        "bits": len(tp.sym.state_bits),
        "op_bits": len(op.planner.sym.state_bits),
    }
    emit({"stage": "sizes", **sizes})
    return station, Planners(tp, op)


def child_ticks(count: int, ticks: int, idle: int) -> None:
    """Child process: build, then stream one JSON line per tick (the parent may kill us)."""

    def emit(record: dict[str, Any]) -> None:
        print(json.dumps(record), flush=True)

    station, planners = build_cells(count, emit)
    names = [cells.intention(c) for c in cells.cell_names(count)]
    for tick in drive(station, planners, names, ticks=ticks, idle=idle, cycle=True):
        emit({"phase": tick.phase, "ms": tick.millis, "plans": tick.plans})


def child_synthesis(count: int) -> None:
    """Child process: `TransitionPlanner(model)`, with its stages timed as they end."""
    import planner.planning.transition_planner as tp_module
    from planner.reading import load_station

    def emit(record: dict[str, Any]) -> None:
        print(json.dumps(record), flush=True)

    def timed(stage: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def run(*args: Any) -> Any:
            emit({"started": stage})
            started = time.perf_counter()
            result = function(*args)
            emit({"stage": stage, "s": time.perf_counter() - started})
            return result

        return run

    station = load_station(cells.station_text(count), f"cells_{count}.yaml")
    started = time.perf_counter()
    stages = {
        "SymbolicModel": "encoding",
        "check_dynamics": "cycle check",
        "bad_parts": "bad states",
        "sift": "sift",
    }
    with contextlib.ExitStack() as patches:
        for name, stage in stages.items():
            patches.enter_context(
                mock.patch.object(tp_module, name, timed(stage, getattr(tp_module, name)))
            )
        planner = tp_module.TransitionPlanner(station.model)
    emit(
        {"stage": "total", "s": time.perf_counter() - started, "bits": len(planner.sym.state_bits)}
    )


def run_child(arguments: list[str], limit: float) -> tuple[list[dict[str, Any]], bool, str]:
    """A child's JSON lines, whether it finished within `limit` seconds (else it was
    killed), and the last line of its error output if it failed."""
    command = [sys.executable, "-m", "bench.runner", *arguments]
    error = ""
    try:
        done = subprocess.run(
            command, cwd=ROOT, capture_output=True, text=True, timeout=limit, check=False
        )
        output, finished = done.stdout, done.returncode == 0
        if done.returncode != 0:
            print(done.stderr[-3000:], file=sys.stderr)
            lines = done.stderr.strip().splitlines()
            error = lines[-1] if lines else f"exit status {done.returncode}"
    except subprocess.TimeoutExpired as expired:
        raw = expired.stdout or b""
        output = raw.decode() if isinstance(raw, bytes) else raw
        finished = False
    records = []
    for line in output.splitlines():
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            break  # a line cut by the kill
    return records, finished, error


@dataclass
class Synthesis:
    transitions: int
    cells: int
    bits: int = 0
    stages: dict[str, float] = field(default_factory=dict)
    total: float | None = None  # seconds; None: killed at the limit
    running: str = ""  # the stage it was in when killed
    error: str = ""  # how it failed, if it did


def probe_synthesis(sizes: Sequence[int], limit: float) -> list[Synthesis]:
    """The planner's construction on growing models until one takes longer than `limit` s."""
    out = []
    for transitions in sizes:
        count = cells.cells_for(transitions)
        records, finished, error = run_child(["--child", "synthesis", "--cells", str(count)], limit)
        row = Synthesis(count * cells.TRANSITIONS_PER_CELL, count, 8 * count)
        for record in records:
            if "stage" in record and record["stage"] != "total":
                row.stages[record["stage"]] = record["s"]
            if "started" in record:
                row.running = record["started"]
            if record.get("stage") == "total":
                row.total, row.bits = record["s"], record["bits"]
        out.append(row)
        row.error = error
        print(f"  synthesis, {row.transitions} transitions: {fmt_s(row.total)}", file=sys.stderr)
        if not finished:
            break
    return out


def fit(probe: list[Synthesis]) -> tuple[int, float, float] | None:
    """Transitions, seconds and exponent of a power law through the last two finished points."""
    done = [(p.transitions, p.total) for p in probe if p.total is not None and p.total > 0.5]
    if len(done) < 2:
        return None
    (n0, s0), (n1, s1) = done[-2], done[-1]
    return n1, s1, math.log(s1 / s0) / math.log(n1 / n0)


def extrapolate(probe: list[Synthesis], transitions: int) -> float | None:
    fitted = fit(probe)
    if fitted is None:
        return None
    n1, s1, exponent = fitted
    return float(s1 * (transitions / n1) ** exponent)


def fmt_s(seconds: float | None) -> str:
    if seconds is None:
        return "killed"
    if seconds >= 3600 * 24 * 365:
        return f"~{seconds / (3600 * 24 * 365):,.0f} years"
    if seconds >= 3600 * 24:
        return f"~{seconds / (3600 * 24):,.0f} days"
    if seconds >= 3600:
        return f"~{seconds / 3600:,.1f} h"
    if seconds >= 120:
        return f"~{seconds / 60:,.0f} min"
    return f"{seconds:,.1f} s"


@dataclass
class Size:
    name: str
    transitions: int
    variables: int = 0
    bits: int = 0
    synthesis: str = ""
    build: str = ""
    ticks: list[Tick] = field(default_factory=list)
    target: float | None = None
    note: str = ""

    def quiet(self, phase: str) -> list[float]:
        return [t.millis for t in self.ticks if t.phase == phase and not t.plans]

    def replans(self) -> list[float]:
        return [t.millis for t in self.ticks if t.plans]


def p99(values: list[float]) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(0.99 * len(ordered)) - 1)]


def ticks_table(rows: list[Size]) -> str:
    out = [
        "| model | transitions | variables (bits) | supervisor synthesis "
        "| planners built in | idle tick median ms (n) "
        "| running tick w/o replanning median / p99 ms (n) "
        "| tick with replanning median ms (n) | target | met |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        idle, quiet, plans = row.quiet("idle"), row.quiet("running"), row.replans()
        idle_text = f"{statistics.median(idle):.2f} ({len(idle)})" if idle else "none"
        quiet_text = (
            f"{statistics.median(quiet):.2f} / {p99(quiet):.2f} ({len(quiet)})" if quiet else "none"
        )
        plan_text = f"{statistics.median(plans):,.1f} ({len(plans)})" if plans else "none"
        if row.note:
            plan_text += f"; {row.note}"
        target, met = "", ""
        if row.target is not None:
            target = f"< {row.target:g} ms w/o replanning"
            measured = quiet or idle
            if not measured:
                met = "not measured"
            else:
                ok = statistics.median(measured) < row.target
                met = "yes" if ok else "**no**"
                if not quiet:
                    met += " (idle ticks only)"
        out.append(
            f"| {row.name} | {row.transitions:,} | {row.variables:,} ({row.bits:,}) "
            f"| {row.synthesis} | {row.build} | {idle_text} | {quiet_text} | {plan_text} "
            f"| {target} | {met} |"
        )
    return "\n".join(out) + "\n"


def probe_table(probe: list[Synthesis], limit: float) -> str:
    out = [
        "| transitions | cells | encoding s | automatic-cycle check s | bad states s | sift s | "
        "TransitionPlanner(model) s |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in probe:
        stages = [
            f"{p.stages[s]:,.2f}" if s in p.stages else ("running" if p.running == s else "")
            for s in ("encoding", "cycle check", "bad states", "sift")
        ]
        total = f"{p.total:,.2f}" if p.total is not None else f"> {limit:g} (killed)"
        if p.error:
            total = f"**failed**: {p.error}"
        out.append(f"| {p.transitions:,} | {p.cells} | {' | '.join(stages)} | {total} |")
    return "\n".join(out) + "\n"


def run_size(
    transitions: int,
    probe: list[Synthesis],
    limit: float,
    budget: float,
    ticks: int,
    idle: int,
) -> Size:
    count = cells.cells_for(transitions)
    row = Size(f"{count} cells", count * cells.TRANSITIONS_PER_CELL)
    row.target = LARGE_TICK_TARGET_MS if row.transitions >= 10_000 else None
    known = next((p for p in probe if p.cells == count), None)
    guess = extrapolate(probe, row.transitions)
    if known is not None and known.total is not None:
        row.synthesis = f"{known.total:,.1f} s"
    else:
        exceeded = any(p.total is None for p in probe)
        row.synthesis = (
            f"> {limit:g} s (killed in {known.running or 'loading'})"
            if known is not None
            else "not tried (a smaller size exceeded the limit)"
            if exceeded
            else "not in --probe"
        )
        row.synthesis += f"; extrapolated {fmt_s(guess)}" if guess else ""
    started = time.perf_counter()
    arguments = ["--child", "ticks", "--cells", str(count), "--ticks", str(ticks)]
    arguments += ["--idle", str(idle)]
    records, finished, error = run_child(arguments, budget)
    elapsed = time.perf_counter() - started
    stages = {r["stage"]: r for r in records if "stage" in r}
    if "sizes" in stages:
        row.variables, row.bits = stages["sizes"]["variables"], stages["sizes"]["bits"]
    build = sum(r["s"] for r in records if "s" in r)
    row.build = f"{build:,.1f} s"
    row.ticks = [
        Tick(r["phase"], r["ms"], tuple((label, ms) for label, ms in r["plans"]))
        for r in records
        if "phase" in r
    ]
    if error:
        row.note = f"**failed**: {error}"
    elif not finished:
        waited = elapsed - build - sum(t.millis for t in row.ticks) / 1000
        row.note = f"the next ran {waited:,.0f} s without finishing (budget {budget:g} s)"
    print(f"  ticks, {row.transitions} transitions: {len(row.ticks)} ticks", file=sys.stderr)
    return row


def demo_ticks(station: Any, planners: Any, idle: int, synthesis: float, build: float) -> Size:
    from app.station.scenario import load_scenario

    path = SCENARIOS / "nominal.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    row = Size("demo station, nominal.yaml", len(station.model.transitions))
    row.variables = len(station.model.variables)
    row.bits = len(planners.transition.sym.state_bits)
    row.synthesis = f"{synthesis:,.1f} s"
    row.build = f"{build:,.1f} s"
    row.target = DEMO_TICK_TARGET_MS
    row.ticks = list(
        drive(
            station,
            planners,
            scenario.intentions or (),
            ticks=idle + int(scenario.until / 0.1),
            idle=idle,
            cycle=False,
            config=scenario.config,
            delays=dict(scenario.delays),
            default_delay=scenario.default_delay,
            start=dict(scenario.start),
        )
    )
    return row


def profile_ticks(transitions: int, ticks: int, idle: int, top: int = 15) -> None:
    """cProfile of `Runner.tick`, per kind of tick, in this process (0: the demo, nominal)."""
    if transitions:
        count = cells.cells_for(transitions)

        def emit(record: dict[str, Any]) -> None:
            print(json.dumps(record), file=sys.stderr)

        station, planners = build_cells(count, emit)
        names = [cells.intention(c) for c in cells.cell_names(count)]
        run = drive(station, planners, names, ticks=ticks, idle=idle, cycle=True, profile=True)
    else:
        from app.station.player import Planners
        from app.station.scenario import load_scenario
        from planner.planning.operation_planner import OperationPlanner
        from planner.planning.transition_planner import TransitionPlanner
        from planner.reading import load_station

        station = load_station(DEMO.read_text(), str(DEMO))
        planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
        path = SCENARIOS / "nominal.yaml"
        scenario = load_scenario(path.read_text(), str(path), station)
        run = drive(
            station,
            planners,
            scenario.intentions or (),
            ticks=ticks,
            idle=idle,
            cycle=False,
            delays=dict(scenario.delays),
            default_delay=scenario.default_delay,
            profile=True,
        )
    kinds: dict[str, list[Tick]] = {"idle": [], "running, no plan": [], "replanning": []}
    for tick in run:
        kind = (
            "replanning" if tick.plans else "idle" if tick.phase == "idle" else "running, no plan"
        )
        kinds[kind].append(tick)
    for kind, chosen in kinds.items():
        if not chosen:
            continue
        out = io.StringIO()
        stats = pstats.Stats(chosen[0].profile, stream=out)
        for tick in chosen[1:]:
            stats.add(tick.profile)
        median = statistics.median(t.millis for t in chosen)
        print(f"== {kind} ticks: {len(chosen)}, median {median:.2f} ms (profiled)")
        stats.sort_stats("tottime").print_stats(top)
        print(out.getvalue().split("\n\n", 1)[-1].strip() + "\n")


def revision() -> str:
    """The commit measured, and whether the code under it had uncommitted changes."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "planner", "app", "hw", "models"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        ).stdout.strip()
    except OSError:
        return "unknown commit"
    return f"commit {commit or 'unknown'}" + (" with uncommitted changes" if dirty else "")


# ---- main ------------------------------------------------------------------------------------


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="plays of each E1-E9 scenario")
    parser.add_argument(
        "--only", nargs="*", help="experiments and scenarios whose names contain these (e3 ...)"
    )
    parser.add_argument(
        "--recovery-only",
        action="store_true",
        help="only the planning queries of every scenario (part 1's plays in child processes)",
    )
    parser.add_argument(
        "--recovery-runs", type=int, default=3, help="plays of each scenario for its queries"
    )
    parser.add_argument(
        "--play-limit", type=float, default=120.0, help="wall seconds per play before it is cut off"
    )
    parser.add_argument(
        "--sizes", type=int, nargs="*", default=[100, 1000, 3000, 10000], help="transitions"
    )
    parser.add_argument(
        "--probe",
        type=int,
        nargs="*",
        default=[100, 1000, 3000, 10000],
        help="transitions to time the planner's construction on, until one exceeds the limit",
    )
    parser.add_argument("--synthesis-limit", type=float, default=90.0, help="seconds")
    parser.add_argument("--budget", type=float, default=90.0, help="seconds per size's tick run")
    parser.add_argument("--ticks", type=int, default=400, help="ticks per size (idle included)")
    parser.add_argument("--idle", type=int, default=50, help="idle ticks before the first start")
    parser.add_argument("--quick", action="store_true", help="1 run, small sizes, short limits")
    parser.add_argument("--output", type=Path, default=RESULTS / "runner.md")
    parser.add_argument(
        "--profile",
        type=int,
        metavar="TRANSITIONS",
        help="instead: cProfile the ticks of one size (0: the demo), print the hotspots",
    )
    parser.add_argument("--child", choices=["ticks", "synthesis", "play"], help=argparse.SUPPRESS)
    parser.add_argument("--model", type=Path, default=DEMO, help=argparse.SUPPRESS)
    parser.add_argument("--scenario", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--cells", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child == "ticks":
        child_ticks(args.cells, args.ticks, args.idle)
        return
    if args.child == "synthesis":
        child_synthesis(args.cells)
        return
    if args.child == "play":
        sys.exit(child_play(args.model, args.scenario))
    if args.profile is not None:
        profile_ticks(args.profile, args.ticks, args.idle)
        return
    if args.quick:
        args.runs, args.sizes, args.probe = 1, [100, 1000], [100, 1000]
        args.synthesis_limit, args.budget, args.ticks = 30.0, 30.0, 200
        args.recovery_runs, args.play_limit = 1, 30.0
    if args.recovery_only:
        args.sizes = []

    from app.station.player import Planners
    from planner.planning.operation_planner import OperationPlanner
    from planner.planning.transition_planner import TransitionPlanner
    from planner.reading import load_station

    measured = revision()
    experiments = []
    if not args.recovery_only:
        station = load_station(DEMO.read_text(), str(DEMO))
        started = time.perf_counter()
        transition_planner = TransitionPlanner(station.model)
        demo_synthesis = time.perf_counter() - started
        planners = Planners(transition_planner, OperationPlanner(station))
        demo_build = time.perf_counter() - started
        paths = sorted(SCENARIOS.glob("e[1-9]_*.yaml"))
        if args.only:
            paths = [p for p in paths if any(o in p.stem for o in args.only)]
        for path in paths:
            experiments.append(run_experiment(station, planners, path, args.runs))
            print(f"  {path.stem}: done", file=sys.stderr)
    plays, play_synthesis = play_scenarios(
        recovery_scenarios(args.only), args.recovery_runs, args.play_limit
    )

    probe = probe_synthesis(args.probe, args.synthesis_limit) if args.sizes else []
    sizes = (
        [demo_ticks(station, planners, args.idle, demo_synthesis, demo_build)] if args.sizes else []
    )
    for transitions in args.sizes:
        sizes.append(
            run_size(transitions, probe, args.synthesis_limit, args.budget, args.ticks, args.idle)
        )

    command = " ".join(["python -m bench.runner", *sys.argv[1:]])
    if revision() != measured:  # child processes import the code as it is when they start
        measured += f" (changed to {revision()} during the run: measurements mix the two)"
    text = f"`{command}`, {time.strftime('%Y-%m-%d')}, {measured}. Machine: {machine()}\n\n"
    if experiments:
        text += (
            f"## Recovery planning in seed 000's experiments (demo station, {args.runs} runs)\n\n"
            "Each planning action of seed 000 Table 1, matched in order among our non-routine "
            "planning actions (reason not `goals`/`intentions`) after the first fault; "
            "target: under 20 ms (median).\n\n"
            + experiments_table(experiments)
            + "\nAll our recovery planning actions (label (reason, status) ms):\n\n"
            + taken_table(experiments)
        )
    if plays:
        text += queries_section(plays, args.recovery_runs, args.play_limit, play_synthesis)
    if sizes:
        text += (
            "\n## Runner tick versus model size\n\n"
            "`Runner.tick` alone (not the simulated world), 0.1 s of simulated time per tick. "
            f"Idle: {args.idle} ticks with no intention armed. Running: then the station's "
            "intentions (bench/cells.py: one cell after another) are started one after another; "
            "ticks that emitted no plan event (effects pending, operations executing) vs. ticks "
            f"that replanned. Each generated size runs in a child process for at most "
            f"{args.budget:g} s (building included).\n\n" + ticks_table(sizes)
        )
    if probe:
        limit = args.synthesis_limit
        largest = max((p.transitions for p in probe if p.total is not None), default=0)
        fitted = fit(probe)
        text += (
            f"\n### Building the transition planner versus size (each killed after {limit:g} s)\n\n"
            + probe_table(probe, limit)
            + (
                f"\nLargest size synthesised within {limit:g} s: {largest:,} transitions"
                if any(p.total is None for p in probe)
                else f"\nEvery size probed was synthesised within {limit:g} s"
            )
            + (f"; time grows about as transitions^{fitted[2]:.1f}.\n" if fitted else ".\n")
        )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
