"""Planning benchmark: the whole `sp plan` process on the station family and the demo station.

    python -m bench.planning [--runs 5] [--timeout 60] [--fd-timeout 120] [--only b6r2]

For every instance: variables, transitions, reachable states, plan length, median and max wall
time of the whole `sp plan` process over repeated runs (interpreter start-up included), its
peak memory, Fast Downward's optimal `astar(lmcut())` on the same instance exported to PDDL
(when `unified-planning` and `up-fast-downward` are installed: `pip install -e .[bench]`),
and the seed's nuXmv time for the nearest plan length (seed 003 Table VII).  Prints a
Markdown table and writes it to bench/results/planning.md.

Each instance first runs with an empty supervisor cache ("cold": synthesis included), then
`--runs` times reusing it (median and max).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from bench import family

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
NUXMV_MS = {10: 776, 20: 1652, 30: 3836, 40: 6259, 50: 34576}  # seed 003 Table VII


@dataclass
class Instance:
    name: str
    model: Path
    goal: str
    model_dict: dict[str, Any] | None = None  # flat form, for the PDDL export


@dataclass
class Row:
    instance: str
    variables: int
    bits: int
    transitions: int
    reachable: int
    length: int | None
    median_ms: float
    max_ms: float
    peak_mb: float
    fd_ms: float | None
    fd_status: str
    sat_ms: float | None
    cold_ms: float
    sat_skipped: bool = False


def family_instances(directory: Path) -> list[Instance]:
    result = []
    for robots, most in ((1, 6), (2, 6), (3, 4)):
        for bolts in range(1, most + 1):
            model_dict = family.station(bolts, robots)
            path = directory / f"family_b{bolts}_r{robots}.yaml"
            path.write_text(yaml.safe_dump(model_dict, sort_keys=False, width=200))
            result.append(Instance(f"B={bolts} R={robots}", path, family.goal(bolts), model_dict))
    return result


def demo_instances() -> list[Instance]:
    demo = ROOT / "models" / "demo_station.yaml"
    if not demo.exists():
        return []
    return [
        Instance("demo: bp1 tightened", demo, "bp1.state == tightened"),
        Instance("demo: tighten_bolts", demo, "tighten_bolts.goal"),
    ]


# Measured from a small stdlib-only launcher process: Linux carries a parent's peak RSS into
# a vfork()ed child at exec, so children of this (large) process would report its size.
_LAUNCHER = """
import json, os, subprocess, sys, threading, time
timeout = float(sys.argv[1]); command = sys.argv[2:]
started = time.perf_counter()
child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
timer = threading.Timer(timeout, child.kill); timer.start()
out = child.stdout.read()
_, status, usage = os.wait4(child.pid, 0)
timer.cancel()
print(json.dumps({"stdout": out.decode(), "wall": time.perf_counter() - started,
                  "peak_kb": usage.ru_maxrss}))
