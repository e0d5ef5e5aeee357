"""Every engine and every reduction against the brute-force oracle (issue 11, point 2).

The bdd engine plans a query part by part (`Reductions.parts`: independent components,
frozen when untouched, concatenated in an order that keeps the sum minimal, or planned
jointly when no such order exists), on each part's cone of influence (`cone`), and with
`symmetry` on one state per orbit of interchangeable objects.  Each reduction is exact, so
every combination must give the oracle's status and minimal length and a legal plan; and
each must actually happen where the model's structure says it must.

`Expected` below is an independent reading of `planner.planning.relevance`'s docstring: the
components are computed here from the model and the query alone, each active component is
planned by the oracle on its own sub-model, and from those plans it follows how many parts
the engine reports and how many bits it searches.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import event as record_event
from hypothesis import note as record_note
from hypothesis import strategies as st
from hypothesis.control import currently_in_test_context

from planner.model.expression_text import parse_expr
from planner.model.flat import Model, TransitionKind
from planner.planning.query import PlanQuery, PlanResult, PlanStatus
from planner.planning.symbolic_planner import Reductions
from planner.planning.symmetry import find_symmetries
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model
from planner.reading.yaml_reader import ModelError, scope_for
from tests.support import oracle as O
from tests.support import strategies_structured as SS
from tests.support.reductions_oracle import (
    UNCONTROLLABLE,
    Expected,
    bits_of,
    expected_structure,
    explicit_swap,
    rename,
    touches,
)

REDUCTIONS = {
    "default": Reductions(),
    "no parts": Reductions(parts=False),
    "no cone": Reductions(cone=False),
    "symmetry": Reductions(symmetry=True),
    "none": Reductions(parts=False, cone=False),
}

SETTINGS = settings(
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
QUERIES_PER_MODEL = 3  # the planners are built once per model: ask each several queries


def event(text: str) -> None:
    """Coverage for `--hypothesis-show-statistics`; the hand-made examples share the
    checks, outside any hypothesis test."""
    if currently_in_test_context():
        record_event(text)


def note(text: str) -> None:
    if currently_in_test_context():
        record_note(text)


# --------------------------------------------------------------------------- the case


@dataclass
class Case:
    """A model as the planners and the oracle read it, with one planner per reduction."""

    spec: dict[str, Any]
    model: Model
    oracle: O.OracleModel
    planners: dict[str, TransitionPlanner]

    def query(self, q: dict[str, Any]) -> PlanQuery:
        scope = scope_for(self.model.domains)
        return PlanQuery(
            start=tuple(q["start"][v.name] for v in self.model.variables),
            goal=parse_expr(q["goal"], scope),
            max_steps=q["max_steps"],
            maintenance=q["maintenance"],
            forbidden=tuple(parse_expr(f, scope) for f in q["forbidden"]),
            always=parse_expr(q["phi"], scope) if q["phi"] is not None else None,
            disabled=frozenset(q["disabled"]),
            relaxed=frozenset(q.get("relaxed", ())),
            maintenance_cost=q.get("maintenance_cost", 1),
        )


def oracle_options(q: dict[str, Any]) -> dict[str, Any]:
    return {
        "maintenance": q["maintenance"],
        "forbidden": tuple(q["forbidden"]),
        "phi": q["phi"],
        "disabled": frozenset(q["disabled"]),
        "relaxed": frozenset(q.get("relaxed", ())),
    }


def make_case(spec: dict[str, Any]) -> Case | None:
    """The case, or None after checking that planner and oracle agree on a cycle."""
    oracle = O.parse_model(spec)
    model = load_model(yaml.safe_dump(spec, sort_keys=False), "structured.yaml")
    if O.has_automatic_cycle(oracle):
        with pytest.raises(ModelError, match="cycle forever"):
            TransitionPlanner(model)
        event("model: automatic cycle (rejected by both)")
        return None
    planners = {name: TransitionPlanner(model, reductions=r) for name, r in REDUCTIONS.items()}
    return Case(spec, model, oracle, planners)


def visited(case: Case, start: O.State, plan: Iterable[str], q: dict[str, Any]) -> list[O.State]:
    """The states a plan visits, by the oracle's steps."""
    states = [start]
    for name in plan:
        possible = dict(
            O.steps(
                case.oracle,
                states[-1],
                maintenance=q["maintenance"],
                disabled=frozenset(q["disabled"]),
            )
        )
        states.append(possible[name])
    return states


