"""Alarms: the ISA-18.2 state machine of the alarm book, and the conditions of real runs."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.station.alarms import (
    SHELVE_LIMIT,
    AlarmBook,
    AlarmChange,
    AlarmError,
    AlarmState,
    Condition,
    Priority,
    conditions,
)
from app.station.player import Planners, play
from app.station.scenario import ScheduledFault, load_scenario
from hw.simulated import Fault
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import Runner, RunnerState
from planner.words import Wording
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
SCENARIOS = ROOT / "models" / "scenarios"
T0 = 1_700_000_000.0  # seconds since the epoch

UNACKED, ACKED = AlarmState.UNACKED, AlarmState.ACKED
RTN_UNACKED, NORMAL, SHELVED = AlarmState.RTN_UNACKED, AlarmState.NORMAL, AlarmState.SHELVED


def cond(key: str, priority: Priority = Priority.HIGH, message: str = "") -> Condition:
    return Condition(key, priority, message or f"{key} is wrong", "r1")


def moves(changes: list[AlarmChange]) -> list[tuple[str, AlarmState | None, AlarmState]]:
    return [(c.key, c.before, c.after) for c in changes]


# -- the state machine ---------------------------------------------------------------------------


def test_a_condition_appearing_raises_an_unacknowledged_alarm_once() -> None:
    book = AlarmBook()
    changes = book.update({"a": cond("a")}, T0)
    assert moves(changes) == [("a", None, UNACKED)]
    assert changes[0].user is None and changes[0].note == "condition appeared"
    assert changes[0].at == T0 and changes[0].alarm.state is UNACKED
    alarm = book.alarm("a")
    assert alarm.active and alarm.raised_at == T0 and alarm.resource == "r1"
    assert book.update({"a": cond("a")}, T0 + 1) == []  # still there: nothing new
    assert book.active_count() == 1 and book.unacknowledged_count() == 1


def test_acknowledge_then_return_goes_to_normal_and_keeps_the_record() -> None:
    book = AlarmBook()
    book.update({"a": cond("a")}, T0)
    change = book.acknowledge("a", "ada", "called maintenance", T0 + 5)
    assert (change.before, change.after, change.user, change.note) == (
        UNACKED,
        ACKED,
        "ada",
        "called maintenance",
    )
    alarm = book.alarm("a")
    assert alarm.active and (alarm.acked_by, alarm.acked_at, alarm.note) == (
        "ada",
        T0 + 5,
        "called maintenance",
    )
    assert moves(book.update({}, T0 + 9)) == [("a", ACKED, NORMAL)]
    assert book.alarm("a").returned_at == T0 + 9 and not book.alarm("a").active
    assert book.alarms() == []  # normal alarms are history
    assert [a.key for a in book.alarms(include_normal=True)] == ["a"]


def test_return_before_acknowledge_waits_for_the_acknowledgement() -> None:
    book = AlarmBook()
    book.update({"a": cond("a")}, T0)
    assert moves(book.update({}, T0 + 1)) == [("a", UNACKED, RTN_UNACKED)]
    assert book.unacknowledged_count() == 1 and book.active_count() == 0
    change = book.acknowledge("a", "ada", "", T0 + 2)
    assert (change.before, change.after) == (RTN_UNACKED, NORMAL)


def test_reappearing_while_returned_unacknowledged_is_unacknowledged_again() -> None:
    book = AlarmBook()
    book.update({"a": cond("a")}, T0)
    book.update({}, T0 + 1)
    assert moves(book.update({"a": cond("a")}, T0 + 2)) == [("a", RTN_UNACKED, UNACKED)]
    alarm = book.alarm("a")
    assert alarm.active and alarm.raised_at == T0 + 2 and alarm.returned_at is None


def test_a_normal_alarm_raised_again_is_a_new_occurrence() -> None:
    book = AlarmBook()
    book.update({"a": cond("a")}, T0)
    book.acknowledge("a", "ada", "seen", T0 + 1)
    book.update({}, T0 + 2)
    assert moves(book.update({"a": cond("a")}, T0 + 3)) == [("a", NORMAL, UNACKED)]
    alarm = book.alarm("a")
    assert (alarm.acked_by, alarm.acked_at, alarm.note, alarm.raised_at) == (None, None, "", T0 + 3)


def test_priority_and_message_follow_the_condition_without_a_state_change() -> None:
    book = AlarmBook()
    book.update({"a": cond("a", Priority.LOW, "first")}, T0)
    assert book.update({"a": cond("a", Priority.CRITICAL, "worse")}, T0 + 1) == []
    alarm = book.alarm("a")
    assert (alarm.priority, alarm.message, alarm.state) == (Priority.CRITICAL, "worse", UNACKED)


@pytest.mark.parametrize(
    ("act", "message"),
    [
        (lambda b: b.acknowledge("nope", "ada", "", T0), "no alarm nope"),
        (
            lambda b: b.acknowledge("acked", "ada", "", T0),
            "the alarm “acked is wrong” is already acknowledged",
        ),
        (lambda b: b.acknowledge("normal", "ada", "", T0), "nothing to acknowledge"),
        (lambda b: b.acknowledge("new", " ", "", T0), "say who you are"),
        (lambda b: b.shelve("new", "ada", 0, "", T0), "shelve for 1 to 480 minutes, not 0"),
        (lambda b: b.shelve("new", "ada", -5, "", T0), "shelve for 1 to 480 minutes"),
        (lambda b: b.shelve("new", "ada", SHELVE_LIMIT + 1, "", T0), "1 to 480 minutes, not 481"),
        (lambda b: b.shelve("new", "ada", math.nan, "", T0), "shelve for 1 to 480 minutes"),
        (lambda b: b.unshelve("new", "ada", T0), "the alarm “new is wrong” is not shelved"),
        (lambda b: b.shelve("nope", "ada", 5, "", T0), "no alarm nope"),
    ],
)
def test_refused_requests_say_what_to_fix_and_change_nothing(
    act: Callable[[AlarmBook], object], message: str
) -> None:
    book = AlarmBook()
    book.update({"acked": cond("acked"), "normal": cond("normal")}, T0 - 10)
    book.acknowledge("acked", "ada", "", T0 - 9)
    book.acknowledge("normal", "ada", "", T0 - 9)
    book.update({"acked": cond("acked"), "new": cond("new")}, T0 - 8)
    before = book.alarms(include_normal=True, include_shelved=True)
    with pytest.raises(AlarmError, match=message):
        act(book)
    assert book.alarms(include_normal=True, include_shelved=True) == before


def test_acknowledging_twice_is_refused() -> None:
    book = AlarmBook()
    book.update({"a": cond("a")}, T0)
    book.acknowledge("a", "ada", "", T0)
    with pytest.raises(AlarmError, match="already acknowledged"):
        book.acknowledge("a", "bob", "", T0 + 1)
    assert book.alarm("a").acked_by == "ada"


def test_a_shelved_alarm_is_hidden_tracked_and_comes_back_when_the_shelve_expires() -> None:
    book = AlarmBook()
    book.update({"a": cond("a"), "b": cond("b")}, T0)
    change = book.shelve("a", "ada", 30, "chattering sensor", T0 + 1)
    assert (change.before, change.after, change.user, change.note) == (
        UNACKED,
        SHELVED,
        "ada",
        "chattering sensor",
    )
    alarm = book.alarm("a")
    assert (alarm.shelved_by, alarm.shelved_until, alarm.shelved_state) == (
        "ada",
        T0 + 1 + 30 * 60,
        UNACKED,
    )
    assert [a.key for a in book.alarms()] == ["b"]
    assert [a.key for a in book.alarms(include_shelved=True)] == ["b", "a"]  # b: unacked
    with pytest.raises(AlarmError, match="shelved; unshelve it"):
        book.acknowledge("a", "ada", "", T0 + 2)
    with pytest.raises(AlarmError, match="already shelved"):
        book.shelve("a", "ada", 5, "", T0 + 2)
    # the condition comes and goes while shelved: tracked, but no state change
    assert book.update({"b": cond("b")}, T0 + 3) == []
    assert not book.alarm("a").active and book.alarm("a").returned_at == T0 + 3
    assert book.update({"a": cond("a"), "b": cond("b")}, T0 + 4) == []
    assert book.alarm("a").active and book.alarm("a").state is SHELVED
    # one second before it runs out nothing happens; at the limit it comes back
    assert book.update({"a": cond("a"), "b": cond("b")}, T0 + 1 + 30 * 60 - 1) == []
    (expired,) = book.update({"a": cond("a"), "b": cond("b")}, T0 + 1 + 30 * 60)
    assert (expired.before, expired.after, expired.user, expired.note) == (
        SHELVED,
        UNACKED,
        None,
        "shelve expired",
    )
    assert expired.alarm.shelved_until is None


def test_an_inactive_alarm_comes_back_from_the_shelf_normal() -> None:
    book = AlarmBook()
    book.update({"a": cond("a")}, T0)
    book.shelve("a", "ada", SHELVE_LIMIT, "", T0)
    book.update({}, T0 + 1)
    (change,) = book.update({}, T0 + SHELVE_LIMIT * 60)
    assert (change.before, change.after) == (SHELVED, NORMAL)


def test_unshelving_by_hand_follows_the_condition() -> None:
    book = AlarmBook()
    book.update({"a": cond("a")}, T0)
    book.acknowledge("a", "ada", "", T0)
    book.shelve("a", "ada", 60, "", T0 + 1)
    change = book.unshelve("a", "bob", T0 + 2)
    # ISA-18.2: an active alarm leaves the shelf unacknowledged, whatever it was before
    assert (change.before, change.after, change.user) == (SHELVED, UNACKED, "bob")
    assert book.alarm("a").acked_by is None


def test_the_list_puts_active_unacknowledged_first_then_priority_then_newest() -> None:
    book = AlarmBook()
    book.update({"low": cond("low", Priority.LOW), "crit": cond("crit", Priority.CRITICAL)}, T0)
    everything = {
        "low": cond("low", Priority.LOW),
        "crit": cond("crit", Priority.CRITICAL),
        "high_old": cond("high_old"),
    }
    book.update(everything, T0 + 1)
    book.update({**everything, "high_new": cond("high_new")}, T0 + 2)
    book.acknowledge("crit", "ada", "", T0 + 3)
    book.update({**everything, "high_new": cond("high_new")}, T0 + 4)
    assert [a.key for a in book.alarms()] == ["high_new", "high_old", "low", "crit"]


def test_the_book_restored_from_its_rows_goes_on_the_same() -> None:
    book = AlarmBook()
    book.update({"a": cond("a"), "b": cond("b")}, T0)
    book.acknowledge("a", "ada", "", T0 + 1)
    book.shelve("b", "ada", 10, "", T0 + 1)
    rows = book.alarms(include_normal=True, include_shelved=True)
    again = AlarmBook(rows)
    rows[0].state = NORMAL  # the book keeps its own copies
    assert moves(again.update({}, T0 + 3600)) == moves(book.update({}, T0 + 3600))
    assert again.alarms(include_normal=True) == book.alarms(include_normal=True)
    with pytest.raises(AlarmError, match="two alarms with key a"):
        AlarmBook([*rows, rows[0]])


def test_acknowledge_all_answers_those_shown_that_still_wait_with_one_note() -> None:
    book = AlarmBook()
    book.update({"a": cond("a"), "b": cond("b"), "c": cond("c"), "d": cond("d")}, T0)
    book.acknowledge("b", "bob", "mine", T0 + 1)  # answered on another device meanwhile
    book.shelve("c", "bob", 10, "", T0 + 1)
    book.update({"a": cond("a"), "b": cond("b"), "c": cond("c")}, T0 + 2)  # d returns
    changes = book.acknowledge_all(["a", "b", "c", "d", "a", "gone"], "ada", "one note", T0 + 3)
    assert moves(changes) == [("a", UNACKED, ACKED), ("d", RTN_UNACKED, NORMAL)]
    assert {(c.user, c.note, c.at) for c in changes} == {("ada", "one note", T0 + 3)}
    assert book.alarm("b").acked_by == "bob" and book.alarm("b").note == "mine"
    assert book.alarm("c").state is SHELVED
    # the same page sent again, after an alarm was raised that it did not show: refused, and
    # the new alarm still waits
    book.update({"a": cond("a"), "b": cond("b"), "c": cond("c"), "e": cond("e")}, T0 + 4)
    with pytest.raises(AlarmError, match="nothing to acknowledge"):
        book.acknowledge_all(["a", "b", "c", "d"], "ada", "", T0 + 5)
    assert book.alarm("e").state is UNACKED and book.unacknowledged_count() == 1


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        ([], "nothing to acknowledge: no alarm was chosen"),
        (["gone", "x"], "nothing to acknowledge: no alarm gone, x"),
        (["acked", "shelved"], "they were acknowledged, shelved or closed meanwhile"),
    ],
)
def test_acknowledge_all_with_nothing_waiting_is_refused_and_changes_nothing(
    keys: list[str], message: str
) -> None:
    book = AlarmBook()
    book.update({"acked": cond("acked"), "shelved": cond("shelved"), "new": cond("new")}, T0)
    book.acknowledge("acked", "bob", "", T0)
    book.shelve("shelved", "bob", 5, "", T0)
    before = book.alarms(include_normal=True, include_shelved=True)
    with pytest.raises(AlarmError, match=message):
        book.acknowledge_all(keys, "ada", "", T0 + 1)
    with pytest.raises(AlarmError, match="say who you are"):
        book.acknowledge_all(["new"], "", "", T0 + 1)
    assert book.alarms(include_normal=True, include_shelved=True) == before


def test_the_end_of_a_run_closes_its_returned_alarms_and_keeps_what_is_active_or_shelved() -> None:
    book = AlarmBook()
    keys = ("returned", "returned_too", "active", "acked", "shelved_gone")
    book.update({k: cond(k) for k in keys}, T0)
    book.acknowledge("acked", "bob", "", T0 + 1)
    book.shelve("shelved_gone", "bob", 30, "", T0 + 1)
    book.update({"active": cond("active"), "acked": cond("acked")}, T0 + 2)
    why = "closed: the run it belonged to ended (ada played the experiment E6)"
    changes = book.end_run(why, T0 + 3)
    assert moves(changes) == [
        ("returned", RTN_UNACKED, NORMAL),
        ("returned_too", RTN_UNACKED, NORMAL),
    ]
    assert {(c.user, c.note, c.at) for c in changes} == {(None, why, T0 + 3)}
    states = {a.key: a.state for a in book.alarms(include_normal=True, include_shelved=True)}
    assert states == {
        "returned": NORMAL,
        "returned_too": NORMAL,
        "active": UNACKED,  # unacknowledged and active: never closed, never hidden
        "acked": ACKED,
        "shelved_gone": SHELVED,
    }
    assert [a.key for a in book.alarms()] == ["active", "acked"]
    assert book.end_run(why, T0 + 4) == []  # nothing left to close
    # the closed ones come back as new occurrences when their condition appears again
    assert moves(book.update({"returned": cond("returned")}, T0 + 5))[0] == (
        "returned",
        NORMAL,
        UNACKED,
    )


# -- the property: states always match the conditions, and every change is reported ---------------

KEYS = ("a", "b")
# what the book may report, by why it changed (ISA-18.2, as the module's docstring has it)
ALLOWED: dict[str, set[tuple[AlarmState | None, AlarmState]]] = {
    "condition appeared": {(None, UNACKED), (NORMAL, UNACKED), (RTN_UNACKED, UNACKED)},
    "condition cleared": {(UNACKED, RTN_UNACKED), (ACKED, NORMAL)},
    "seen": {(UNACKED, ACKED), (RTN_UNACKED, NORMAL)},  # acknowledged
    "shelved": {(s, SHELVED) for s in (UNACKED, ACKED, RTN_UNACKED, NORMAL)},
    "run ended": {(RTN_UNACKED, NORMAL)},  # closed, with the reason
}
steps = st.lists(
    st.one_of(
        st.tuples(st.just("set"), st.sampled_from(KEYS), st.booleans(), st.sampled_from(Priority)),
        st.tuples(st.just("ack"), st.sampled_from((*KEYS, "x"))),
        st.tuples(st.just("ack_all"), st.lists(st.sampled_from((*KEYS, "x")), max_size=3)),
        st.tuples(st.just("end_run")),
        st.tuples(st.just("shelve"), st.sampled_from(KEYS), st.sampled_from((0, 1, 5, 480, 481))),
        st.tuples(st.just("unshelve"), st.sampled_from(KEYS)),
        st.tuples(st.just("wait"), st.sampled_from((0.0, 1.0, 59.0, 300.0, 3600.0, 30_000.0))),
    ),
    max_size=40,
)


@settings(max_examples=500, deadline=None)
@given(steps)
def test_alarm_states_match_their_conditions_and_every_change_is_reported(
    script: list[tuple[object, ...]],
) -> None:
    book = AlarmBook()
    now = T0
    present: dict[str, Priority] = {}
    replayed: dict[str, AlarmState] = {}
    for step in script:
        changes: list[AlarmChange] = []
        before = {a.key: a for a in book.alarms(include_normal=True, include_shelved=True)}
        match step:
            case ("set", str(key), bool(on), Priority() as priority):
                if on:
                    present[key] = priority
                else:
                    present.pop(key, None)
            case ("wait", float(seconds)):
                now += seconds
            case ("ack", str(key)):
                state = before[key].state if key in before else None
                try:
                    changes.append(book.acknowledge(key, "ada", "seen", now))
                    assert state in (UNACKED, RTN_UNACKED)
                    assert changes[0].after is (ACKED if state is UNACKED else NORMAL)
                except AlarmError:
                    assert state not in (UNACKED, RTN_UNACKED)
            case ("ack_all", list(keys)):
                waiting = [k for k in dict.fromkeys(keys) if k in before and before[k].waiting]
                try:
                    changes += book.acknowledge_all(keys, "ada", "seen", now)
                    assert [c.key for c in changes] == waiting
                except AlarmError:
                    assert waiting == []
            case ("end_run",):
                returned = [k for k, a in sorted(before.items()) if a.state is RTN_UNACKED]
                changes += book.end_run("run ended", now)
                assert [c.key for c in changes] == returned
            case ("shelve", str(key), int(minutes)):
                try:
                    changes.append(book.shelve(key, "ada", minutes, "shelved", now))
                    assert 1 <= minutes <= SHELVE_LIMIT and before[key].state is not SHELVED
                except AlarmError:
                    assert (
                        key not in before
                        or not 1 <= minutes <= SHELVE_LIMIT
                        or (before[key].state is SHELVED)
                    )
            case ("unshelve", str(key)):
                try:
                    changes.append(book.unshelve(key, "ada", now))
                    assert before[key].state is SHELVED
                except AlarmError:
                    assert key not in before or before[key].state is not SHELVED
        if step[0] in ("set", "wait"):
            changes = book.update({k: cond(k, p) for k, p in present.items()}, now)
        for change in changes:  # replaying the changes gives the book's states
            assert change.before == replayed.get(change.key)
            assert change.alarm.state is change.after and change.at == now
            replayed[change.key] = change.after
            if change.note in ("shelve expired", "unshelved"):
                assert change.before is SHELVED
                assert change.after is (UNACKED if change.key in present else NORMAL)
            else:
                assert (change.before, change.after) in ALLOWED[change.note]
        alarms = book.alarms(include_normal=True, include_shelved=True)
        assert {a.key: a.state for a in alarms} == replayed
        for alarm in alarms:
            if step[0] in ("set", "wait"):
                assert alarm.active == (alarm.key in present)
            if alarm.state in (UNACKED, ACKED):
                assert alarm.active
            elif alarm.state in (RTN_UNACKED, NORMAL):
                assert not alarm.active
            else:
                assert alarm.shelved_until is not None and now < alarm.shelved_until
            if alarm.active and alarm.key in present:
                assert alarm.priority is present[alarm.key]


# -- conditions of real runs on the demo station ---------------------------------------------------


@pytest.fixture(scope="module")
def demo() -> tuple[Station, Planners]:
    station = load_station(MODEL.read_text(), str(MODEL))
    return station, Planners(TransitionPlanner(station.model), OperationPlanner(station))


def play_with_alarms(
    demo: tuple[Station, Planners],
    name: str,
    faults: tuple[ScheduledFault, ...] = (),
    acknowledge: bool = False,
) -> tuple[AlarmBook, list[AlarmChange], list[tuple[float, str, str]]]:
    """Play a scenario, feeding each tick's conditions to an alarm book; with `acknowledge`
    an operator acknowledges every new alarm at once.  Returns the book, its changes and the
    runner's events as (time, kind, subject)."""
    station, planners = demo
    path = SCENARIOS / f"{name}.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    scenario = replace(scenario, faults=scenario.faults + faults)
    runner = Runner(station, planners.transition, planners.operation, scenario.config)
    book, changes, ticks = AlarmBook(), [], [0]
    words = Wording(station)  # once: a wording is built from the whole model

    def watch(state: RunnerState) -> None:
        now = round(ticks[0] * 0.1, 6)  # play's clock: 0.1 s a tick
        ticks[0] += 1
        new = book.update(conditions(runner, state, words), now)
        changes.extend(new)
        if acknowledge:
            changes.extend(
                book.acknowledge(c.key, "operator", "", now) for c in new if c.after is UNACKED
            )

    events = [(e.time, e.kind, e.subject) for e in play(station, scenario, planners, watch=watch)]
    assert events[-1][1] == "done"
    return book, changes, events


