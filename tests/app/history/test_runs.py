"""Runs found in a station's events (app.history.runs): where one starts and ends, how it ends, and
one clock across restarts."""

from __future__ import annotations

import itertools
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from app.history.runs import Happening, find_runs, on_one_clock, runs, seconds, within
from app.station.runs import Outcome


def intention(time: float, name: str, before: str, after: str, why: str = "") -> dict[str, Any]:
    detail = {"before": before, "after": after, "why": why}
    return {"time": time, "kind": "intention", "subject": name, "detail": detail}


def keyed(*items: dict[str, Any]) -> list[Happening]:
    return [Happening(key=k + 1, **item) for k, item in enumerate(items)]


def test_a_run_lasts_from_the_first_start_to_the_last_finish() -> None:
    found = keyed(
        {"time": 0.0, "kind": "taken", "subject": "before"},
        intention(1.0, "a", "i", "e"),
        intention(2.0, "b", "i", "e"),
        intention(5.0, "a", "e", "f"),
        intention(9.0, "b", "e", "f"),
        {"time": 10.0, "kind": "taken", "subject": "after"},
    )
    (run,) = find_runs(found)
    assert (run.first, run.last, run.start, run.end) == (2, 5, 1.0, 9.0)
    assert (run.intentions, run.outcome, run.cycle_time) == (("a", "b"), Outcome.FINISHED, 8.0)
    assert [h.key for h in within(found, run)] == [2, 3, 4, 5]


def test_an_error_started_again_goes_on_a_cancel_ends_cancelled() -> None:
    found = keyed(
        intention(1.0, "a", "i", "e"),
        intention(2.0, "a", "e", "error", "no plan"),
        intention(3.0, "a", "error", "i", "started again after an error"),
        intention(3.5, "a", "i", "e"),
        intention(6.0, "a", "e", "f"),
        intention(7.0, "b", "i", "e"),
        intention(8.0, "b", "e", "i", "cancelled by engineer"),
    )
    first, second = find_runs(found)
    assert (first.start, first.end, first.outcome) == (1.0, 6.0, Outcome.FINISHED)
    assert (second.start, second.end, second.outcome) == (7.0, 8.0, Outcome.CANCELLED)


def test_an_experiment_interrupts_and_the_last_run_may_still_be_running() -> None:
    found = keyed(
        intention(1.0, "a", "i", "e"),
        {"time": 4.0, "kind": "experiment", "subject": "E6"},
        intention(4.0, "a", "i", "e"),
        {"time": 6.0, "kind": "taken", "subject": "step"},
    )
    first, second = find_runs(found)
    assert (first.outcome, first.end) == (Outcome.INTERRUPTED, 4.0)
    assert (second.outcome, second.start, second.end) == (Outcome.RUNNING, 4.0, 6.0)


def test_a_log_that_begins_with_an_intention_in_error_has_its_run() -> None:
    found = keyed(intention(1.0, "a", "e", "error"), intention(4.0, "a", "error", "f"))
    (run,) = find_runs(found)
    assert (run.start, run.end, run.outcome) == (1.0, 4.0, Outcome.FINISHED)


def test_a_restarted_station_goes_on_from_its_last_time_and_runs_know_the_wall_time() -> None:
    found = [
        Happening(100.0, "intention", "a", {"after": "e"}, key=1, wall=1000.0),
        Happening(130.0, "taken", "x", key=2, wall=1030.0),
        Happening(0.5, "taken", "y", key=3, wall=1031.0),  # the process restarted
        Happening(10.5, "intention", "a", {"before": "e", "after": "f"}, key=4, wall=1041.0),
    ]
    times = [h.time for h in on_one_clock(found)]
    assert times == [100.0, 130.0, 130.0, 140.0]
    (run,) = find_runs(on_one_clock(found))
    assert run.cycle_time == 40.0
    assert run.wall(run.end) == 1040.0


def test_seconds_in_words() -> None:
    assert [seconds(12.44), seconds(185), seconds(3720)] == ["12.4 s", "3 min 05 s", "1 h 02 min"]


STATES = st.sampled_from(["i", "e", "f", "error"])


@st.composite
def intention_histories(draw: st.DrawFn) -> list[Happening]:
    """Random state changes of three intentions, with experiments between them."""
    found, time = [], 0.0
    for key in range(1, draw(st.integers(0, 40)) + 1):
        time += draw(st.floats(0, 5))
        if draw(st.integers(0, 9)) == 0:
            found.append(Happening(time, "experiment", "E1", key=key))
            continue
        name = draw(st.sampled_from(["a", "b", "c"]))
        detail = {"before": draw(STATES), "after": draw(STATES), "why": ""}
        found.append(Happening(time, "intention", name, detail, key=key))
    return found


@given(intention_histories())
def test_runs_are_in_order_and_never_overlap(found: list[Happening]) -> None:
    runs = find_runs(found)
    for run in runs:
        assert run.first <= run.last and run.start <= run.end
        assert run.intentions, "a run has the intention that started it"
    for earlier, later in itertools.pairwise(runs):
        assert earlier.last < later.first and earlier.end <= later.start
        assert earlier.outcome is not Outcome.RUNNING


def run_record(time: float, boundary: str, intentions: list[str], **more: str) -> dict[str, Any]:
    detail: dict[str, Any] = {"why": "", "intentions": intentions, **more}
    return {"time": time, "kind": "run", "subject": boundary, "detail": detail}


def test_recorded_runs_are_read_from_their_records_not_guessed_from_words() -> None:
    """A restart after an error whose cause is worded otherwise ("begun anew") is one run:
    the records say so, where the old heuristic looked for "again" in the words."""
    found = keyed(
        run_record(1.0, "started", ["a"]),
        intention(1.0, "a", "i", "e"),
        intention(2.0, "a", "e", "error", "no plan"),
        intention(3.0, "a", "error", "i", "begun anew by ada"),
        intention(3.0, "a", "i", "e"),
        intention(6.0, "a", "e", "f"),
        run_record(6.0, "ended", ["a"], outcome="finished"),
        run_record(7.0, "started", ["b"]),
        intention(7.0, "b", "i", "e"),
    )
    assert len(find_runs(found)) == 3  # the old way cuts the restart in two
    first, second = runs(found)
    assert (first.first, first.last, first.start, first.end) == (1, 7, 1.0, 6.0)
    assert (first.intentions, first.outcome) == (("a",), Outcome.FINISHED)
    assert [h.key for h in within(found, first)][1] == 2  # the intention's start is in it
    assert (second.outcome, second.start) == (Outcome.RUNNING, 7.0)


def test_a_log_from_before_run_records_is_read_the_old_way_up_to_the_first_record() -> None:
    found = keyed(
        intention(1.0, "a", "i", "e"),
        intention(2.0, "a", "e", "f"),
        intention(3.0, "b", "i", "e"),  # running when the station was upgraded
        run_record(4.0, "started", ["a"]),
        intention(4.0, "a", "i", "e"),
        run_record(5.0, "ended", ["a"], outcome="cancelled"),
    )
    old, cut, new = runs(found)
    assert (old.outcome, old.end) == (Outcome.FINISHED, 2.0)
    assert (cut.outcome, cut.end) == (Outcome.INTERRUPTED, 3.0)
    assert (new.outcome, new.start, new.end) == (Outcome.CANCELLED, 4.0, 5.0)