def check_result(
    case: Case, q: dict[str, Any], result: PlanResult, expected: O.OracleResult, label: str
) -> None:
    """Status, minimal length, a legal replay and the visited states; for bad starts the
    violated list."""
    query = case.query(q)
    options = oracle_options(q)
    assert result.status.value == expected.status, label
    if result.status is PlanStatus.FOUND:
        assert result.length == expected.length, label
        problem = O.replay(case.oracle, query.start, list(result.plan), q["goal"], **options)
        assert problem is None, f"{label}: {problem}"
        assert result.states[0] == query.start, label
        assert len(result.states) == result.length + 1, label
        assert list(result.states) == visited(case, query.start, result.plan, q), label
        if expected.maintenance_steps is not None:
            steps = O.maintenance_steps(case.oracle, list(result.plan))
            assert steps == expected.maintenance_steps, label
    elif result.status is PlanStatus.BAD_START:
        if query.relaxed:
            # why recovery cannot start: a kept specification violated directly, or a
            # forbidden predicate; the planner lists every specification the start is bad
            # for (the relaxed ones too), which must include those
            names = set(O.violated(case.oracle, query.start))
            names |= {f"forbidden[{i}]" for i in range(len(q["forbidden"]))}
            assert set(expected.violated) <= set(result.violated) <= names, label
        else:
            assert list(result.violated) == expected.violated, label


# --------------------------------------------------------------------------- the structure


def structure(case: Case, q: dict[str, Any]) -> Expected:
    return expected_structure(case.model, case.oracle, case.query(q))


def check_structure(case: Case, q: dict[str, Any], results: dict[str, PlanResult]) -> Expected:
    """The reductions happen where the structure says they must."""
    model = case.model
    expected = structure(case, q)
    total = bits_of(model, [v.name for v in model.variables])
    event(f"components: {len(expected.components)}, active: {len(expected.active)}")
    if not expected.searches:
        return expected
    if len(expected.active) < len(expected.components):
        event("parts: a component is frozen")
    if expected.busy:
        event("parts: an automatic is enabled at the start of an active part")
    if expected.fallback:
        event("parts: joint fallback (no order keeps the sum minimal)")
    elif expected.parts > 1:
        event("parts: concatenated in order")
    if expected.unsettled and not expected.fallback:
        event("parts: one part ends with an automatic enabled (planned last)")
    note(f"expected structure: {expected}")
    for name, result in results.items():
        if not result.found:
            # a part that cannot reach its goal ends the query before the others are searched
            # (found in random mode: 1 of 4 bits searched, no part count), so an unreachable
            # answer says nothing about where the search would have gone
            continue
        statistics = result.statistics
        reductions = REDUCTIONS[name]
        if not reductions.parts:
            assert statistics["parts"] == 1, name
            assert statistics["searched_bits"] <= total, name
            if not reductions.cone:
                assert statistics["searched_bits"] == total, name
            continue
        assert statistics["parts"] == expected.parts, name
        if reductions.cone:
            assert statistics["searched_bits"] <= expected.bits, name
        else:
            assert statistics["searched_bits"] == expected.bits, name
    if results["default"].found:
        default = results["default"].statistics["searched_bits"]
        if default < expected.bits:
            event("cone: dropped bits of an active part")
        if default < total:
            event("searched fewer bits than the model has")
    lengths = expected.lengths
    if expected.parts > 1 and None not in lengths and q.get("maintenance_cost", 1) == 1:
        # the theorem the parts reduction rests on: the sum of the parts is the minimum
        total_length = sum(n for n in lengths if n is not None)
        whole = results["none"]
        if total_length <= q["max_steps"]:
            assert whole.found and whole.length == total_length
        else:
            assert not whole.found
    return expected


Excuse = Callable[[Case, dict[str, Any], str, PlanResult, O.OracleResult], str | None]