def identifiers(station: Station) -> set[str]:
    """The model's names a person must not read: those with a digit, "_" or "." (r2, bp3.state,
    get_nr_r2), and "nr"; plain words such as "operator" are words."""
    model = station.model
    names = {r.name for r in station.resources} | {o.name for o in station.operations}
    names |= {i.name for i in station.intentions} | {s.name for s in model.specifications}
    names |= {v.name for v in model.variables} | {t.name for t in model.transitions}
    return {n for n in names if n == "nr" or re.search(r"[\d_.]", n)}


def assert_in_words(book: AlarmBook, station: Station) -> None:
    """Every alarm's message in people's words: no model identifier, no paper reference."""
    names = identifiers(station)
    for alarm in book.alarms(include_normal=True, include_shelved=True):
        tokens = set(re.findall(r"[A-Za-z_][\w.]*[\w]", alarm.message))
        assert not tokens & names, f"{alarm.key}: {alarm.message}"
        assert not re.search(r"seed \d|Figure|Table [IVX]", alarm.message), alarm.message


def test_e6_raises_r2_and_error_alarms_and_only_r2_stays(demo: tuple[Station, Planners]) -> None:
    book, changes, events = play_with_alarms(demo, "e6_r2_disconnects_above_engine")
    (lost,) = [t for t, kind, subject in events if (kind, subject) == ("unavailable", "r2")]
    (r2,) = [c for c in changes if c.key == "resource:r2"]
    assert (r2.after, r2.at, r2.alarm.priority, r2.alarm.resource) == (
        UNACKED,
        lost,
        Priority.HIGH,
        "r2",
    )
    assert r2.alarm.message.startswith("robot 2 is not answering") and "UR10" in r2.alarm.message
    raised = {c.key: c.alarm for c in changes if c.before is None}
    assert raised["operation:get_nr_r2"].priority is Priority.MEDIUM
    assert raised["operation:get_nr_r2"].message.startswith("robot 2 takes the nutrunner: in error")
    assert_in_words(book, demo[0])
    assert raised["intention:tighten_bolts"].priority is Priority.HIGH
    # production finished; r2 never answers again in E6, so its alarm alone is still active
    assert [a.key for a in book.alarms(include_normal=True) if a.active] == ["resource:r2"]
    assert {a.key: a.state for a in book.alarms()} == {
        "resource:r2": UNACKED,
        "intention:tighten_bolts": RTN_UNACKED,
        "operation:get_nr_r2": RTN_UNACKED,
        "operation:locate_tool_r1": RTN_UNACKED,
    }


