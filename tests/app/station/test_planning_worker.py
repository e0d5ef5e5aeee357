"""Planning off the tick: the runner's queries answered by a worker process, the tick going
on meanwhile, a query past its budget answered as such."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.station.planning_worker import PlanningWorker
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import (
    Action,
    EnterRestart,
    EventKind,
    Inputs,
    LeaveRestart,
    Runner,
    RunnerConfig,
    StartIntention,
)
from tests.support.paths import MINI_STATION, REPOSITORY

MINI = MINI_STATION


@pytest.fixture(scope="module")
def mini() -> Station:
    return load_station(MINI.read_text(), str(MINI))


def worker(budget: float, delay: float) -> Iterator[PlanningWorker]:
    made = PlanningWorker(MINI.read_text(), str(MINI), None, budget=budget, delay=delay)
    try:
        deadline = time.monotonic() + 60
        while not made.ready and time.monotonic() < deadline:  # it builds its planners
            made.collect()
            time.sleep(0.05)
        assert made.ready
        yield made
    finally:
        made.close()


@pytest.fixture
def slow_worker() -> Iterator[PlanningWorker]:
    yield from worker(budget=30.0, delay=1.5)


@pytest.fixture
def impatient_worker() -> Iterator[PlanningWorker]:
    yield from worker(budget=0.5, delay=3.0)


def runner_with(station: Station, planning: PlanningWorker) -> Runner:
    config = RunnerConfig(auto_intentions=frozenset())
    planners = TransitionPlanner(station.model), OperationPlanner(station)
    return Runner(station, *planners, config, time.perf_counter, planning=planning)


def test_the_tick_goes_on_while_a_slow_query_runs(
    mini: Station, slow_worker: PlanningWorker
) -> None:
    """Each query takes 1.5 s; the ticks around them return at once, take people's actions
    and reply to them, and the plan is taken when its answer comes."""
    runner = runner_with(mini, slow_worker)
    heard = frozenset(r.name for r in mini.resources)
    state = runner.initial(0.0)
    actions: tuple[Action, ...] = (StartIntention(name="assemble"),)
    waited, replies, plans = 0, [], []
    now = 0.0
    deadline = time.monotonic() + 60
    while not plans and time.monotonic() < deadline:
        result = runner.tick(state, Inputs(heartbeats=heard, actions=actions), now)
        state, actions = result.state, ()
        replies += result.replies
        plans += [e for e in result.events if e.kind is EventKind.PLAN]
        if not plans:
            waited += 1
            if waited == 5:  # a person acts while the station waits for its plan
                actions = (EnterRestart(user="eve", reason="checking"),)
            if waited == 6:
                actions = (LeaveRestart(user="eve"),)
        time.sleep(0.05)
        now = round(now + 0.05, 6)
    assert plans and plans[0].subject == "OP" and plans[0].detail["status"] == "found"
    # ticks went on while the query was out: people's acts were taken and answered before
    # the plan came (how long a tick takes beside a worker: bench/runner.py)
    assert waited >= 7
    assert [r.accepted for r in replies] == [True, True, True]
    assert state.intentions["assemble"] == "e"


def test_a_query_past_its_budget_is_answered_as_such(
    mini: Station, impatient_worker: PlanningWorker
) -> None:
    runner = runner_with(mini, impatient_worker)
    heard = frozenset(r.name for r in mini.resources)
    state = runner.initial(0.0)
    actions: tuple[Action, ...] = (StartIntention(name="assemble"),)
    plans = []
    now = 0.0
    deadline = time.monotonic() + 30
    while not plans and time.monotonic() < deadline:
        result = runner.tick(state, Inputs(heartbeats=heard, actions=actions), now)
        state, actions = result.state, ()
        plans += [e for e in result.events if e.kind is EventKind.PLAN]
        time.sleep(0.05)
        now = round(now + 0.05, 6)
    assert plans and plans[0].detail["status"] == "over_budget"
    assert impatient_worker.replaced == 1


def test_the_worker_ends_when_its_station_is_killed(tmp_path: Path) -> None:
    """After `kill -9` of the station process no planning process is left behind."""
    script = tmp_path / "station.py"
    script.write_text(
        "import os, signal, sys, time\n"
        "from app.station.planning_worker import PlanningWorker\n"
        "if __name__ == '__main__':\n"
        f"    w = PlanningWorker(open({str(MINI)!r}).read(), 'mini', None)\n"
        "    while not w.ready:\n"
        "        w.collect(); time.sleep(0.05)\n"
        "    print(w.process.pid, flush=True)\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    root = REPOSITORY
    out = tmp_path / "pid"
    with out.open("w") as written:  # a file, not a pipe the worker would keep open
        run = subprocess.run([sys.executable, str(script)], cwd=root, stdout=written, timeout=120)
    assert run.returncode == -signal.SIGKILL
    pid = int(out.read_text().split()[0])
    deadline = time.monotonic() + 15
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(pid)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as stat:  # a zombie has ended; its parent did not reap it
        return stat.read().split()[2] != "Z"