def plan_everywhere(
    case: Case, q: dict[str, Any], excuse: Excuse | None = None
) -> dict[str, PlanResult]:
    """The query on every reduction (and, when the query allows, on the sat engine),
    each checked against the oracle unless `excuse` names a known bug it shows."""
    query = case.query(q)
    options = oracle_options(q)
    expected = O.plan(
        case.oracle,
        query.start,
        q["goal"],
        max_steps=query.max_steps,
        maintenance_cost=query.maintenance_cost,
        **options,
    )
    event(f"oracle: {expected.status}" + (" in 0 steps" if expected.length == 0 else ""))
    results = {}
    for name, planner in case.planners.items():
        results[name] = result = planner.plan(query)
        known = excuse(case, q, name, result, expected) if excuse is not None else None
        if known is not None:
            event(f"known bug: {known}")
            continue
        check_result(case, q, result, expected, name)
    if not query.relaxed and query.maintenance_cost == 1:  # sat: no such queries
        result = case.planners["default"].plan(query, engine="sat")
        check_result(case, q, result, expected, "sat")
    if expected.status == "found" and expected.length and results["default"].found:
        final = results["default"].states[-1]
        if any(t.kind == "automatic" and t.enabled(final) for t in case.oracle.transitions):
            event("plan: ends where an automatic is enabled")
    return results


def example(text: str) -> Case:
    case = make_case(yaml.safe_load(text))
    assert case is not None
    return case


def ask(case: Case, goal: str, start: dict[str, Any] | None = None, **extra: Any) -> dict[str, Any]:
    """A query dict with the defaults, from the initial state unless `start` says more."""
    values = {v.name: v.initial for v in case.model.variables} | (start or {})
    return {
        "start": values,
        "goal": goal,
        "maintenance": False,
        "forbidden": [],
        "phi": None,
        "disabled": [],
        "max_steps": 12,
    } | extra


# --------------------------------------------------------------------------- independent components


@settings(SETTINGS, max_examples=100)
@given(data=st.data())
def test_component_models_plan_like_the_oracle_under_every_reduction(
    data: st.DataObject,
) -> None:
    structured = data.draw(SS.component_models())
    case = make_case(structured.model)
    if case is None:
        return
    for _ in range(QUERIES_PER_MODEL):
        q = data.draw(SS.component_queries(structured))
        results = plan_everywhere(case, q)
        check_structure(case, q, results)
        _bridge_events(case, q, structured)


def _bridge_events(case: Case, q: dict[str, Any], structured: SS.Structured) -> None:
    """Bridges of uncontrollable kinds always join their parts; the others only when the
    query may use them."""
    query = case.query(q)
    expected = structure(case, q)
    for name in structured.bridges:
        t = case.model.transition(name)
        joined = any(touches(t) <= c for c in expected.components)
        assert joined or t.kind not in UNCONTROLLABLE
        usable = name not in query.disabled and (
            query.maintenance or t.kind is not TransitionKind.MAINTENANCE
        )
        if t.kind in UNCONTROLLABLE or usable:
            assert joined, name
            event(f"bridge: {t.kind.value} joins two parts")
        else:
            event("bridge: unusable, parts stay apart")


# Two robots a and b that share nothing; each `start` leaves an automatic `settle` to run.
TWO_ROBOTS = """
variables:
  - {name: a.pos, domain: [home, mid, bp]}
  - {name: a.busy, domain: bool}
  - {name: b.pos, domain: [home, mid, bp]}
  - {name: b.busy, domain: bool}
transitions:
  - {name: a.start, guard: "a.pos == home && !a.busy", actions: ["a.pos := mid", "a.busy := true"]}
  - {name: a.settle, kind: automatic, guard: a.busy, actions: ["a.busy := false"]}
  - {name: a.arrive, guard: "a.pos == mid", actions: ["a.pos := bp"]}
  - {name: b.start, guard: "b.pos == home && !b.busy", actions: ["b.pos := mid", "b.busy := true"]}
  - {name: b.settle, kind: automatic, guard: b.busy, actions: ["b.busy := false"]}
  - {name: b.arrive, guard: "b.pos == mid", actions: ["b.pos := bp"]}
"""


