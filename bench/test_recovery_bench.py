"""Keeps the benchmark of every planning query honest: its scenarios load, a short play in a
child process becomes a row of the table, and a play cut off in a query says which.

No timing is asserted; the benchmark measures, this only checks that what it measures works.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from app.station.scenario import ScenarioError, load_scenario
from bench.runner import (
    BENCH_SCENARIOS,
    DEMO,
    describe_end,
    play_scenarios,
    queries_table,
    read_play,
    recovery_scenarios,
    target,
)
from planner.model.station import Station
from planner.reading import load_station

# a station small enough to synthesise in a blink: one bolt, placed and tightened
ONE_BOLT = """\
station: one_bolt
variables:
  - {name: bolt.state, domain: [empty, placed, tightened], kind: decision}
resources:
  - name: nr
    variables:
      - {name: run, domain: bool, kind: command}
      - {name: torque, domain: bool, kind: measured}
    abilities:
      - name: run_nut
        predicates:
          enabled: "!run && !torque"
          executing: "run && !torque"
          finished: "run && torque"
        transitions:
          - {name: start, guard: "enabled && bolt.state == placed", actions: ["run := true"]}
          - {name: torque, kind: effect, guard: executing, actions: ["torque := true"]}
          - {name: finish, kind: automatic, guard: finished,
             actions: ["run := false", "bolt.state := tightened"]}
          - {name: release, kind: effect, guard: "!run && torque", actions: ["torque := false"]}
  - name: operator
    abilities:
      - name: place_bolt
        transitions:
          - {name: start, guard: "bolt.state == empty", actions: ["bolt.state := placed"]}
operations:
  - {name: place, precondition: "bolt.state == empty", effects: ["bolt.state := placed"]}
  - {name: tighten, precondition: "bolt.state == placed", effects: ["bolt.state := tightened"]}
intentions:
  - {name: assemble, goal: "bolt.state == tightened"}
"""

# E3's recovery chain in small: time-out, operation and intention in error, maintenance
# planning, and the background check once a second
NEVER_TORQUE = """\
description: the nutrunner never reaches its torque
intentions: [assemble]
config: {effect_timeouts: {nr.run_nut.torque: 1.0}}
faults:
  - {at: 0, kind: block_effect, effect: nr.run_nut.torque}
until: 5
"""


@pytest.fixture(scope="module")
def demo() -> Station:
    return load_station(DEMO.read_text(), str(DEMO))


def test_bench_scenarios_load_and_each_has_a_time_limit(demo: Station) -> None:
    paths = sorted(BENCH_SCENARIOS.glob("*.yaml"))
    assert len(paths) >= 9
    for path in paths:
        text = path.read_text()
        scenario = load_scenario(text, str(path), demo)  # else file:line:column: what is wrong
        assert "until" in yaml.safe_load(text), f"{path.name}: it need not finish; give until"
        # something goes wrong: a fault, a person's action, slow devices, people or planning
        wrong = scenario.faults or scenario.actions or scenario.delays or scenario.planning_delay
        assert scenario.description and wrong, path.name
    played = recovery_scenarios(None)
    assert [p.stem.split("_")[0] for p in played[:9]] == [f"e{k}" for k in range(1, 10)]
    assert played[9:] == paths
    assert [p.stem for p in recovery_scenarios(["reject_oil"])] == [
        "reject_oil_filter_removal",
        "reject_oil_filter_removal_and_alternative",
    ]


def test_a_broken_bench_scenario_is_reported_at_its_line_and_column(demo: Station) -> None:
    path = BENCH_SCENARIOS / "double_both_robots_silent.yaml"
    text = path.read_text().replace("disconnect, resource: r2", "disconect, resource: r2")
    line = next(k for k, s in enumerate(text.splitlines(), 1) if "disconect" in s)
    column = text.splitlines()[line - 1].index("disconect") + 1
    with pytest.raises(ScenarioError) as raised:
        load_scenario(text, str(path), demo)
    assert str(raised.value).startswith(f"{path}:{line}:{column}: faults[1].kind: kind must be")


def test_a_short_play_in_a_child_process_becomes_a_row_of_the_table(tmp_path: Path) -> None:
    model = tmp_path / "one_bolt.yaml"
    model.write_text(ONE_BOLT)
    scenario = tmp_path / "never_torque.yaml"
    scenario.write_text(NEVER_TORQUE)
    rows, synthesis = play_scenarios([scenario], runs=2, limit=60.0, model=model)
    assert synthesis > 0
    [plays] = rows
    assert len(plays) == 2  # neither was cut off
    for play in plays:
        assert play.end == "stopped" and play.end_time == pytest.approx(5.1)
        announced = [q.label for q in play.queries if q.announced]
        assert announced == ["OP", "TP", "TP", "TP w/ETO", "OP w/DO", "TP w/ETO w/MT"]
        assert [q.recovery for q in play.queries if q.announced] == [False] * 3 + [True] * 3
        unannounced = [q for q in play.queries if not q.announced]
        assert {q.reason for q in unannounced} == {
            "which operations fail",
            "which intentions fail",
            "background check of an operation",
            "background check of an intention",
        }
        assert all(q.recovery and q.millis > 0 for q in unannounced)
        assert [q.time for q in play.queries] == sorted(q.time for q in play.queries)
    count = len(plays[0].queries)
    recovery = len(plays[0].recovery())
    unannounced_count = count - 6
    row = next(r for r in queries_table(rows).splitlines() if r.startswith("| never_torque |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1].startswith(
        "stopped at its time limit (5 s), waiting for engineer: nr.run_nut.torque ("
    )
    assert cells[2:4] == [
        "2",
        f"{count} ({recovery}; {unannounced_count})",
    ]
    assert cells[7] == "met" or cells[7].startswith("**not met**")


def test_a_play_cut_off_in_a_query_names_it_and_keeps_what_it_completed() -> None:
    def started(number: int, at: float, planner: str, purpose: str, clock: float) -> dict[str, Any]:
        return {"bench": "query", "id": number, "time": at, "planner": planner, "purpose": purpose,
                "clock": clock}  # fmt: skip

    plan = {"kind": "plan", "subject": "TP w/MT", "reason": "forbidden state", "status": "found"}
    records = [
        {"time": 0.0, "kind": "fault", "subject": "set"},
        started(0, 1.0, "TP", "forbidden-state recovery", 100.0),
        {"bench": "answer", "id": 0, "status": "found", "millis": 12.5},
        {"bench": "announced", "id": 0},
        {"time": 1.0, **plan, "millis": 12.5},
        started(1, 1.0, "OP", "background check of an intention", 100.0),
        {"bench": "answer", "id": 1, "status": "unreachable", "millis": 3.0},
        started(2, 1.1, "TP", "forbidden-state recovery", 101.0),
    ]
    lines = [json.dumps(r) for r in records] + ['{"bench": "answ']  # the line cut by the kill
    play = read_play(lines, "hangs", 60.0, cut=131.0)
    play.wall = 31.0
    assert play.end == "cut off" and play.end_time == 1.1
    assert [(q.label, q.reason, q.announced) for q in play.queries] == [
        ("TP w/MT", "forbidden state", True),
        ("OP", "background check of an intention", False),
    ]
    assert play.running == ("TP: forbidden-state recovery", 1.1, 30.0)
    assert describe_end(play) == (
        "**cut off** after 31 s wall, at 1.1 s of 60 s simulated: the next query "
        "(TP: forbidden-state recovery, at 1.1 s) ran over 30.0 s without finishing"
    )
    assert target([play]) == "**not met**: a query ran over 30.0 s"