def test_e6_with_r2_back_and_an_attentive_operator_ends_with_every_alarm_normal(
    demo: tuple[Station, Planners],
) -> None:
    back = ScheduledFault(Fault("reconnect", resource="r2"), at=33.0)  # after the maintenance
    book, changes, events = play_with_alarms(
        demo, "e6_r2_disconnects_above_engine", (back,), acknowledge=True
    )
    (lost,) = [t for t, kind, subject in events if kind == "unavailable" and subject == "r2"]
    assert lost < 33.0
    assert [c.at for c in changes if c.key == "resource:r2"] == [lost, lost, 33.0]
    assert book.active_count() == 0 and book.unacknowledged_count() == 0
    assert book.alarms() == [] and len(book.alarms(include_normal=True)) == 4


def test_e2_forbidden_state_is_critical_until_recovery(demo: tuple[Station, Planners]) -> None:
    book, changes, events = play_with_alarms(demo, "e2_oil_filter_early", acknowledge=True)
    (forbidden,) = [t for t, kind, _ in events if kind == "forbidden"]
    (recovered,) = [t for t, kind, _ in events if kind == "recovered"]
    assert moves(changes) == [
        ("forbidden", None, UNACKED),
        ("forbidden", UNACKED, ACKED),
        ("forbidden", ACKED, NORMAL),
    ]
    assert [c.at for c in changes] == [forbidden, forbidden, recovered]
    alarm = changes[0].alarm
    assert alarm.priority is Priority.CRITICAL
    assert "broken: oil filters only after every bolt pair is tightened" in alarm.message
    assert_in_words(book, demo[0])
    assert book.active_count() == 0