def test_a_component_the_goal_does_not_touch_is_frozen() -> None:
    case = example(TWO_ROBOTS)
    q = ask(case, "a.pos == bp")
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert len(expected.components) == 2 and len(expected.active) == 1
    assert results["default"].plan == ("a.start", "a.settle", "a.arrive")
    assert results["default"].statistics["parts"] == 1
    assert results["default"].statistics["searched_bits"] == 3 < 6
    assert results["none"].statistics["searched_bits"] == 6


def test_parts_are_concatenated_the_busy_one_first() -> None:
    """b's automatic is enabled at the start: b must move first, though a comes first
    in the model; the parts' sum is the minimum."""
    case = example(TWO_ROBOTS)
    q = ask(case, "a.pos == mid && b.pos == bp", {"b.pos": "mid", "b.busy": True})
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert expected.parts == 2 and expected.busy == (frozenset({"b.pos", "b.busy"}),)
    assert results["default"].plan == ("b.settle", "b.arrive", "a.start")
    assert results["default"].statistics["parts"] == 2


def test_a_part_that_ends_with_an_automatic_enabled_goes_last() -> None:
    case = example(TWO_ROBOTS)
    q = ask(case, "a.pos == mid && b.pos == bp", {"b.pos": "mid"})
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert expected.unsettled == (frozenset({"a.pos", "a.busy"}),)
    assert results["default"].plan == ("b.arrive", "a.start")
    assert results["default"].statistics["parts"] == 2


def test_a_part_whose_start_has_an_automatic_enabled_is_active_though_its_goal_holds() -> None:
    """b's goal part holds, but its `settle` is enabled at the start and goes before any
    controlled step of a: b cannot be frozen."""
    case = example(TWO_ROBOTS)
    q = ask(case, "a.pos == mid && b.pos == home", {"b.busy": True})
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert expected.active == expected.components and expected.busy == (expected.active[1],)
    assert results["default"].plan == ("b.settle", "a.start")


@pytest.mark.parametrize(
    ("goal", "start", "extra"),
    [
        # both end with `settle` enabled: one must settle before the other starts
        ("a.pos == mid && b.pos == mid", {}, 1),
        # both start busy: their automatics run first, together, at no extra cost
        ("a.pos == bp && b.pos == bp", {"a.pos": "mid", "a.busy": True, "b.busy": True}, 0),
    ],
    ids=["both end busy", "both start busy"],
)
def test_parts_no_order_can_concatenate_are_planned_jointly(
    goal: str, start: dict[str, Any], extra: int
) -> None:
    case = example(TWO_ROBOTS)
    q = ask(case, goal, start)
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert expected.fallback
    assert results["default"].statistics["parts"] == 1
    assert results["default"].statistics["searched_bits"] == 6
    assert sum(n for n in expected.lengths if n is not None) + extra == results["default"].length


def test_a_part_is_replanned_to_end_calm_when_that_costs_no_step() -> None:
    """`a.rush` (first in the model) leaves `settle` enabled; `a.walk` reaches mid as
    fast and calm, so a goes first and b (which cannot end calm) last."""
    text = TWO_ROBOTS.replace(
        "  - {name: a.start,",
        '  - {name: a.rush, guard: "a.pos == home", actions: ["a.pos := mid", "a.busy := true"]}\n'
        '  - {name: a.walk, guard: "a.pos == home", actions: ["a.pos := mid"]}\n'
        "  - {name: a.start,",
    )
    case = example(text)
    q = ask(case, "a.pos == mid && b.pos == mid")
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert expected.unsettled == (frozenset({"b.pos", "b.busy"}),)
    assert results["default"].plan == ("a.walk", "b.start")
    assert results["default"].statistics["parts"] == 2


