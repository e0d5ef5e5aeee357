"""CUDD's garbage collection policy, measured: on (CUDD's own thresholds), off, or off with a
collection every 100th query (the planner's policy before issue 11).

    python -m bench.gc_policy [--runs 3]

Two workloads, each in a fresh child process per run so that peak memory is the workload's
own: long searches (`sp plan`-like queries of the station family and the demo), and a
station's stream of small queries (the runner playing the nominal assembly and E6, E7, E9
against the simulated world).  Prints a Markdown table of median CPU seconds and peak MB and
writes it to bench/results/gc_policy.md.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

from bench.planning import machine

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
POLICIES = ("on", "off", "every 100")
SCENARIOS = ("nominal", "e6_r2_disconnects_above_engine", "e7_r2_disconnects_holding_tool")
SCENARIOS += ("e9_torque_not_reached",)

_CHILD = r"""
import json, resource, sys, time, yaml
from planner.planning.transition_planner import TransitionPlanner
policy, workload = sys.argv[1], sys.argv[2]

def with_policy(planner):
    if policy == "on":
        return planner
    planner.sym.bdd.configure(garbage_collection=False)
    if policy == "every 100":
        plan, count = planner.plan, [0]
        def counted(query, engine=None):
            count[0] += 1
            collect = count[0] % 100 == 0
            if collect:
                planner.sym.bdd.configure(garbage_collection=True)
            try:
                return plan(query, engine)
            finally:
                if collect:
                    planner.sym.bdd.configure(garbage_collection=False)
        planner.plan = counted
    return planner

if workload == "searches":
    from bench import family
    from planner.model.expressions import parse_expr
    from planner.reading.flat import scope_for
    from planner.planning.query import PlanQuery
    from planner.model.station import load_station
    cases = [(yaml.safe_dump(family.station(6, 2), sort_keys=False), family.goal(6))]
    cases.append((open("models/demo_station.yaml").read(), "bp1.state == tightened"))
    elapsed = 0.0
    for text, goal in cases:
        station = load_station(text, "model.yaml")
        planner = with_policy(TransitionPlanner(station.model))
        scope = scope_for(station.model.domains, station.predicates)
        start = tuple(station.model.initial_values().values())
        query = PlanQuery(start, parse_expr(goal, scope), disabled=station.restart_transitions)
        began = time.process_time()
        assert planner.plan(query).found
        elapsed += time.process_time() - began
else:
    from app.station.scenario import Planners, load_scenario, play
    from planner.planning.operation_planner import OperationPlanner
    from planner.model.station import load_station
    station = load_station(open("models/demo_station.yaml").read(), "demo.yaml")
    planners = Planners(with_policy(TransitionPlanner(station.model)), OperationPlanner(station))
    elapsed = 0.0
    for name in sys.argv[3:]:
        path = f"models/scenarios/{name}.yaml"
        scenario = load_scenario(open(path).read(), path, station)
        for event in play(station, scenario, planners, stopwatch=time.process_time):
            if event.kind == "plan" and event.millis is not None:
                elapsed += event.millis / 1000
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"seconds": elapsed, "peak_mb": peak}))
"""


def measure(policy: str, workload: str) -> dict[str, float]:
    command = [sys.executable, "-W", "ignore", "-c", _CHILD, policy, workload, *SCENARIOS]
    out = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=True)
    result: dict[str, float] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    lines = [
        f"Machine: {machine()}",
        "",
        "| policy | long searches: CPU s | peak MB | station queries: planning CPU s | peak MB |",
        "|---|---|---|---|---|",
    ]
    for policy in POLICIES:
        cells = []
        for workload in ("searches", "station"):
            runs = [measure(policy, workload) for _ in range(args.runs)]
            cells.append(f"{statistics.median(r['seconds'] for r in runs):.2f}")
            cells.append(f"{max(r['peak_mb'] for r in runs):.0f}")
        lines.append(f"| {policy} | " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "gc_policy.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