"""


def run_sp(
    instance: Instance, timeout: float, engine: str = "bdd"
) -> tuple[dict[str, Any] | None, float, float]:
    """One whole `sp plan` process: its JSON answer, wall seconds and peak RSS in MB."""
    sp = Path(sys.executable).parent / "sp"
    command = [str(sp), "plan", str(instance.model), "--goal", instance.goal, "--json"]
    command += ["--engine", engine]
    launched = subprocess.run(
        [sys.executable, "-c", _LAUNCHER, str(timeout), *command],
        capture_output=True,
        text=True,
        check=True,
    )
    report = json.loads(launched.stdout)
    try:
        answer = json.loads(report["stdout"])
    except json.JSONDecodeError:
        answer = None
    return answer, report["wall"], report["peak_kb"] / 1024


def sizes(instance: Instance) -> tuple[int, int, int, int]:
    from planner.station import load_station
    from planner.transition_planner import TransitionPlanner

    model = load_station(instance.model.read_text(), str(instance.model)).model
    planner = TransitionPlanner(model)
    reachable = planner.sym.count(planner.reachable(tuple(model.initial_values().values())))
    return len(model.variables), len(planner.sym.state_bits), len(model.transitions), reachable


def fast_downward(instance: Instance, timeout: float) -> tuple[float | None, str]:
    if instance.model_dict is None:
        return None, "n/a"
    try:
        from bench.fd_runner import solve_optimal
        from bench.pddl_export import to_up_problem
    except ImportError:
        return None, "not installed"
    from planner.station import load_station

    model = load_station(instance.model.read_text(), str(instance.model)).model
    start = dict(model.initial_values())
    # FD gets the specifications as invariants checked after every step rather than our
    # supervisor guards (large guards blow up FD's translation); the plan lengths are
    # compared per instance, so a difference in meaning would show in the table
    problem = to_up_problem(instance.model_dict, start, instance.goal, enforce_specifications=True)
    result = solve_optimal(problem, timeout)
    if result.status != "optimal":
        return None, result.status
    return result.seconds * 1000, str(result.length)


def measure(
    instance: Instance, runs: int, timeout: float, fd_timeout: float, sat_timeout: float
) -> Row:
    variables, bits, transitions, reachable = sizes(instance)
    times: list[float] = []
    length: int | None = None
    # the first run synthesises the supervisor into an empty cache (cold), the others reuse it
    os.environ["SP_CACHE_DIR"] = tempfile.mkdtemp(prefix="sp-bench-cache-")
    answer, cold, peak = run_sp(instance, timeout)
    length = answer.get("length") if answer else None
    for _ in range(runs if answer is not None else 0):
        answer, wall, run_peak = run_sp(instance, timeout)
        times.append(wall * 1000)
        peak = max(peak, run_peak)
        if answer is None:
            break
    fd_ms, fd_status = fast_downward(instance, fd_timeout) if fd_timeout > 0 else (None, "skipped")
    sat_answer, sat_wall, _ = (
        run_sp(instance, sat_timeout, "sat") if sat_timeout > 0 else (None, 0, 0)
    )
    return Row(
        instance.name,
        variables,
        bits,
        transitions,
        reachable,
        length,
        statistics.median(times) if times else cold * 1000,
        max(times) if times else cold * 1000,
        peak,
        fd_ms,
        fd_status,
        sat_wall * 1000 if sat_answer is not None else None,
        cold * 1000,
        sat_skipped=sat_timeout <= 0,
    )


def nuxmv(length: int | None) -> str:
    if length is None:
        return ""
    nearest = min(NUXMV_MS, key=lambda n: abs(n - length))
    return f"{NUXMV_MS[nearest]:,} (n={nearest})"


def table(rows: list[Row]) -> str:
    header = (
        "| instance | variables (bits) | transitions | reachable states | plan length "
        "| sp plan cold ms | median ms | max ms | peak MB | --engine sat ms "
        "| Fast Downward opt. ms | FD / sp | nuXmv ms (seed) |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for r in rows:
        fd = f"{r.fd_ms:,.0f}" if r.fd_ms is not None else r.fd_status
        if r.fd_ms is not None and r.fd_status != str(r.length):
            fd += f" (length {r.fd_status}!)"
        ratio = f"{r.fd_ms / r.median_ms:.1f}x" if r.fd_ms is not None else ""
        length = str(r.length) if r.length is not None else "timeout"
        sat = f"{r.sat_ms:,.0f}" if r.sat_ms is not None else "timeout"
        if r.sat_skipped:
            sat = "skipped"
        lines.append(
            f"| {r.instance} | {r.variables} ({r.bits}) | {r.transitions} | {r.reachable:,} "
            f"| {length} | {r.cold_ms:,.0f} | {r.median_ms:,.0f} | {r.max_ms:,.0f} "
            f"| {r.peak_mb:.0f} | {sat} "
            f"| {fd} | {ratio} | {nuxmv(r.length)} |"
        )
    return header + "\n".join(lines) + "\n"


def machine() -> str:
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.system()}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds per sp plan run")
    parser.add_argument("--fd-timeout", type=float, default=120.0, help="0 skips Fast Downward")
    parser.add_argument("--sat-timeout", type=float, default=30.0, help="0 skips --engine sat")
    parser.add_argument("--only", nargs="*", help="instance names containing these texts")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        instances = family_instances(Path(tmp)) + demo_instances()
        if args.only:
            instances = [i for i in instances if any(o in i.name for o in args.only)]
        rows = []
        for instance in instances:
            row = measure(instance, args.runs, args.timeout, args.fd_timeout, args.sat_timeout)
            rows.append(row)
            print(table([row]).splitlines()[-1], flush=True)
    text = f"Machine: {machine()}\n\n" + table(rows)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "planning.md").write_text(text)
    print()
    print(text)


if __name__ == "__main__":
    main()