BRIDGED = """
variables:
  - {name: door, domain: bool}
  - {name: lamp, domain: bool}
  - {name: fan, domain: bool}
transitions:
  - {name: door.push, guard: "!door", actions: ["door := true"]}
  - {name: lamp.switch, guard: "!lamp", actions: ["lamp := true"]}
  - {name: fan.switch, guard: "!fan", actions: ["fan := true"]}
  - {name: lamp.auto, kind: automatic, guard: "door && !lamp", actions: ["lamp := true"]}
  - {name: fan.by_hand, kind: maintenance, guard: "lamp && !fan", actions: ["fan := true"]}
"""


@pytest.mark.parametrize(
    ("extra", "parts"),
    [
        ({}, 2),  # the automatic ties door and light; the fan is apart
        ({"maintenance": True}, 1),  # by hand, the fan follows the light
        ({"maintenance": True, "disabled": ["fan.by_hand"]}, 2),
    ],
)
def test_automatics_and_usable_steps_that_read_two_parts_join_them(
    extra: dict[str, Any], parts: int
) -> None:
    case = example(BRIDGED)
    q = ask(case, "door && lamp && fan", **extra)
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert frozenset({"door", "lamp"}) <= expected.components[0]
    assert len(expected.components) == parts
    assert results["default"].statistics["parts"] == parts


# --------------------------------------------------------------------------- symmetry


def check_symmetries(case: Case, symmetric: SS.Symmetric) -> None:
    """`find_symmetries` returns real automorphisms only, each with the transitions it
    breaks, and every swap of two exact copies."""
    found = {(s.first, s.second): s for s in find_symmetries(case.planners["symmetry"].sym)}
    for (first, second), swap in found.items():
        failed = explicit_swap(case.oracle, first, second)
        assert failed is not None, f"{swap.name} is no automorphism"
        assert failed <= swap.broken, swap.name
        for name, image in swap.transitions.items():
            assert image == rename(name, first, second), swap.name
    last = symmetric.copies[-1]
    for first, second in itertools.combinations(symmetric.copies, 2):
        if symmetric.altered is None or last not in (first, second):
            assert (first, second) in found, (first, second)
            assert not found[first, second].broken, (first, second)
            event("symmetry: swap of exact copies found")
            continue
        failed = explicit_swap(case.oracle, first, second)
        if failed is None:
            assert (first, second) not in found, (first, second)
            event("symmetry: swap rejected by verification")
        elif failed:
            event("symmetry: swap kept for queries without the altered transition")
        else:
            event("symmetry: altered guard changes nothing")


@settings(SETTINGS, max_examples=50)
@given(data=st.data())
def test_symmetric_models_plan_like_the_oracle_under_every_reduction(
    data: st.DataObject,
) -> None:
    symmetric = data.draw(SS.symmetric_models())
    case = make_case(symmetric.model)
    if case is None:
        return
    check_symmetries(case, symmetric)
    for _ in range(QUERIES_PER_MODEL):
        q = data.draw(SS.symmetric_queries(symmetric))
        event("query: keeps the symmetry" if q["symmetric"] else "query: breaks it")
        results = plan_everywhere(case, q)
        check_structure(case, q, results)
        # one state per orbit (not always fewer: an orbit's other states need not be
        # reachable from an asymmetric start)
        with_swaps = results["symmetry"].statistics.get("reached", 0)
        if with_swaps < results["default"].statistics.get("reached", 0):
            event("symmetry: fewer states reached")


COPIES = """
variables:
  - {name: r.pos, domain: [home, bp1, bp2, bp3]}
  - {name: bp1.state, domain: [empty, half, full]}
  - {name: bp2.state, domain: [empty, half, full]}
  - {name: bp3.state, domain: [empty, half, full]}
transitions:
  - {name: r.go_home, guard: "r.pos != home", actions: ["r.pos := home"]}
  - {name: r.goto_bp1, guard: "r.pos == home", actions: ["r.pos := bp1"]}
  - {name: r.goto_bp2, guard: "r.pos == home", actions: ["r.pos := bp2"]}
  - {name: r.goto_bp3, guard: "r.pos == home", actions: ["r.pos := bp3"]}
  - {name: bp1.fill, guard: "r.pos == bp1 && bp1.state == empty", actions: ["bp1.state := half"]}
  - {name: bp2.fill, guard: "r.pos == bp2 && bp2.state == empty", actions: ["bp2.state := half"]}
  - {name: bp3.fill, guard: "r.pos == bp3 && bp3.state == empty", actions: ["bp3.state := half"]}
  - {name: bp1.done, kind: automatic, guard: "bp1.state == half", actions: ["bp1.state := full"]}
  - {name: bp2.done, kind: automatic, guard: "bp2.state == half", actions: ["bp2.state := full"]}
  - {name: bp3.done, kind: automatic, guard: "bp3.state == half", actions: ["bp3.state := full"]}
"""
ALL_FULL = "bp1.state == full && bp2.state == full && bp3.state == full"


