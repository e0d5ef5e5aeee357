"""A run's timeline (app.history.timeline) and its drawing (app.history.timeline_drawing):
E6 played on the simulated station, and properties of random event sequences on the demo station."""

from __future__ import annotations

import itertools
import re
import xml.etree.ElementTree as ElementTree
from dataclasses import replace

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.history import timeline_drawing
from app.history.runs import Happening, Run, find_runs, from_events
from app.history.timeline import BarKind, Timeline, timeline
from app.history.timeline_data import Bar, Lane, LaneGroup
from app.station.player import Planners, play
from app.station.runs import Outcome
from app.station.scenario import load_scenario
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
E6 = ROOT / "models" / "scenarios" / "e6_r2_disconnects_above_engine.yaml"
T0 = 1_700_000_000.0


@pytest.fixture(scope="module")
def demo() -> Station:
    return load_station(MODEL.read_text(), str(MODEL))


@pytest.fixture(scope="module")
def e6(demo: Station) -> tuple[list[Happening], Run, Timeline]:
    planners = Planners(TransitionPlanner(demo.model), OperationPlanner(demo))
    scenario = load_scenario(E6.read_text(), str(E6), demo)
    found = [replace(h, wall=T0 + h.time) for h in from_events(play(demo, scenario, planners))]
    (run,) = find_runs(found)
    return found, run, timeline(found, demo, run)


def test_e6_r2_fails_waits_for_a_person_and_the_time_lost_is_its_silence(
    e6: tuple[list[Happening], Run, Timeline],
) -> None:
    _, run, found = e6
    r2 = [b for b in found.bars if b.lane == "r2"]
    kinds = {b.kind for b in r2}
    assert {BarKind.FAILED, BarKind.OUTAGE, BarKind.MAINTENANCE} <= kinds, kinds
    (failed,) = [b for b in r2 if b.kind is BarKind.FAILED]
    assert "no answer" in failed.title
    (mending,) = [b for b in r2 if b.kind is BarKind.MAINTENANCE]
    assert "move" in mending.title and "home" in mending.title
    assert found.lane("r2").label == "robot 2"
    causes = dict((loss.cause, loss.seconds) for loss in found.losses)
    assert causes.get("robot 2 stopped answering", 0) > 1.0, causes
    assert 0 < found.lost <= run.cycle_time


def test_e6_shows_operations_that_ran_at_once(
    e6: tuple[list[Happening], Run, Timeline],
) -> None:
    """Both robots busy in the same seconds (operations in parallel, section 3.4)."""
    _, run, found = e6
    most, together = found.at_once
    lanes = [lane for lane in found.lanes if lane.group is LaneGroup.OPERATIONS]
    assert 2 <= most <= len(lanes)
    assert 1.0 < together < run.cycle_time


def test_operations_back_to_back_are_not_at_once() -> None:
    run = Run(0, 9, 0.0, 10.0, ("a",), Outcome.FINISHED)
    lanes = (Lane("operations:x", "x", "x", LaneGroup.OPERATIONS),)

    def bar(start: float, end: float, kind: BarKind = BarKind.EXECUTING) -> Bar:
        return Bar("operations:x", start, end, "x", "x", kind)

    def at_once(*bars: Bar) -> tuple[int, float]:
        return Timeline(run, lanes, bars, (), ()).at_once

    assert at_once(bar(0, 2), bar(2, 4)) == (1, 0.0)
    assert at_once(bar(0, 3), bar(1, 4), bar(2, 5)) == (3, 3.0)
    assert at_once(bar(0, 3), bar(1, 4, BarKind.ERROR)) == (1, 0.0)
    assert at_once() == (0, 0.0)


def test_e6_labels_are_words_not_model_names(
    demo: Station, e6: tuple[list[Happening], Run, Timeline]
) -> None:
    _, _, found = e6
    names = {r.name for r in demo.resources} | {o.name for o in demo.operations}
    names |= {i.name for i in demo.intentions} | {t.name for t in demo.model.transitions}
    texts = [lane.label for lane in found.lanes] + [b.label for b in found.bars]
    texts += [b.title for b in found.bars] + [m.label for m in found.marks]
    texts += [loss.cause for loss in found.losses]
    names -= {"operator"}  # a resource named with a plain word: "the operator"
    for text in texts:
        words = set(re.findall(r"[\w.]+", text))
        assert not words & names, f"{text!r} names {words & names}"
        assert "seed" not in text and "w/" not in text, text


