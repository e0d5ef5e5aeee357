"""Relaxed reachability (issue 27): the per-variable value boxes never rule out a goal that
some plan reaches, at any length; and they do rule out a goal cut off by a disabled effect,
at once."""

from __future__ import annotations

from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from planner.model.expression_text import parse_expr
from planner.model.flat import Model, TransitionKind
from planner.planning.query import PlanQuery, PlanStatus
from planner.planning.relaxed import goal_may_hold
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model
from planner.reading.yaml_reader import scope_for
from tests.planner.test_transition_planner import SETTINGS, _load, _query
from tests.support import oracle as O
from tests.support.strategies import flat_models, queries, query_extensions

ANY_LENGTH = 10_000  # past the number of states of every random model


def usable(model: Model, query: PlanQuery) -> list[Any]:
    return [
        t
        for t in model.transitions
        if t.name not in query.disabled
        and (query.maintenance or t.kind is not TransitionKind.MAINTENANCE)
    ]


@settings(SETTINGS, max_examples=200)
@given(data=st.data())
def test_a_goal_the_boxes_rule_out_has_no_plan_at_any_length(data: st.DataObject) -> None:
    model_dict = data.draw(flat_models())
    oracle_model = O.parse_model(model_dict)
    if O.has_automatic_cycle(oracle_model):
        return
    model = _load(model_dict)
    q = data.draw(queries(model_dict))
    ext = data.draw(query_extensions(model_dict, q["start"]))
    query = _query(model, q, ext)
    start = dict(zip((v.name for v in model.variables), query.start, strict=True))
    if goal_may_hold(query.goal, start, usable(model, query), query.always):
        return  # says nothing: the search decides
    expected = O.plan(
        oracle_model,
        query.start,
        q["goal"],
        max_steps=ANY_LENGTH,
        maintenance=q["maintenance"],
        phi=ext["phi"],
        disabled=frozenset(ext["disabled"]),
    )
    assert expected.status != "found", (q["goal"], expected)


CELL = """
variables:
  - {name: requested, domain: bool, initial: false, kind: command}
  - {name: locked, domain: bool, initial: false, kind: measured}
  - {name: tool, domain: [none, nr], initial: none, kind: command}
transitions:
  - {name: lock, guard: "!requested", actions: ["requested := true"]}
  - {name: lock_confirm, kind: effect, guard: "requested && !locked", actions: ["locked := true"]}
  - {name: take_tool, guard: "locked && tool == none", actions: ["tool := nr"]}
"""


def test_a_goal_behind_a_disabled_effect_is_unreachable_without_a_search() -> None:
    model = load_model(CELL, "cell.yaml")
    planner = TransitionPlanner(model)
    goal = parse_expr("tool == nr", scope_for(model.domains))
    start = tuple(v.initial for v in model.variables)
    working = planner.plan(PlanQuery(start, goal))
    assert working.found and working.plan == ("lock", "lock_confirm", "take_tool")
    broken = planner.plan(PlanQuery(start, goal, disabled=frozenset({"lock_confirm"})))
    assert broken.status is PlanStatus.UNREACHABLE
    assert broken.statistics == {"layers": 0, "relaxed": 1}  # ruled out before any layer