def swaps(case: Case) -> dict[tuple[str, str], frozenset[str]]:
    """The verified swaps, each with the transitions it breaks."""
    return {(s.first, s.second): s.broken for s in find_symmetries(case.planners["symmetry"].sym)}


def test_interchangeable_copies_are_found_and_searched_once_per_orbit() -> None:
    case = example(COPIES)
    assert swaps(case) == {
        ("bp1", "bp2"): frozenset(),
        ("bp1", "bp3"): frozenset(),
        ("bp2", "bp3"): frozenset(),
    }
    q = ask(case, ALL_FULL)
    results = plan_everywhere(case, q)
    check_structure(case, q, results)
    assert results["default"].length == 3 * 4 - 1  # goto, fill, done, go_home; no last home
    reached = results["symmetry"].statistics["reached"]
    assert reached < results["default"].statistics["reached"]
    # a goal on one copy keeps the swap of the other two only
    one = plan_everywhere(case, ask(case, "bp1.state == full"))
    assert one["default"].statistics["reached"] > one["symmetry"].statistics["reached"]


@pytest.mark.parametrize(
    ("altered", "guard", "kept"),
    [
        # an automatic: no swap with bp3 is an automorphism
        ("bp3.done", "bp3.state == half && r.pos != home", False),
        # controlled: kept for the queries that do not use it
        ("bp3.fill", "r.pos == bp3 && bp3.state != full", True),
    ],
)
def test_a_copy_that_only_looks_the_same_is_not_swapped(
    altered: str, guard: str, kept: bool
) -> None:
    spec = yaml.safe_load(COPIES)
    for t in spec["transitions"]:
        if t["name"] == altered:
            t["guard"] = guard
    case = make_case(spec)
    assert case is not None
    found = swaps(case)
    assert found[("bp1", "bp2")] == frozenset()
    for pair in [("bp1", "bp3"), ("bp2", "bp3")]:
        assert (pair in found) is kept
        if kept:
            assert found[pair] == {altered, altered.replace("bp3", pair[0])}
    for goal in [ALL_FULL, "bp3.state == full", "bp1.state == full || bp3.state == full"]:
        results = plan_everywhere(case, ask(case, goal))
        check_structure(case, ask(case, goal), results)
    if kept:  # without the fill steps the swaps hold: nothing moves, fewer states
        off = ["bp1.fill", "bp2.fill", "bp3.fill"]
        results = plan_everywhere(case, ask(case, ALL_FULL, disabled=off))
        assert not results["symmetry"].found


# ------------------------------------------------------------------------- forbidden-state recovery


@settings(SETTINGS, max_examples=60)
@given(data=st.data())
def test_relaxed_queries_recover_like_the_oracle_under_every_reduction(
    data: st.DataObject,
) -> None:
    if data.draw(st.booleans()):
        structured = data.draw(SS.component_models(specified=True))
        model, queries = structured.model, SS.component_queries(structured)
    else:
        symmetric = data.draw(SS.symmetric_models(specified=True))
        model, queries = symmetric.model, SS.symmetric_queries(symmetric)
    case = make_case(model)
    if case is None:
        return
    for _ in range(QUERIES_PER_MODEL):
        q = data.draw(SS.relaxations(model, data.draw(queries)))
        start = case.query(q).start
        if start in O.bad_states(case.oracle):
            event("relaxed: the start is bad")
        results = plan_everywhere(case, q)
        check_structure(case, q, results)