def test_timeouts_halts_and_lost_resources_are_alarms_with_their_resource(
    demo: tuple[Station, Planners],
) -> None:
    station, planners = demo
    runner = Runner(station, planners.transition, planners.operation)
    state = runner.initial()
    assert conditions(runner, state) == {}
    effect = runner.index.effects[0].name
    state.timed_out.add(effect)
    state.unavailable.add("nr")
    state.halted = "automatic transitions cycle"
    state.intentions["tighten_bolts"] = "e"
    state.operations["tighten_bp1"] = "error"
    state.failures["tighten_bp1"] = runner.config.retries
    found = conditions(runner, state)
    assert {k: (c.priority, c.resource) for k, c in found.items()} == {
        "halted": (Priority.CRITICAL, ""),
        "resource:nr": (Priority.HIGH, "nr"),
        "operation:tighten_bp1": (Priority.MEDIUM, "nr"),
        f"effect:{effect}": (Priority.LOW, runner.index.owner[effect]),
    }
    assert "did not happen in time" in found[f"effect:{effect}"].message
    assert "is not retried" in found["operation:tighten_bp1"].message
    # with no intention executing, an operation left in error waits harmlessly: no alarm
    state.intentions["tighten_bolts"] = "f"
    assert "operation:tighten_bp1" not in conditions(runner, state)


