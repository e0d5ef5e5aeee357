"""The planners against the brute-force oracle on random small models (section 8 semantics)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.bdd.synthesis import breaking
from planner.model.expression_text import parse_expr
from planner.model.expressions import Expr
from planner.model.flat import Model, TransitionKind
from planner.model.semantics import Semantics
from planner.planning.query import PlanQuery, PlanStatus
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model
from planner.reading.yaml_reader import ModelError, scope_for
from tests.support import oracle as O
from tests.support.strategies import flat_models, queries, query_extensions, random_atom

SETTINGS = settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def _load(model_dict: dict[str, Any]) -> Model:
    return load_model(yaml.safe_dump(model_dict, sort_keys=False), "random.yaml")


def _planner_or_cycle(model_dict: dict[str, Any]) -> TransitionPlanner | None:
    """The planner, or None after checking that planner and oracle agree on a cycle."""
    oracle_model = O.parse_model(model_dict)
    model = _load(model_dict)
    if O.has_automatic_cycle(oracle_model):
        with pytest.raises(ModelError, match="cycle forever"):
            TransitionPlanner(model)
        return None
    return TransitionPlanner(model)


def _query(model: Model, q: dict[str, Any], ext: dict[str, Any]) -> PlanQuery:
    scope = scope_for(model.domains)
    return PlanQuery(
        start=tuple(q["start"][v.name] for v in model.variables),
        goal=parse_expr(q["goal"], scope),
        max_steps=ext["max_steps"],
        maintenance=q["maintenance"],
        forbidden=tuple(parse_expr(f, scope) for f in ext["forbidden"]),
        always=parse_expr(ext["phi"], scope) if ext["phi"] is not None else None,
        disabled=frozenset(ext["disabled"]),
    )


@settings(SETTINGS, max_examples=300)
@given(data=st.data())
def test_plans_are_minimal_legal_and_agree_with_the_oracle(data: st.DataObject) -> None:
    model_dict = data.draw(flat_models())
    planner = _planner_or_cycle(model_dict)
    if planner is None:
        return
    q = data.draw(queries(model_dict))
    ext = data.draw(query_extensions(model_dict, q["start"]))
    if data.draw(st.booleans()):  # half the queries plain, as `sp plan` asks them
        ext = {"forbidden": [], "phi": None, "disabled": [], "max_steps": 10}
    query = _query(planner.model, q, ext)
    oracle_model = O.parse_model(model_dict)
    options: dict[str, Any] = {
        "maintenance": q["maintenance"],
        "forbidden": tuple(ext["forbidden"]),
        "phi": ext["phi"],
        "disabled": frozenset(ext["disabled"]),
    }
    expected = O.plan(oracle_model, query.start, q["goal"], max_steps=ext["max_steps"], **options)
    for engine in ("bdd", "sat"):
        result = planner.plan(query, engine=engine)
        assert result.status.value == expected.status, engine
        if result.status is PlanStatus.FOUND:
            assert result.length == expected.length, engine
            problem = O.replay(oracle_model, query.start, list(result.plan), q["goal"], **options)
            assert problem is None, f"{engine}: {problem}"
            assert result.states[0] == query.start
            assert len(result.states) == result.length + 1
        elif result.status is PlanStatus.BAD_START:
            assert list(result.violated) == expected.violated, engine


@SETTINGS
@given(data=st.data())
def test_plans_keep_what_they_are_told_to_keep(data: st.DataObject) -> None:
    """`PlanQuery.kept` (the causal links of the next operations, planner.runner.links):
    no state of a plan is one from which the world alone breaks a kept predicate.  The
    planners close each predicate over the uncontrollable transitions that can reach what it
    reads, which may keep out a few states more than the exact closure over the whole
    model: their plans avoid the oracle's states exactly, they never find a plan the oracle
    says does not exist, and both engines give the same answer."""
    model_dict = data.draw(flat_models())
    planner = _planner_or_cycle(model_dict)
    if planner is None:
        return
    oracle_model = O.parse_model(model_dict)
    q = data.draw(queries(model_dict))
    start = O.state_from_dict(oracle_model, q["start"])
    atoms = data.draw(st.lists(random_atom(model_dict["variables"]), min_size=1, max_size=3))
    held = [a for a in atoms if O.evaluate(oracle_model, a, start)]
    kept = tuple(held[:2] or atoms[:1])
    ext = {"forbidden": [], "phi": None, "disabled": [], "max_steps": 8}
    query = replace(_query(planner.model, q, ext), kept=_parsed(planner.model, kept))
    expected = O.plan(
        oracle_model, start, q["goal"], max_steps=8, maintenance=q["maintenance"], kept=kept
    )
    broken = [O.breaking(oracle_model, k) for k in kept]
    results = {engine: planner.plan(query, engine=engine) for engine in ("bdd", "sat")}
    assert results["bdd"].status == results["sat"].status
    assert results["bdd"].length == results["sat"].length
    for engine, result in results.items():
        if expected.status == "unreachable":
            assert result.status is not PlanStatus.FOUND, engine
        if expected.status == "bad_start":
            assert result.status is PlanStatus.BAD_START, engine
            assert set(expected.violated) <= set(result.violated), engine
        if result.status is PlanStatus.FOUND:
            assert expected.status == "found" and expected.length is not None, engine
            assert result.length >= expected.length, engine
            problem = O.replay(
                oracle_model, start, list(result.plan), q["goal"], maintenance=q["maintenance"]
            )
            assert problem is None, f"{engine}: {problem}"
            for state in result.states:
                assert not any(state in b for b in broken), (engine, state)
    for k, states in zip(kept, broken, strict=True):  # the planners' closure covers the exact one
        closure = breaking(planner.sym, parse_expr(k, scope_for(planner.model.domains)))
        assert all(planner.sym.contains(closure, s) for s in states), k  # type: ignore[arg-type]


def _parsed(model: Model, texts: tuple[str, ...]) -> tuple[Expr, ...]:
    scope = scope_for(model.domains)
    return tuple(parse_expr(t, scope) for t in texts)


@SETTINGS
@given(model_dict=flat_models())
def test_bad_states_equal_explicit_enumeration(model_dict: dict[str, Any]) -> None:
    planner = _planner_or_cycle(model_dict)
    if planner is None:
        return
    oracle_model = O.parse_model(model_dict)
    expected = O.bad_states(oracle_model)
    sym = planner.sym
    assert sym.count(planner.bad) == len(expected)
    for state in O.all_states(oracle_model):
        assert sym.contains(planner.bad, state) == (state in expected), state


@SETTINGS
@given(model_dict=flat_models())
def test_supervisor_guards_forbid_exactly_the_steps_into_bad_states(
    model_dict: dict[str, Any],
) -> None:
    planner = _planner_or_cycle(model_dict)
    if planner is None:
        return
    oracle_model = O.parse_model(model_dict)
    bad = O.bad_states(oracle_model)
    guarded = Semantics(planner.model, {g.transition: g.guard for g in planner.guards})
    plain = Semantics(planner.model)
    for state in O.all_states(oracle_model):
        if state in bad or plain.automatic_enabled(state):
            continue
        for with_guard, without in zip(guarded.transitions, plain.transitions, strict=True):
            if without.kind not in (TransitionKind.CONTROLLED, TransitionKind.MAINTENANCE):
                continue
            if not without.guard(state):
                continue
            leads_to_bad = without.apply(state) in bad
            assert with_guard.guard(state) == (not leads_to_bad), (without.name, state)


@SETTINGS
@given(data=st.data())
def test_reachable_states_equal_an_explicit_search(data: st.DataObject) -> None:
    model_dict = data.draw(flat_models())
    planner = _planner_or_cycle(model_dict)
    if planner is None:
        return
    oracle_model = O.parse_model(model_dict)
    bad = O.bad_states(oracle_model)
    start = data.draw(st.sampled_from(sorted(O.all_states(oracle_model), key=repr)))
    maintenance = data.draw(st.booleans())
    expected: set[tuple[object, ...]] = set()
    todo = [start] if start not in bad else []
    while todo:
        state = todo.pop()
        if state in expected:
            continue
        expected.add(state)
        todo += [
            s for _, s in O.steps(oracle_model, state, maintenance=maintenance) if s not in bad
        ]
    reached = planner.reachable(start, maintenance=maintenance)  # type: ignore[arg-type]
    assert planner.sym.count(reached) == len(expected)
    for state in expected:
        assert planner.sym.contains(reached, state)  # type: ignore[arg-type]


def test_plans_on_models_too_big_for_cudd_to_count() -> None:
    """Over 1,000 searched bits a plan carries no count of the states it reached: CUDD
    counts in doubles, which overflow beyond 2^1024 states.  One specification ties every
    flag together, so no reduction can leave the 1,100 bits out of the search."""
    flags = [f"f{k}" for k in range(1100)]
    text = yaml.safe_dump(
        {
            "variables": [{"name": f, "domain": "bool", "initial": False} for f in flags],
            "transitions": [
                {"name": "first", "guard": "!f0", "actions": ["f0 := true"]},
                {"name": "last", "guard": "f0 && !f1099", "actions": ["f1099 := true"]},
            ],
            "specifications": [
                {"name": "order", "invariant": "f1099 -> " + " || ".join(flags[:-1])}
            ],
        }
    )
    model = load_model(text, "big.yaml")
    planner = TransitionPlanner(model)
    goal = parse_expr("f1099", scope_for(model.domains))
    result = planner.plan(PlanQuery(tuple(False for _ in flags), goal, 5))
    assert result.status is PlanStatus.FOUND
    assert result.plan == ("first", "last")
    assert result.statistics["searched_bits"] == 1100
    assert "reached" not in result.statistics
