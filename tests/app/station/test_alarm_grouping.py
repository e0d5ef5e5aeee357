"""One fault, one alarm (`app.station.alarm_grouping`): consequences listed under their root,
first-out, start-up suppression, the escalation of a person waited for.  The root alarms of
E1-E9 and of the fault scenarios (`expect.alarms`) are checked where those are played
(tests/planner/runner/test_runner.py, tests/app/station/test_fault_scenarios.py)."""

from __future__ import annotations

from dataclasses import replace

from app.station.alarm_conditions import ESCALATE_AFTER
from app.station.alarm_grouping import STARTUP_GRACE, StartUp, rationalise
from app.station.alarms import AlarmBook, AlarmState, Condition, Priority, conditions
from planner.runner import Runner, RunnerState
from tests.support import plays


def cond(key: str, priority: Priority = Priority.MEDIUM, resource: str = "") -> Condition:
    return Condition(key, priority, f"words of {key}", resource)


def keep(book: AlarmBook, found: dict[str, Condition], now: float) -> dict[str, Condition]:
    alarms = rationalise(found, book.active())
    book.update(alarms, now)
    return alarms


def test_a_silent_robot_is_one_alarm_with_its_consequences_listed_under_it() -> None:
    book = AlarmBook()
    found = {
        "resource:r2": cond("resource:r2", Priority.HIGH, "r2"),
        "operation:get_nr_r2": cond("operation:get_nr_r2", resource="r2"),
        "operation:locate_tool_r1": cond("operation:locate_tool_r1", resource="r1"),
        "intention:tighten": cond("intention:tighten", Priority.HIGH),
        "effect:r2.goto.arrive": cond("effect:r2.goto.arrive", Priority.LOW, "r2"),
    }
    alarms = keep(book, found, 1.0)
    assert list(alarms) == ["resource:r2"]
    root = alarms["resource:r2"]
    assert set(root.grouped) == set(found) - {"resource:r2"}
    assert "words of operation:get_nr_r2" in root.consequences and root.priority is Priority.HIGH
    assert [a.key for a in book.alarms()] == ["resource:r2"]
    assert book.alarm("resource:r2").consequences == root.consequences


def test_without_a_cause_the_first_consequence_out_is_the_root_and_stays_it() -> None:
    book = AlarmBook()
    op = cond("operation:locate_tool_r1", resource="r1_cam")
    assert list(keep(book, {op.key: op}, 1.0)) == [op.key]
    later = {op.key: op, "intention:tighten": cond("intention:tighten", Priority.HIGH)}
    alarms = keep(book, later, 2.0)
    assert list(alarms) == [op.key]
    assert alarms[op.key].priority is Priority.HIGH  # the group's highest
    # the same tick: an operation is the nearer cause than the intention it serves
    fresh = AlarmBook()
    both = {"intention:a": cond("intention:a"), "operation:b": cond("operation:b")}
    assert list(keep(fresh, both, 1.0)) == ["operation:b"]


def test_consequences_outliving_their_root_stay_under_it() -> None:
    """A connector's lock that timed out is re-enabled when the plan moves on; the
    operation it put in error (retries spent) is still the same fault."""
    book = AlarmBook()
    effect = cond("effect:r1_tc.lock.connect", Priority.LOW, "r1")
    op = cond("operation:get_nr_r1", resource="r1")
    keep(book, {effect.key: effect, op.key: op}, 1.0)
    alarms = keep(book, {op.key: op}, 2.0)
    assert list(alarms) == [effect.key] and alarms[effect.key].grouped == (op.key,)
    assert book.alarm(effect.key).active
    assert list(keep(book, {}, 3.0)) == []
    assert not book.alarm(effect.key).active


def test_two_causes_are_two_alarms_and_a_consequence_goes_to_its_own_resource() -> None:
    book = AlarmBook()
    first = cond("resource:r1", Priority.HIGH, "r1")
    keep(book, {first.key: first}, 1.0)
    second = cond("resource:r2", Priority.HIGH, "r2")
    found = {
        first.key: first,
        second.key: second,
        "operation:get_nr_r2": cond("operation:get_nr_r2", resource="r2"),
        "intention:tighten": cond("intention:tighten", Priority.HIGH),
    }
    alarms = keep(book, found, 2.0)
    assert alarms["resource:r2"].grouped == ("operation:get_nr_r2",)
    assert alarms["resource:r1"].grouped == ("intention:tighten",)  # the first out
    assert book.first_out() == "resource:r1"


def test_a_device_still_starting_is_no_alarm_until_its_grace_is_over() -> None:
    state = RunnerState(values={}, intentions={}, operations={}, last_heard={"r1": 0.0, "r2": 0.0})
    startup = StartUp()
    state.unavailable = {"r1", "r2"}
    assert startup.quiet(state, 0.0) == {"r1", "r2"}
    state.last_heard["r1"] = 1.0  # r1 answered once, then went silent: that is a fault
    assert startup.quiet(state, 3.0) == {"r2"}
    found = {k: cond(k, Priority.HIGH, k[9:]) for k in ("resource:r1", "resource:r2")}
    assert list(rationalise(found, {}, startup.quiet(state, 3.0))) == ["resource:r1"]
    assert startup.quiet(state, STARTUP_GRACE) == frozenset()  # r2 never answered: now a fault
    startup.restart(40.0)  # an experiment puts the station back: devices start again
    assert startup.quiet(state, 41.0) == {"r1", "r2"}


def test_a_person_waited_for_through_the_reminders_is_an_alarm_to_the_shift() -> None:
    station, planners = plays.demo()
    runner = Runner(station, planners.transition, planners.operation)
    state = runner.initial(0.0)
    step = sorted(runner.index.person_effects)[0]
    state.effect_enabled_since[step] = 0.0
    state.reminded[step] = ESCALATE_AFTER - 1
    assert not [k for k in conditions(runner, state) if k.startswith("waiting:")]
    state.reminded[step] = ESCALATE_AFTER
    (waited,) = [c for k, c in conditions(runner, state).items() if k.startswith("waiting:")]
    assert waited.key == f"waiting:{step}" and waited.priority is Priority.MEDIUM
    assert "has waited 4 min for the operator" in waited.message
    assert waited.resource == runner.station.owner_of(step)


def test_the_book_keeps_the_group_through_a_restart() -> None:
    """The grouping lives in the alarm rows (a station restarted mid-fault keeps it)."""
    book = AlarmBook()
    effect = cond("effect:r1_tc.lock.connect", Priority.LOW, "r1")
    op = cond("operation:get_nr_r1", resource="r1")
    keep(book, {effect.key: effect, op.key: op}, 1.0)
    again = AlarmBook(replace(a) for a in book.alarms(include_normal=True))
    assert list(keep(again, {op.key: op}, 2.0)) == [effect.key]
    assert again.alarm(effect.key).state is AlarmState.UNACKED
