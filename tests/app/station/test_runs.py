"""The one definition of a run (app.station.runs): where the tracker says runs begin and end,
on the demo station's intentions, and over random sequences of rounds."""

from __future__ import annotations

from dataclasses import dataclass, field

from hypothesis import given
from hypothesis import strategies as st

from app.station.runs import Outcome, RunBoundary, RunTracker
from planner.reading import load_station
from planner.runner import Event, EventKind, IntentionState, StartIntention
from planner.words import Wording
from tests.support.paths import REPOSITORY

DEMO = REPOSITORY / "models" / "demo_station.yaml"
STATION = load_station(DEMO.read_text(), str(DEMO))
WORDS = Wording(STATION)
NAMES = [i.name for i in STATION.intentions]


@dataclass
class State:
    """What the tracker reads of a runner state: the intentions' states."""

    intentions: dict[str, IntentionState] = field(default_factory=dict)

    def busy_intentions(self) -> list[str]:
        busy = (IntentionState.EXECUTING, IntentionState.ERROR)
        return [n for n, s in self.intentions.items() if s in busy]


def changed(name: str, before: IntentionState, after: IntentionState) -> Event:
    return Event(0.0, EventKind.INTENTION, name, {"before": before, "after": after})


INIT, E, F, ERROR = (
    IntentionState.INITIAL,
    IntentionState.EXECUTING,
    IntentionState.FINISHED,
    IntentionState.ERROR,
)


def test_a_run_begins_with_a_start_on_an_idle_station_and_ends_when_it_finishes() -> None:
    name = NAMES[0]
    tracker = RunTracker(WORDS)
    start = StartIntention(user="ada", name=name)
    tick = [changed(name, INIT, E)]
    around = tracker.around(1.0, State({name: E}), tick, [start])  # type: ignore[arg-type]
    assert [e.kind for e in around] == [EventKind.RUN, EventKind.INTENTION]  # the run first
    began = around[0]
    assert began.subject == RunBoundary.STARTED and began.detail["intentions"] == [name]
    assert began.detail["why"] == f"ada started {WORDS.intention(name)} on an idle station"
    assert tracker.observe(2.0, State({name: E}), [], []) == []  # type: ignore[arg-type]
    tick = [changed(name, E, F)]
    around = tracker.around(3.0, State({name: F}), tick, [])  # type: ignore[arg-type]
    assert [e.kind for e in around] == [EventKind.INTENTION, EventKind.RUN]  # the end last
    ended = around[-1]
    assert ended.subject == RunBoundary.ENDED and ended.detail["outcome"] == Outcome.FINISHED
    assert ended.detail["why"] == f"{WORDS.intention(name)} finished"
    assert not tracker.open


def test_an_error_and_its_restart_stay_in_one_run_and_a_cancel_ends_it_cancelled() -> None:
    name = NAMES[0]
    tracker = RunTracker(WORDS)
    steps = [
        (State({name: E}), [changed(name, INIT, E)]),
        (State({name: ERROR}), [changed(name, E, ERROR)]),
        (State({name: E}), [changed(name, ERROR, INIT), changed(name, INIT, E)]),  # started again
        (State({name: INIT}), [changed(name, E, INIT)]),  # cancelled
    ]
    found = [e for state, tick in steps for e in tracker.observe(0.0, state, tick, [])]  # type: ignore[arg-type]
    assert [e.subject for e in found] == [RunBoundary.STARTED, RunBoundary.ENDED]
    assert found[-1].detail["outcome"] == Outcome.CANCELLED
    assert f"{WORDS.intention(name)} stopped" in found[-1].detail["why"]


def test_an_intention_that_starts_and_finishes_in_one_tick_is_a_run() -> None:
    """The state before and after show no busy intention; the tick's events do."""
    name = NAMES[0]
    tracker = RunTracker(WORDS)
    tick = [changed(name, INIT, E), changed(name, E, F)]
    found = tracker.observe(0.0, State({name: F}), tick, [])  # type: ignore[arg-type]
    assert [e.subject for e in found] == [RunBoundary.STARTED, RunBoundary.ENDED]
    assert found[0].detail["why"] == f"{WORDS.intention(name)} started on an idle station"


def test_a_reset_interrupts_an_open_run_only_and_a_restored_run_goes_on() -> None:
    name = NAMES[0]
    assert RunTracker(WORDS).interrupt(0.0, "E6 played") == []
    restored = RunTracker(WORDS, State({name: E}))  # type: ignore[arg-type]
    assert restored.open and restored.intentions == [name]
    (ended,) = restored.interrupt(5.0, "ada played the experiment E6")
    assert ended.detail["outcome"] == Outcome.INTERRUPTED
    assert ended.detail["why"] == "ada played the experiment E6"
    assert restored.stop(6.0, "time limit") == []


ROUND = st.lists(
    st.tuples(st.sampled_from(NAMES), st.sampled_from([INIT, E, F, ERROR])), max_size=3
)


@given(st.lists(ROUND, max_size=30))
def test_runs_alternate_begin_end_and_an_end_says_how(rounds: list[list[tuple[str, str]]]) -> None:
    """Whatever the intentions do: beginnings and ends alternate, an end comes exactly when
    no intention is busy any more, and it is finished only when all of the run's are."""
    tracker = RunTracker(WORDS)
    state = State({n: INIT for n in NAMES})
    said: list[str] = []
    for changes in rounds:
        tick = []
        for name, after in changes:
            tick.append(changed(name, state.intentions[name], IntentionState(after)))
            state.intentions[name] = IntentionState(after)
        for event in tracker.observe(0.0, state, tick, []):  # type: ignore[arg-type]
            said.append(event.subject)
            if event.subject == RunBoundary.ENDED:
                assert not state.busy_intentions()
                all_done = all(state.intentions[n] == F for n in event.detail["intentions"])
                assert (event.detail["outcome"] == Outcome.FINISHED) == all_done
        assert tracker.open == bool(state.busy_intentions())
    assert said == [RunBoundary.STARTED, RunBoundary.ENDED] * (len(said) // 2) + (
        [RunBoundary.STARTED] if len(said) % 2 else []
    )