def test_a_dead_end_alarm_names_the_cause_and_whom_it_waits_for(
    demo: tuple[Station, Planners],
) -> None:
    """A camera that always misses: the intention's alarm says why (the misses), not only
    that no plan reaches its goal, and that it is the engineer's to decide."""
    station, planners = demo
    path = ROOT / "models" / "scenarios" / "faults" / "endless_camera_misses.yaml"
    scenario = replace(load_scenario(path.read_text(), str(path), station), until=40.0)
    runner = Runner(station, planners.transition, planners.operation, scenario.config)
    states: list[RunnerState] = []
    list(play(station, scenario, planners, watch=states.append))
    alarm = conditions(runner, states[-1])["intention:tighten_bolts"]
    assert "the scan found nothing happened instead of tools located" in alarm.message
    assert not set(re.findall(r"[\w.]+", alarm.message)) & identifiers(station), alarm.message
    assert "mend the cause, or decide in restart mode" in alarm.message


def test_a_silent_device_without_a_resource_raises_a_stale_values_alarm_in_words(
    demo: tuple[Station, Planners],
) -> None:
    station, planners = demo
    runner = Runner(station, planners.transition, planners.operation)
    state = runner.initial(0.0)
    why = "plc does not answer: no good answer for 1.2 s"
    state.stale = {"agv.engine": why, "bp1.state": why}
    found = conditions(runner, state)
    (stale,) = [c for c in found.values() if c.key.startswith("stale:")]
    assert stale.key == "stale:agv.engine,bp1.state" and stale.priority is Priority.HIGH
    assert stale.message.startswith("plc does not answer") and "bolt pair 1" in stale.message
    assert "bp1.state" not in stale.message
    state.stale = {}
    assert not [k for k in conditions(runner, state) if k.startswith("stale:")]
