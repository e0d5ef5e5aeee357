"""Steps the partial order declares independent really commute (replayed in other orders)."""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench import family
from planner.model.expression_text import parse_expr
from planner.model.semantics import Semantics
from planner.planning.partial_order import Block, blocks, independent_operations
from planner.planning.query import PlanQuery
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model
from planner.reading.yaml_reader import scope_for
from tests.support import oracle as O
from tests.support.strategies import flat_models, queries


def _draw_order(data: st.DataObject, order: list[Block]) -> list[int]:
    """A random order of the blocks that the partial order allows (a topological order)."""
    done: list[int] = []
    remaining = list(range(len(order)))
    while remaining:
        ready = [k for k in remaining if order[k].after <= set(done)]
        chosen = data.draw(st.sampled_from(ready))
        done.append(chosen)
        remaining.remove(chosen)
    return done


@settings(
    max_examples=600,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(data=st.data())
def test_any_order_the_partial_order_allows_is_legal_and_ends_the_same(
    data: st.DataObject,
) -> None:
    model_dict: dict[str, Any] = data.draw(flat_models(max_vars=5, max_transitions=8))
    oracle_model = O.parse_model(model_dict)
    if O.has_automatic_cycle(oracle_model):
        return
    model = load_model(yaml.safe_dump(model_dict, sort_keys=False), "random.yaml")
    planner = TransitionPlanner(model)
    q = data.draw(queries(model_dict))
    start = tuple(q["start"][v.name] for v in model.variables)
    goal = parse_expr(q["goal"], scope_for(model.domains))
    result = planner.plan(PlanQuery(start, goal, max_steps=10, maintenance=q["maintenance"]))
    if not result.found or result.length < 2:
        return
    guards = {g.transition: g.guard for g in planner.guards}
    pending = Semantics(model).automatic_enabled(result.states[-1])
    order = blocks(model, result.plan, guards, automatic_at_end=pending)
    assert [s for b in order for s in b.steps] == list(result.plan)
    done = _draw_order(data, order)
    reordered = [s for k in done for s in order[k].steps]
    problem = O.replay(oracle_model, start, reordered, q["goal"], maintenance=q["maintenance"])
    assert problem is None, (done, problem)


# found by the random profile: t2 re-enables t3.auto at the plan's end, so t0 cannot follow it
PENDING_AT_THE_END = """
variables:
  - {name: a, domain: bool}
  - {name: b, domain: bool}
transitions:
  - {name: t0.cont, guard: "a == false", actions: ["a := true"]}
  - {name: t2.cont, guard: "b == true", actions: ["b := false"]}
  - {name: t3.auto, kind: automatic, guard: "b == false", actions: ["b := true"]}
"""


def test_a_block_that_leaves_an_automatic_transition_enabled_goes_last() -> None:
    model = load_model(PENDING_AT_THE_END, "pending.yaml")
    planner = TransitionPlanner(model)
    goal = parse_expr("a == true && b == false", scope_for(model.domains))
    result = planner.plan(PlanQuery((False, False), goal, max_steps=10))
    assert result.plan == ("t3.auto", "t0.cont", "t2.cont")
    assert Semantics(model).automatic_enabled(result.states[-1])
    order = blocks(model, result.plan, automatic_at_end=True)
    assert [b.transition for b in order] == ["t3.auto", "t0.cont", "t2.cont"]
    assert order[2].after == {0, 1}  # t3.auto is enabled at the end: t2's block last
    assert order[1].after == {0}
    # not told, the blocks of t0 and t2 look independent, and t0 after t2 fails
    assert blocks(model, result.plan)[2].after == {0}
    problem = O.replay(
        O.parse_model(yaml.safe_load(PENDING_AT_THE_END) | {"specifications": []}),
        (False, False),
        ["t3.auto", "t2.cont", "t0.cont"],
        "a == true && b == false",
    )
    assert problem is not None and "t0.cont" in problem


def _replay(planner: TransitionPlanner, start: tuple[object, ...], steps: list[str]) -> str | None:
    """Why `steps` is not a legal plan from `start` (section 8), or None."""
    semantics = Semantics(planner.model)
    state = start
    for i, name in enumerate(steps):
        problem = semantics.step_allowed(state, name)  # type: ignore[arg-type]
        if problem is not None:
            return f"step {i} ({name}): {problem}"
        state = semantics.by_name[name].apply(state)  # type: ignore[arg-type]
        if planner.sym.contains(planner.bad, state):  # type: ignore[arg-type]
            return f"step {i} ({name}) enters a bad state"
    return None


@pytest.fixture(scope="module")
def bolt_station() -> tuple[TransitionPlanner, PlanQuery, list[Block]]:
    model_dict = family.station(bolt_pairs=3, robots=2)
    model = load_model(yaml.safe_dump(model_dict, sort_keys=False), "family.yaml")
    planner = TransitionPlanner(model)
    goal = parse_expr(family.goal(3), scope_for(model.domains))
    query = PlanQuery(tuple(model.initial_values().values()), goal)
    result = planner.plan(query)
    assert result.found and result.length == 27
    return (
        planner,
        query,
        blocks(model, result.plan, {g.transition: g.guard for g in planner.guards}),
    )


PARALLEL = """
variables:
  - {name: r1.ref, domain: [home, bp1], kind: command}
  - {name: r1.pos, domain: [home, bp1], kind: measured}
  - {name: bin.state, domain: [empty, filled], kind: estimated}
  - {name: lamp.on, domain: bool, kind: command}
transitions:
  - {name: r1.goto_bp1, guard: "r1.pos == r1.ref && r1.ref == home", actions: ["r1.ref := bp1"]}
  - {name: r1.arrive, kind: effect, guard: "r1.pos != r1.ref", actions: ["r1.pos := r1.ref"]}
  - {name: operator.fill_bin, guard: "bin.state == empty", actions: ["bin.state := filled"]}
  - {name: lamp.switch_on, guard: "!lamp.on && bin.state == filled", actions: ["lamp.on := true"]}
specifications:
  - {name: lamp_only_at_bp1, invariant: "lamp.on -> r1.pos == bp1"}
"""


def test_steps_of_unrelated_resources_may_start_in_parallel() -> None:
    model = load_model(PARALLEL, "parallel.yaml")
    planner = TransitionPlanner(model)
    goal = parse_expr("r1.pos == bp1 && lamp.on", scope_for(model.domains))
    result = planner.plan(PlanQuery(tuple(model.initial_values().values()), goal))
    assert result.length == 4
    order = {b.transition: b for b in blocks(model, result.plan)}
    index = {b.transition: k for k, b in enumerate(blocks(model, result.plan))}
    # the robot's move and the operator's work share nothing; the lamp waits for the bin
    assert index["r1.goto_bp1"] not in order["operator.fill_bin"].after
    assert index["operator.fill_bin"] not in order["r1.goto_bp1"].after
    assert index["operator.fill_bin"] in order["lamp.switch_on"].after
    # the specification lets the lamp on only once the robot is at bp1
    assert index["r1.goto_bp1"] in order["lamp.switch_on"].after


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_reordered_station_plans_stay_legal(
    bolt_station: tuple[TransitionPlanner, PlanQuery, list[Block]], data: st.DataObject
) -> None:
    planner, query, order = bolt_station
    done = _draw_order(data, order)
    steps = [s for k in done for s in order[k].steps]
    assert _replay(planner, query.start, steps) is None
    final = Semantics(planner.model)
    state = query.start
    for name in steps:
        state = final.by_name[name].apply(state)  # type: ignore[arg-type]
    assert planner.sym.contains(planner.sym.expr(query.goal), state)  # type: ignore[arg-type]


def test_operations_with_disjoint_variables_are_independent() -> None:
    uses = {
        "place_bp1": frozenset({"bp1"}),
        "place_bp2": frozenset({"bp2"}),
        "tighten_bp1": frozenset({"bp1", "nr"}),
        "tighten_bp2": frozenset({"bp2", "nr"}),
    }
    plan = ["place_bp1", "place_bp2", "tighten_bp1", "tighten_bp2"]
    assert independent_operations(uses, plan) == [
        frozenset(),
        frozenset(),
        frozenset({0}),
        frozenset({1, 2}),
    ]