def test_the_drawing_of_e6_is_svg_with_a_time_of_day_axis_and_r2s_failure(
    e6: tuple[list[Happening], Run, Timeline],
) -> None:
    _, run, found = e6
    svg = str(timeline_drawing.draw(found, "E6"))
    root = ElementTree.fromstring(svg)  # well-formed
    assert root.get("viewBox", "").startswith(f"0 0 {timeline_drawing.WIDTH} ")
    assert 'data-kind="failed" data-lane="r2"' in svg
    assert 'data-kind="outage" data-lane="r2"' in svg
    assert timeline_drawing.time_of_day(run, run.start) in svg
    assert re.search(r">\d\d:\d\d:\d\d<", svg)
    rows = root.findall("{http://www.w3.org/2000/svg}g[@class='tl-row']") or [
        g for g in root.iter() if g.get("class") == "tl-row"
    ]
    assert len(rows) == len(found.lanes)


def test_row_labels_wrap_at_spaces() -> None:
    lines = timeline_drawing.wrapped("find the hanging tools with robot 1's camera", 20)
    assert lines == ["find the hanging", "tools with robot…"]
    assert timeline_drawing.wrapped("robot 2") == ["robot 2"]
    assert timeline_drawing.tick_step(45) == 5 and timeline_drawing.tick_step(3000) == 300


# -- properties on random event sequences -----------------------------------------------------


# fmt: off
EVENT_KINDS = [
    "taken", "taken", "effect", "unexpected", "timeout", "unavailable", "available",
    "operation", "intention", "plan", "instruction", "approval", "operator", "forbidden",
    "recovered", "restart",
]
# fmt: on


@st.composite
def histories(draw: st.DrawFn, station: Station) -> list[Happening]:
    """Random events of the kinds a timeline reads, about the station's own names."""
    transitions = [t.name for t in station.model.transitions]
    resources = [r.name for r in station.resources]
    operations = [o.name for o in station.operations]
    intentions = [i.name for i in station.intentions]
    states = st.sampled_from(["i", "e", "f", "error"])
    found: list[Happening] = [Happening(0.0, "intention", intentions[0], {"after": "e"}, key=1)]
    time = 0.0
    for key in range(2, draw(st.integers(1, 60)) + 2):
        time += draw(st.sampled_from([0.0, 0.1, 0.5, 1.0, 3.0]))
        kind = draw(st.sampled_from(EVENT_KINDS))
        detail: dict[str, object] = {}
        if kind in ("taken", "effect", "unexpected", "timeout", "instruction", "approval"):
            subject = draw(st.sampled_from(transitions))
            detail = {"type": draw(st.sampled_from(["controlled", "effect", "automatic"]))}
            detail["waited"] = draw(st.sampled_from([0.0, 2.0, 50.0]))
        elif kind in ("unavailable", "available"):
            subject = draw(st.sampled_from(resources))
            detail = {"silent_for": draw(st.sampled_from([0.0, 1.0, 100.0]))}
        elif kind in ("operation", "intention"):
            subject = draw(st.sampled_from(operations if kind == "operation" else intentions))
            detail = {"before": draw(states), "after": draw(states), "why": "because"}
        elif kind == "operator":
            subject, detail = "done", {"transition": draw(st.sampled_from(transitions))}
        elif kind == "plan":
            subject = "plan"
            detail = {"reason": draw(st.sampled_from(["maintenance", "error", "goals"]))}
            detail["status"] = draw(st.sampled_from(["found", "none"]))
        elif kind == "restart":
            subject = draw(st.sampled_from(["entered", "left"]))
        else:
            subject = "spec"
        found.append(Happening(time, kind, subject, detail, key=key))
    return found