# a and b as in TWO_ROBOTS, each with a specification that an effect can break
RECOVERING = (
    TWO_ROBOTS
    + """
  - {name: a.slip, kind: effect, guard: "a.pos == bp && !a.busy", actions: ["a.busy := true"]}
  - {name: b.slip, kind: effect, guard: "b.pos == bp && !b.busy", actions: ["b.busy := true"]}
  - {name: a.back, guard: "a.pos == bp", actions: ["a.pos := home"]}
specifications:
  - {name: a.calm_at_bp, invariant: "!(a.pos == bp && a.busy)"}
  - {name: b.calm_at_bp, invariant: "!(b.pos == bp && b.busy)"}
"""
)


def test_recovery_plans_only_the_parts_that_are_bad_jointly() -> None:
    """a stands at bp, bad by closure (it may slip); recovery with a's specification
    relaxed brings it home, and b, good, stays frozen."""
    case = example(RECOVERING)
    start = {"a.pos": "bp"}
    assert O.violated(case.oracle, case.query(ask(case, "true", start)).start) == ["a.calm_at_bp"]
    q = ask(case, "true", start, relaxed=["a.calm_at_bp"])
    results = plan_everywhere(case, q)
    expected = check_structure(case, q, results)
    assert expected.active == (frozenset({"a.pos", "a.busy"}),)
    assert results["default"].plan == ("a.back",)
    assert results["default"].statistics["parts"] == 1
    assert results["default"].statistics["searched_bits"] == 3
    # a recovery plan may pass where the dropped specification is violated: a slipped
    slipped = ask(case, "true", {"a.pos": "bp", "a.busy": True}, relaxed=["a.calm_at_bp"])
    assert plan_everywhere(case, slipped)["default"].plan == ("a.settle", "a.back")
    # a start bad for a kept specification drops it too, but the recovery must still end
    # where every supervisor holds again: b has no way back from bp, so there is no plan
    both = ask(case, "true", {"b.pos": "bp", "b.busy": True}, relaxed=["a.calm_at_bp"])
    result = plan_everywhere(case, both)["default"]
    assert result.status is PlanStatus.UNREACHABLE and result.plan == ()


def test_sat_refuses_relaxed_queries() -> None:
    case = example(TWO_ROBOTS)
    query = case.query(ask(case, "true", relaxed=["nothing"]))
    with pytest.raises(ValueError, match="needs the bdd engine"):
        case.planners["default"].plan(query, engine="sat")


# --------------------------------------------------------------------------- maintenance cost


def weigh_maintenance(data: st.DataObject, q: dict[str, Any]) -> dict[str, Any]:
    """`q` with maintenance weighed 2, 3 or 10 and a bound that may be tight (the cheapest
    plan may then not fit, and a dearer one must be found)."""
    bound = data.draw(st.sampled_from([q["max_steps"], 3, 4, 5, 6]))
    cost = data.draw(st.sampled_from([2, 3, 10]))
    return {**q, "maintenance": True, "maintenance_cost": cost, "max_steps": bound}


@settings(SETTINGS, max_examples=60)
@given(data=st.data())
def test_weighted_maintenance_plans_like_the_oracle_under_every_reduction(
    data: st.DataObject,
) -> None:
    structured = data.draw(SS.component_models(shortcuts=True))
    case = make_case(structured.model)
    if case is None:
        return
    for _ in range(QUERIES_PER_MODEL):
        q = weigh_maintenance(data, data.draw(SS.component_queries(structured)))
        results = plan_everywhere(case, q)
        check_structure(case, q, results)
        plain = O.plan(
            case.oracle,
            case.query(q).start,
            q["goal"],
            max_steps=q["max_steps"],
            **oracle_options(q),
        )
        weighted = results["default"]
        if plain.status == "found" and weighted.found and weighted.length > plain.length:
            event("maintenance cost: a longer plan with fewer maintenance steps")


