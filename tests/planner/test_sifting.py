"""The order after synthesis: independent blocks sifted apart, one block sifted as a whole."""

from __future__ import annotations

import yaml

from bench import cells
from planner.bdd.sifting import blocks
from planner.bdd.symbolic import SymbolicModel
from planner.bdd.synthesis import bad_states
from planner.planning.query import PlanQuery, PlanStatus
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model, load_station
from tests.support.paths import MINI_STATION

MINI = MINI_STATION


def _cell_runs(planner: TransitionPlanner) -> list[str]:
    """The cells in the order their bits come, one entry per run of a cell's bits."""
    sym = planner.sym
    owner = {b: v.name.split("_")[0] for v in planner.model.variables for b in sym.bits[v.name]}
    runs: list[str] = []
    for bit in planner.order():
        if not runs or runs[-1] != owner[bit]:
            runs.append(owner[bit])
    return runs


def test_independent_cells_are_sifted_apart_and_stay_together() -> None:
    station = load_station(cells.station_text(4), "cells_4.yaml")
    assert len(blocks(station.model)) == 4
    first, second = TransitionPlanner(station.model), TransitionPlanner(station.model)
    assert first.order() == second.order()  # deterministic
    assert sorted(_cell_runs(first)) == ["c0", "c1", "c2", "c3"]  # each cell's bits together
    assert first.bad == bad_states(first.sym)


def test_a_model_of_one_block_is_sifted_as_a_whole() -> None:
    station = load_station(MINI.read_text(), str(MINI))
    assert len(blocks(station.model)) == 1
    planner = TransitionPlanner(station.model)
    sym = SymbolicModel(station.model)
    bad_states(sym)
    sym.sift()
    assert planner.order() == sorted(sym.bdd.vars, key=sym.bdd.level_of_var)


def test_bits_declared_for_swaps_stay_with_their_block() -> None:
    """A transition that copies a variable it also writes gets primed bits (symbolic.py)."""
    text = yaml.safe_dump(
        {
            "variables": [
                {"name": "x", "domain": ["a", "b", "c"], "initial": "a"},
                {"name": "y", "domain": ["a", "b", "c"], "initial": "b"},
                {"name": "f", "domain": "bool", "initial": False},
                {"name": "g", "domain": "bool", "initial": False},
            ],
            "transitions": [
                {"name": "swap", "actions": ["x := y", "y := x"]},
                {"name": "flag", "guard": "!f", "actions": ["f := true", "g := f"]},
                {"name": "spread", "kind": "effect", "guard": "f && !g", "actions": ["g := true"]},
            ],
            "specifications": [{"name": "apart", "invariant": "x != c"}],
        }
    )
    model = load_model(text, "swap.yaml")
    planner = TransitionPlanner(model)
    sym, order = planner.sym, planner.order()
    assert len(order) == 2 * len(sym.state_bits)  # both transitions copy what they write
    for names in (("x", "y"), ("f", "g")):
        mine = {b for name in names for b in sym.bits[name]}
        at = [i for i, bit in enumerate(order) if bit.removesuffix("p") in mine]
        assert at == list(range(at[0], at[0] + 2 * len(mine))), names
    start = tuple(v.initial for v in model.variables)
    goal = planner.sym.model.transitions[0].guard  # `true`: any state
    assert planner.plan(PlanQuery(start, goal)).status is PlanStatus.FOUND
