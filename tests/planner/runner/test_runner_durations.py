"""Plans that minimise the cycle from what the station has learned (DESIGN.md section 3.4).

Among operation plans of the minimal length the operation planner prefers the one of the
least expected makespan, with each operation's time learned from the station's own runs
(`app.history.durations`), the model's `duration` before any.  The test station has a job
either robot can do: in parallel the other robot looks faster, until the station has
learned that it is far slower.
"""

from __future__ import annotations

from collections.abc import Mapping

import pytest

from app.history.durations import Durations, learned
from app.station.player import Planners, play
from app.station.scenario import Scenario
from planner.model.station import Station
from planner.planning.makespan import expected_makespan, makespan
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import Event, EventKind, OperationState, RunnerConfig
from planner.runner.runner import Runner


def robot(name: str, jobs: list[str]) -> str:
    kinds = ", ".join(["idle", *[f"on_{j}" for j in jobs]])
    lines = [
        f"  - name: {name}",
        "    variables:",
        f"      - {{name: cmd, domain: [{kinds}], kind: command}}",
        *[f"      - {{name: {j}, domain: bool, kind: measured}}" for j in jobs],
        "    transitions:",
    ]
    for j in jobs:
        lines += [
            f'      - {{name: do_{j}, guard: "cmd == idle && !{j}", actions: ["cmd := on_{j}"]}}',
            f'      - {{name: did_{j}, kind: effect, guard: "cmd == on_{j} && !{j}",'
            f' actions: ["{j} := true"]}}',
            f'      - {{name: rest_{j}, kind: automatic, guard: "cmd == on_{j} && {j}",'
            f' actions: ["cmd := idle"]}}',
        ]
    return "\n".join(lines)


TWO_WAYS = f"""
station: two_ways
resources:
{robot("r1", ["x", "y"])}
{robot("r2", ["x"])}
operations:
  - {{name: y_by_r1, precondition: "r1.cmd == idle && !r1.y",
     effects: ["r1.y := true", "r1.cmd := idle"], duration: 2}}
  - {{name: x_by_r1, precondition: "r1.cmd == idle && !r1.x && !r2.x",
     effects: ["r1.x := true", "r1.cmd := idle"], duration: 2}}
  - {{name: x_by_r2, precondition: "r2.cmd == idle && !r1.x && !r2.x",
     effects: ["r2.x := true", "r2.cmd := idle"], duration: 2}}
intentions:
  - {{name: both, goal: "r1.y && (r1.x || r2.x)"}}
"""

INITIAL, EXECUTING = OperationState.INITIAL, OperationState.EXECUTING
R2_FAR = {"default": 1.0, "r2": 10.0}  # r2's work takes ten times r1's


def station() -> Station:
    return load_station(TWO_WAYS, "two_ways.yaml")


def play_two_ways(known: Mapping[str, float] | None = None) -> list[Event]:
    s = station()
    planners = Planners(TransitionPlanner(s.model), OperationPlanner(s))
    scenario = Scenario("two_ways.yaml", config=RunnerConfig(), delays=R2_FAR, until=120.0)
    return list(play(s, scenario, planners, learned=known))


def who_did_x(events: list[Event]) -> list[str]:
    return [
        e.subject
        for e in events
        if e.kind is EventKind.OPERATION
        and e.subject.startswith("x_by")
        and e.detail.get("before") == EXECUTING
        and e.detail.get("why") == "goal reached"
    ]


def test_makespan_follows_the_partial_order() -> None:
    plan = ["a", "b", "c"]
    after = [frozenset(), frozenset(), frozenset({0, 1})]
    assert makespan(plan, after, {"a": 2.0, "b": 5.0}, default=1.0) == 6.0
    assert makespan([], [], {}, default=1.0) == 0.0
    variables = {"a": frozenset({"v"}), "b": frozenset({"w"}), "c": frozenset({"v"})}
    # c shares v with a and waits for it; b runs beside them
    assert expected_makespan(variables, plan, {"a": 2.0, "b": 5.0, "c": 1.0}) == 5.0
    assert expected_makespan(variables, plan, {"a": 2.0, "b": 1.0, "c": 4.0}) == 6.0
    # an operation never timed counts as the median of those that were
    assert expected_makespan(variables, plan, {"a": 2.0, "b": 1.0}) == 3.5


