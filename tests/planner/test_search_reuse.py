"""A weighted query searches budget after budget (`SymbolicPlanner._search`); each search
reuses the layers of the one before for the counts they share (issue 27).  On random
structured models the reused search must be the fresh one, layer for layer."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import given, settings
from hypothesis import strategies as st

from planner.model.flat import TransitionKind
from planner.planning.search import Outcome, search
from tests.planner.test_reductions import SETTINGS, make_case, weigh_maintenance
from tests.support import strategies_structured as SS


@settings(SETTINGS, max_examples=60)
@given(data=st.data())
def test_a_search_that_reuses_a_smaller_budgets_layers_is_the_fresh_search(
    data: st.DataObject,
) -> None:
    structured = data.draw(SS.component_models(shortcuts=True))
    case = make_case(structured.model)
    if case is None:
        return
    q = weigh_maintenance(data, data.draw(SS.component_queries(structured)))
    planner = case.planners["default"]
    symbolic = planner._search
    query = case.query(q)
    sets = symbolic._sets(query)
    everything = frozenset(v.name for v in case.model.variables)
    problem = symbolic.problem(query, sets, everything, sets.goal)
    counted = frozenset(t.name for t in problem.transitions if t.kind is TransitionKind.MAINTENANCE)
    before: Outcome | None = None
    for budget in (1, 2, 3):
        bigger = replace(problem, counted=counted, budget=budget, cost=q["maintenance_cost"])
        fresh = search(planner.sym, bigger, keep=True)
        if before is not None:
            reused = search(planner.sym, bigger, before.kept, keep=True)
            assert reused == fresh  # found, plan, layers, exhausted
            assert reused.kept == fresh.kept  # every layer, each count, the same set
            assert reused.reached == fresh.reached
        before = fresh
