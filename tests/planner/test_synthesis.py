"""Componentwise synthesis against the oracle and against the closure over the whole model.

Bad states are computed one component at a time (planner/bdd/synthesis.py explains why that is
exact although automatic transitions have priority over the whole model); these tests check
it on random models made of independent parts, where the decomposition actually splits.
"""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench import cells
from planner.bdd.symbolic import SymbolicModel
from planner.bdd.synthesis import backward_closure, bad_states, components, violated_by, violations
from planner.model.expressions import variables_of
from planner.model.flat import Model, TransitionKind
from planner.model.semantics import Semantics
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model, load_station
from planner.reading.yaml_reader import ModelError
from tests.support import oracle as O
from tests.support.paths import REPOSITORY
from tests.support.strategies import independent_models

DEMO = REPOSITORY / "models" / "demo_station.yaml"


def _load(model_dict: dict[str, Any]) -> Model:
    return load_model(yaml.safe_dump(model_dict, sort_keys=False), "parts.yaml")


def _monolithic(sym: SymbolicModel) -> Any:
    return backward_closure(sym, violations(sym, sym.model.specifications))


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(data=st.data())
def test_componentwise_bad_states_equal_the_oracle_and_the_whole_closure(
    data: st.DataObject,
) -> None:
    model_dict = data.draw(independent_models())
    oracle_model = O.parse_model(model_dict)
    model = _load(model_dict)
    if O.has_automatic_cycle(oracle_model):
        with pytest.raises(ModelError, match="cycle forever"):
            TransitionPlanner(model)
        return
    planner = TransitionPlanner(model)
    sym = planner.sym
    parts = [p for p in components(model) if p.variables]
    assert len(parts) >= len({v.name.split(".")[0] for v in model.variables})
    expected = O.bad_states(oracle_model)
    assert sym.count(planner.bad) == len(expected)
    for state in O.all_states(oracle_model):
        assert sym.contains(planner.bad, state) == (state in expected), state
    assert planner.bad == _monolithic(sym)
    states = sorted(O.all_states(oracle_model), key=repr)
    for state in data.draw(st.lists(st.sampled_from(states), max_size=4)):
        assert violated_by(sym, sym.state(state)) == O.violated(oracle_model, state), state


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(model_dict=independent_models())
def test_guards_read_over_the_written_parts_forbid_exactly_the_steps_into_bad_states(
    model_dict: dict[str, Any],
) -> None:
    oracle_model = O.parse_model(model_dict)
    if O.has_automatic_cycle(oracle_model):
        return
    planner = TransitionPlanner(_load(model_dict))
    model = planner.model
    bad = O.bad_states(oracle_model)
    guards = {g.transition: g.guard for g in planner.guards}
    guarded, plain = Semantics(model, guards), Semantics(model)
    for state in O.all_states(oracle_model):
        if state in bad or plain.automatic_enabled(state):
            continue
        for with_guard, without in zip(guarded.transitions, plain.transitions, strict=True):
            if without.kind is TransitionKind.CONTROLLED and without.guard(state):
                leads_to_bad = without.apply(state) in bad
                assert with_guard.guard(state) == (not leads_to_bad), (without.name, state)
    part_of = {name: p for p in components(model) for name in p.variables}
    for name, guard in guards.items():
        actions = model.transition(name).actions
        relevant = {v for a in actions for v in part_of[a.target].variables}
        relevant |= {a.source for a in actions if a.source is not None}
        assert variables_of(guard) <= relevant, name


def test_cells_split_into_one_component_each_and_keep_their_bad_states() -> None:
    station = load_station(cells.station_text(3), "cells_3.yaml")
    sym = SymbolicModel(station.model)
    parts = [p for p in components(station.model) if p.specifications]
    assert [sorted({v.split("_")[0] for v in p.variables}) for p in parts] == [
        ["c0"],
        ["c1"],
        ["c2"],
    ]
    bad = bad_states(sym)
    assert bad != sym.false
    assert bad == _monolithic(sym)


def test_the_demo_station_keeps_its_bad_states() -> None:
    """One large component: here the speed comes from closing each specification apart."""
    station = load_station(DEMO.read_text(), str(DEMO))
    sym = SymbolicModel(station.model)
    assert bad_states(sym) == _monolithic(sym)