def test_a_costly_maintenance_step_gives_way_to_a_longer_plan() -> None:
    case = example(SS.SHORTCUTS)
    q = ask(case, "x == v3 && y == v3", maintenance=True)
    assert plan_everywhere(case, q)["default"].plan == ("x.jump", "y.jump")
    costly = plan_everywhere(case, {**q, "maintenance_cost": 10})
    assert costly["default"].plan == ("x.c0", "x.c1", "x.c2", "y.c0", "y.c1", "y.c2")
    assert costly["default"].statistics["parts"] == 2
    cheap = plan_everywhere(case, {**q, "maintenance_cost": 2})
    assert cheap["default"].plan == ("x.jump", "y.jump")


def test_weighted_parts_that_do_not_fit_in_max_steps_are_planned_jointly() -> None:
    """Each part's cheapest plan is its chain (6 steps in all), over max_steps 4: a joint
    search finds one jump and one chain."""
    case = example(SS.SHORTCUTS)
    q = ask(case, "x == v3 && y == v3", maintenance=True, maintenance_cost=10, max_steps=4)
    results = plan_everywhere(case, q)  # the oracle: 4 steps, one of them maintenance
    plan = results["default"].plan
    assert len(plan) == 4 and sum(step.endswith(".jump") for step in plan) == 1
    assert results["default"].statistics["parts"] == 1


BY_HAND = """
variables:
  - {name: a.x, domain: [v0, v1, v2]}
  - {name: a.busy, domain: bool}
  - {name: b.y, domain: [v0, v1]}
  - {name: b.busy, domain: bool}
transitions:
  - {name: a.start, guard: "a.x == v0", actions: ["a.x := v1", "a.busy := true"]}
  - {name: a.drift, kind: automatic, guard: a.busy, actions: ["a.busy := false", "a.x := v2"]}
  - {name: a.by_hand, kind: maintenance, guard: "a.x == v0", actions: ["a.x := v1"]}
  - {name: b.start, guard: "b.y == v0", actions: ["b.y := v1", "b.busy := true"]}
  - {name: b.settle, kind: automatic, guard: b.busy, actions: ["b.busy := false"]}
"""


def test_a_part_replanned_to_a_calm_end_keeps_its_cost() -> None:
    """Part a's plan a.start ends with a.drift enabled; re-planning it to a calm end finds
    a.by_hand, as short but dearer, so a goes last: (b.start, b.settle, a.start)."""
    case = example(BY_HAND)
    q = ask(case, "a.x == v1 && b.y == v1", maintenance=True, maintenance_cost=10)
    results = plan_everywhere(case, q)  # the oracle: 3 steps, no maintenance
    assert results["default"].plan == ("b.start", "b.settle", "a.start")


SLOW_OR_BY_HAND = """
variables:
  - {name: x, domain: [v0, v1, v2, v3]}
  - {name: done, domain: bool}
transitions:
  - {name: c0, guard: "x == v0", actions: ["x := v1"]}
  - {name: c1, guard: "x == v1", actions: ["x := v2"]}
  - {name: c2, guard: "x == v2", actions: ["x := v3"]}
  - {name: jump, kind: maintenance, guard: "x != v3", actions: ["x := v3"]}
  - {name: finish, guard: "x == v3 && !done", actions: ["done := true"]}
"""


@pytest.mark.parametrize("reductions", ["default", "none"])
def test_a_maintenance_step_is_taken_when_max_steps_leaves_no_other_way(
    reductions: str,
) -> None:
    """Within 3 steps the chain reaches x == v3 but cannot finish; the jump can: the budget
    of maintenance steps is raised although the jump reaches no state the chain did not."""
    case = example(SLOW_OR_BY_HAND)
    q = ask(case, "done", maintenance=True, maintenance_cost=10, max_steps=3)
    start = case.query(q).start
    expected = O.plan(
        case.oracle, start, "done", max_steps=3, maintenance=True, maintenance_cost=10
    )
    assert expected == O.OracleResult("found", 2, [], 1)
    result = case.planners[reductions].plan(case.query(q))
    assert result.plan == ("jump", "finish")


def test_sat_refuses_weighted_maintenance() -> None:
    case = example(SS.SHORTCUTS)
    q = ask(case, "x == v3 && y == v3", maintenance=True, maintenance_cost=10)
    with pytest.raises(ValueError, match="bdd engine"):
        case.planners["default"].plan(case.query(q), engine="sat")