DEMO = load_station(MODEL.read_text(), str(MODEL))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(histories(DEMO))
def test_bars_of_one_lane_never_overlap_and_time_lost_is_counted_once(
    found: list[Happening],
) -> None:
    for run in find_runs(found):
        drawn = timeline(found, DEMO, run)
        lanes = {lane.key for lane in drawn.lanes}
        for lane in lanes:
            busy = sorted(
                (b.start, b.end) for b in drawn.bars if b.lane == lane and b.kind.activity
            )
            for (_, end), (start, _) in itertools.pairwise(busy):
                assert end <= start + 1e-9, f"{lane}: {busy}"
        for bar in drawn.bars:
            assert bar.lane in lanes
            assert run.start <= bar.start <= bar.end <= run.end + 1e-9
        assert all(loss.seconds > 0 for loss in drawn.losses)
        assert len({loss.cause for loss in drawn.losses}) == len(drawn.losses)
        assert drawn.lost <= run.cycle_time + 1e-6
        most, together = drawn.at_once
        assert 0 <= together <= run.cycle_time + 1e-6 and (most >= 2 or together == 0)
        ElementTree.fromstring(str(timeline_drawing.draw(drawn, "random")))


# -- issue 29: outages at a run's start, routine cards, one cause for people -----------------


def _run_of(found: list[Happening]) -> Run:
    return Run(found[0].key, found[-1].key, 10.0, 40.0, ("tighten_bolts",), Outcome.FINISHED)


def test_an_outage_that_ended_before_the_run_is_not_its_own_and_one_across_its_start_counts_from_it(
    demo: Station,
) -> None:
    ended = [
        Happening(5.0, "unavailable", "r2", {"silent_for": 2.0}, key=1),
        Happening(8.0, "available", "r2", {}, key=2),
        Happening(10.0, "intention", "tighten_bolts", {"before": "i", "after": "e"}, key=3),
        Happening(40.0, "intention", "tighten_bolts", {"before": "e", "after": "f"}, key=4),
    ]
    drawn = timeline(ended, demo, _run_of(ended))
    assert drawn.losses == ()
    assert [b for b in drawn.bars if b.lane == "r2"] == []
    assert drawn.marks == ()  # nothing of the run before

    across = [
        Happening(5.0, "unavailable", "r2", {"silent_for": 2.0}, key=1),
        Happening(10.0, "intention", "tighten_bolts", {"before": "i", "after": "e"}, key=2),
        Happening(16.0, "available", "r2", {}, key=3),
        Happening(40.0, "intention", "tighten_bolts", {"before": "e", "after": "f"}, key=4),
    ]
    drawn = timeline(across, demo, _run_of(across))
    assert [(loss.cause, loss.seconds) for loss in drawn.losses] == [
        ("robot 2 stopped answering", 6.0)
    ]


def test_a_long_wait_on_a_routine_card_is_time_lost_waiting_for_a_person(demo: Station) -> None:
    """The operator took 105 s to place a bolt pair: reminded, the whole wait is lost; a
    maintenance step waits under the same cause, whoever it is for."""
    card = "operator.confirm"
    found = [
        Happening(10.0, "intention", "tighten_bolts", {"before": "i", "after": "e"}, key=1),
        Happening(45.0, "reminder", card, {"waited": 30.0}, key=2),
        Happening(75.0, "reminder", card, {"waited": 60.0}, key=3),
        Happening(120.0, "effect", card, {"type": "effect"}, key=4),
        Happening(130.0, "instruction", "operator.move_r2_home", {}, key=5),
        Happening(140.0, "operator", "done", {"transition": "operator.move_r2_home"}, key=6),
        Happening(150.0, "intention", "tighten_bolts", {"before": "e", "after": "f"}, key=7),
    ]
    run = Run(1, 7, 10.0, 150.0, ("tighten_bolts",), Outcome.FINISHED)
    drawn = timeline(found, demo, run)
    assert [(loss.cause, loss.seconds) for loss in drawn.losses] == [
        ("waiting for a person", 115.0)
    ]
