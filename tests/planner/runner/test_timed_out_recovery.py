"""A recovery never waits on an effect that timed out (issue 28, point 1).

The nutrunner loses power while r1 stands on placed bolts (a forbidden state) and does not
start again: the first recovery waits for the motor; once that start times out it is
disabled in planning, so the recovery is made again without it (r1 moves up), and while the
station is in the forbidden state `waiting_for` names it, whoever the recovery waits on.
"""

from __future__ import annotations

from planner.runner import EventKind, Runner
from planner.runner.waiting import Who, waiting_for
from tests.support import plays

SPEC = "nutrunner_running_at_bp2"


def test_a_recovery_waiting_on_a_timed_out_effect_is_made_again_without_it() -> None:
    played = plays.played("nutrunner_power_cycled_on_bolts", states=True)
    events = played.events
    plans = [e for e in events if e.kind is EventKind.PLAN]
    recoveries = [e for e in plans if e.detail.get("reason") == "forbidden state"]
    assert recoveries[0].detail["plan"] == ["nr.run_nut.spin_up"]
    [timeout] = [e for e in events if e.kind is EventKind.TIMEOUT]
    assert timeout.subject == "nr.run_nut.spin_up"
    again = [e for e in recoveries if e.time >= timeout.time]
    assert again and again[0].time - timeout.time <= 0.5, [e.time for e in recoveries]
    assert "nr.run_nut.spin_up" not in again[0].detail["plan"]
    [recovered] = [e for e in events if e.kind is EventKind.RECOVERED]
    assert recovered.time > again[0].time
    # a recovery waits on a timed-out effect for one tick at most (the one that saw it)
    assert played.states is not None
    waiting = [
        s.recovery is not None and bool(s.recovery.expected() & s.timed_out) for s in played.states
    ]
    longest = run = 0
    for waits in waiting:
        run = run + 1 if waits else 0
        longest = max(longest, run)
    assert longest <= 1, longest
    last = events[-1]
    assert last.kind is EventKind.STOPPED
    assert [(w["who"], w["subject"]) for w in last.detail["waiting_for"]] == [
        ("engineer", "nr.run_nut.spin_up")
    ]


def test_waiting_for_names_the_forbidden_state_while_a_recovery_runs() -> None:
    station, planners = plays.demo()
    played = plays.played("nutrunner_power_cycled_on_bolts", states=True)
    runner = Runner(station, planners.transition, planners.operation, played.scenario.config)
    assert played.states is not None
    seen: dict[Who, str] = {}
    for state in played.states:
        if state.recovery is None:
            continue
        items = [w for w in waiting_for(runner, state) if w.subject == SPEC]
        assert len(items) == 1, state.now  # named whenever the station is in it
        seen.setdefault(items[0].who, items[0].what)
    assert "waits for nr.run_nut.spin_up" in seen[Who.DEVICE]
    assert "step 1: r1.goto_home" in seen[Who.OPERATOR]