def test_durations_are_the_median_of_the_last_finished_runs() -> None:
    def run(name: str, start: float, end: float, why: str = "goal reached") -> list[Event]:
        return [
            Event(start, EventKind.OPERATION, name, {"before": INITIAL, "after": EXECUTING}),
            Event(
                end, EventKind.OPERATION, name, {"before": EXECUTING, "after": INITIAL, "why": why}
            ),
        ]

    records = [
        *run("a", 0.0, 4.0),
        *run("a", 10.0, 12.0),
        *run("a", 20.0, 50.0),  # one slow run does not steer the plans
        *run("b", 0.0, 9.0, why="reset"),  # not finished: not timed
        Event(60.0, EventKind.OPERATION, "c", {"before": INITIAL, "after": EXECUTING}),
    ]
    assert learned(records) == {"a": 4.0}
    book = Durations(last=2)
    assert book.learn(records)
    assert book.medians() == {"a": 16.0}  # the last two only
    book.forget_starts()  # c's start is not carried across a restart
    assert not book.learn(
        [
            Event(
                70.0,
                EventKind.OPERATION,
                "c",
                {"before": EXECUTING, "after": INITIAL, "why": "goal reached"},
            )
        ]
    )


def test_the_model_s_estimates_until_the_station_has_learned() -> None:
    s = station()
    runner = Runner(s, TransitionPlanner(s.model), OperationPlanner(s), RunnerConfig())
    assert runner.durations() == {"y_by_r1": 2.0, "x_by_r1": 2.0, "x_by_r2": 2.0}
    runner.learned = {"x_by_r2": 10.0}
    assert runner.durations()["x_by_r2"] == 10.0


def test_learned_durations_choose_the_shorter_cycle() -> None:
    """By the model's estimates r2 does x beside r1's y; once learned that r2 takes ten
    times as long, r1 does both, one after the other, and the cycle is shorter."""
    first = play_two_ways()
    assert first[-1].kind is EventKind.DONE
    assert who_did_x(first) == ["x_by_r2"]
    known = learned(first)
    assert known["x_by_r2"] > 3 * known["x_by_r1" if "x_by_r1" in known else "y_by_r1"]
    second = play_two_ways(known)
    assert second[-1].kind is EventKind.DONE
    assert who_did_x(second) == ["x_by_r1"]
    assert second[-1].time < first[-1].time
    [planned] = [e for e in second if e.kind is EventKind.PLAN and "expected_cycle" in e.detail][:1]
    assert planned.detail["expected_cycle"] < known["x_by_r2"]


def test_learned_durations_ignored_is_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    """The planted fault: the planner given the model's estimates only."""
    monkeypatch.setattr(
        Runner, "durations", lambda self: {"y_by_r1": 2.0, "x_by_r1": 2.0, "x_by_r2": 2.0}
    )
    first = play_two_ways()
    second = play_two_ways(learned(first))
    assert who_did_x(second) == ["x_by_r2"]
    assert second[-1].time >= first[-1].time


def test_one_at_a_time_the_durations_do_not_matter() -> None:
    s = station()
    planners = Planners(TransitionPlanner(s.model), OperationPlanner(s))
    config = RunnerConfig(sequential=True)
    scenario = Scenario("two_ways.yaml", config=config, delays=R2_FAR, until=120.0)
    events = list(play(s, scenario, planners, learned={"x_by_r2": 10.0}))
    assert events[-1].kind is EventKind.DONE
    assert not [e for e in events if "expected_cycle" in e.detail]
