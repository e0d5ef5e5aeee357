"""Models are read and built in a child process within a budget (issue 26)."""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from app.station.model_budget import ModelBudget, ModelChecks, OverBudget
from tests.support.bombs import synthesis_bomb
from tests.support.stations import MODEL


def test_reading_in_the_child_finds_what_the_loader_finds() -> None:
    checks = ModelChecks(ModelBudget(read_seconds=30))
    assert checks.problems(MODEL.read_text(encoding="utf-8"), "demo") == []
    found = checks.problems("variables:\n  - {name: x, domain: bool}\ntransitions: 3\n", "m")
    assert found and found[0][:2] == (3, 14), found


def test_a_supervisor_past_its_time_is_refused_in_words_and_its_child_ended() -> None:
    checks = ModelChecks(ModelBudget(seconds=1.0))
    started = time.monotonic()
    with pytest.raises(OverBudget) as refused:
        checks.build(synthesis_bomb(), "model version 2", None)
    assert refused.value.message == "the supervisor is too large to build within 1 s"
    assert time.monotonic() - started < 30  # the child's start, then one second
    assert checks.slots.acquire(blocking=False)  # its slot is free again


def children_niceness(before: dict[int, int] | None = None) -> dict[int, int]:
    """Each model-budget child of this process (but those `before`), with its niceness."""
    found = {}
    for task in os.listdir("/proc"):
        try:
            with open(f"/proc/{task}/stat", encoding="ascii") as stat:
                parent = int(stat.read().rsplit(")", 1)[1].split()[1])
            with open(f"/proc/{task}/cmdline", "rb") as line:
                ours = b"app.station.model_budget" in line.read()
        except (OSError, ValueError):
            continue
        if parent == os.getpid() and ours and int(task) not in (before or {}):
            found[int(task)] = os.getpriority(os.PRIO_PROCESS, int(task))
    return found


def test_the_children_run_below_the_station_loop_on_all_cores_but_one() -> None:
    """What lets the station's loop come first on a busy machine (the model bombs test takes
    out the time its loop waits for a CPU): a reading child and a building child run at
    niceness 10, and at most one per core but one at once."""
    assert ModelBudget().at_once == max(1, len(os.sched_getaffinity(0)) - 1)
    checks = ModelChecks(ModelBudget(seconds=3.0, read_seconds=30))
    mine, before = os.getpriority(os.PRIO_PROCESS, 0), children_niceness()
    try:
        assert checks.problems(MODEL.read_text(encoding="utf-8"), "demo") == []
        (reader,) = children_niceness(before).values()  # kept for the next read
        assert reader == min(19, mine + 10)
        with ThreadPoolExecutor(1) as pool:
            building = pool.submit(checks.build, synthesis_bomb(), "model version 2", None)
            deadline, niced = time.monotonic() + 60, min(19, mine + 10)
            while list(children_niceness(before).values()) != [niced, niced]:
                assert time.monotonic() < deadline, children_niceness(before)  # niced at start
                assert not building.done()  # the reader and the building child, both niced
                time.sleep(0.05)
            with pytest.raises(OverBudget):
                building.result()
    finally:
        checks.close()
