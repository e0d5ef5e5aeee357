"""Keeps the runner benchmark from rotting: its generated cells load, plan and run to the end.

No timing is asserted; the benchmark measures, this only checks that what it measures works.
"""

from __future__ import annotations

from app.station.player import Planners
from bench import cells
from bench.runner import drive, match_paper
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import Event


def test_generated_cells_load_with_the_expected_size() -> None:
    station = load_station(cells.station_text(3), "cells_3.yaml")
    assert len(station.model.transitions) == 3 * cells.TRANSITIONS_PER_CELL
    assert [i.name for i in station.intentions] == ["cell_c0", "cell_c1", "cell_c2"]
    assert cells.cells_for(10_000) == 1000


def test_cell_intentions_run_to_completion_again_and_again() -> None:
    station = load_station(cells.station_text(2), "cells_2.yaml")
    planners = Planners(TransitionPlanner(station.model), OperationPlanner(station))
    names = [cells.intention(c) for c in cells.cell_names(2)]
    ticks = list(drive(station, planners, names, ticks=300, idle=10, cycle=True))
    assert len(ticks) == 300
    assert all(not t.plans for t in ticks[:10])
    labels = [label for t in ticks for label, _ in t.plans]
    # every cell cycle: an operation plan, then a transition plan for each of its 3 operations
    assert labels[:4] == ["OP", "TP", "TP", "TP"]
    assert labels.count("OP") >= 4  # both cells finished at least twice
    assert set(labels) == {"OP", "TP"}  # no recovery: nothing failed
    running = [t for t in ticks[10:] if not t.plans]
    assert len(running) > 200  # most ticks wait for effects without replanning


def test_paper_actions_are_matched_in_order() -> None:
    def plan(label: str) -> Event:
        level, *flags = label.replace(" w/", " ").split()
        return Event(0.0, "plan", label, {"level": level, "flags": flags})

    ours = [plan("TP w/ETO"), plan("TP w/MT"), plan("OP w/DO"), plan("TP w/ETO w/MT")]
    assert match_paper(["TP w/ETO", "OP w/DO", "TP w/MT"], ours) == [0, 2, 3]
    assert match_paper(["OP"], ours[:2]) == [None]
