"""The station form compiles to the flat model (docs/models.md)."""

from __future__ import annotations

import pytest

from planner.model.expressions import Equals, format_expr, variables_of
from planner.model.flat import TransitionKind
from planner.model.semantics import Semantics
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.partial_order import independent_operations
from planner.planning.query import PlanQuery, PlanStatus
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.reading.yaml_reader import ModelError
from tests.support.paths import MINI_STATION

MINI = MINI_STATION


@pytest.fixture(scope="module")
def station() -> Station:
    return load_station(MINI.read_text(), str(MINI))


def test_resource_variables_are_qualified(station: Station) -> None:
    names = [v.name for v in station.model.variables]
    assert names == ["bp1.state", "nr.run", "nr.running", "nr.torque", "r1.ref", "r1.pos"]


def test_each_transition_and_variable_has_the_resource_it_belongs_to(station: Station) -> None:
    assert station.owner_of("r1.goto_bp1") == "r1"
    assert station.owner_of("r1.goto.arrive") == "r1"  # a generic effect
    assert station.owner_of("nr.running") == "nr"
    assert station.owner_of("bp1.state") == ""  # station-wide
    assert station.owner_of("no.such.name") == ""
    for resource in station.resources:
        assert all(station.owner_of(t) == resource.name for t in resource.transitions)


def test_abilities_are_instantiated_per_parameter_value(station: Station) -> None:
    goto = [a for a in station.abilities if a.template == "goto"]
    assert [a.qualified for a in goto] == ["r1.goto_home", "r1.goto_bp1"]
    assert station.model.transition("r1.goto_bp1").actions[0].value == "bp1"
    # the per-instance extra guard is conjoined to start (seed 003 Table V)
    assert format_expr(station.model.transition("r1.goto_home").guard) == (
        "r1.pos == r1.ref && r1.ref != home && !nr.running"
    )
    assert "nr.running" not in format_expr(station.model.transition("r1.goto_bp1").guard)


def test_a_transition_equal_for_every_value_is_emitted_once(station: Station) -> None:
    names = [t.name for t in station.model.transitions]
    assert names.count("r1.goto.arrive") == 1
    assert not any(n.startswith("r1.goto_home.") for n in names)
    arrive = station.model.transition("r1.goto.arrive")
    assert arrive.kind is TransitionKind.EFFECT
    assert str(arrive.actions[0]) == "r1.pos := r1.ref"


def test_standard_predicates_are_named_globally(station: Station) -> None:
    finished = station.predicates["r1.goto_bp1.finished"]
    assert format_expr(finished) == "r1.pos == bp1 && r1.ref == bp1"
    assert "nr.run_nut.resetting" in station.predicates


def test_operations_and_intentions(station: Station) -> None:
    operation = station.operation("tighten_bp1")
    assert operation.name == "tighten_bp1"
    assert operation.precondition == Equals("bp1.state", "placed")
    values = dict(station.model.initial_values())
    assert format_expr(operation.planning_goal(values)) == "bp1.state == tightened"
    assert format_expr(station.predicates["assemble.goal"]) == (
        "bp1.state == tightened && r1.pos == home"
    )


def test_goals_may_name_intentions_and_operations(station: Station) -> None:
    planner = TransitionPlanner(station.model)
    start = tuple(station.model.initial_values().values())
    for engine in ("bdd", "sat"):
        result = planner.plan(PlanQuery(start, station.predicates["assemble.goal"]), engine=engine)
        assert result.found and result.length == 9
        semantics = Semantics(station.model)
        assert semantics.values(result.states[-1])["bp1.state"] == "tightened"


def broken(old: str, new: str) -> list[str]:
    text = MINI.read_text().replace(old, new)
    assert text != MINI.read_text()
    with pytest.raises(ModelError) as caught:
        TransitionPlanner(load_station(text, "station.yaml").model)
    return [str(d) for d in caught.value.diagnostics]


def test_errors_in_templates_point_at_the_template_once() -> None:
    # one message for the template, not one per parameter value, at the right column
    (message,) = broken(
        'enabled: "pos == ref && ref != {target}"', 'enabled: "poz == ref && ref != {target}"'
    )
    assert message == (
        "station.yaml:32:21: in predicate 'enabled' of ability 'r1.goto': "
        "unknown variable 'poz' (did you mean 'pos'?)"
    )


def test_error_after_a_placeholder_is_located_in_the_template() -> None:
    (message,) = broken(
        'finished: "pos == {target} && ref == {target}"',
        'finished: "pos == {target} && ref == {target} && posx"',
    )
    assert message.startswith("station.yaml:34:60: in predicate 'finished' of ability 'r1.goto':")
    assert "unknown variable 'posx'" in message


def test_an_instantiated_value_outside_the_domain_names_the_transition() -> None:
    messages = broken('actions: ["ref := {target}"]', 'actions: ["ref := {target}x"]')
    assert messages == [
        "station.yaml:36:61: in an action of transition 'r1.goto.start': "
        "'homex' is not a value of 'r1.ref' (domain: home, bp1)",
        "station.yaml:36:61: in an action of transition 'r1.goto.start': "
        "'bp1x' is not a value of 'r1.ref' (domain: home, bp1)",
    ]


def test_unknown_instance_value() -> None:
    (message,) = broken("home: {guard:", "moon: {guard:")
    assert "'moon' is not a value of the parameter of 'goto'" in message


def test_unknown_predicate_in_a_goal_suggests_the_right_one() -> None:
    (message,) = broken(
        'goal: "bp1.state == tightened && r1.pos == home"', 'goal: "tighten_bp1.gaol"'
    )
    assert "unknown variable 'tighten_bp1.gaol' (did you mean 'tighten_bp1.goal'?)" in message


def test_the_operation_planner_sequences_operations_for_the_intentions(
    station: Station,
) -> None:
    planner = OperationPlanner(station)
    assert [t.name for t in planner.model.transitions] == ["place_bp1", "tighten_bp1"]
    assert [v.name for v in planner.model.variables] == ["bp1.state", "r1.pos"]
    values = station.model.initial_values()
    query = planner.query(values, [station.intention("assemble")])
    for engine in ("bdd", "sat"):
        result = planner.plan(query, engine)
        assert [o.name for o in planner.operations(result)] == ["place_bp1", "tighten_bp1"]
    # an operation in error is planned around; here nothing else places bolts
    blocked = planner.query(values, [station.intention("assemble")], disabled=["place_bp1"])
    assert planner.plan(blocked).status is PlanStatus.UNREACHABLE
    uses = {
        o.name: variables_of(o.precondition) | {a.target for a in o.effects}
        for o in station.operations
    }
    assert independent_operations(uses, ["place_bp1", "tighten_bp1"]) == [
        frozenset(),
        frozenset({0}),
    ]


def test_duplicate_operation_names() -> None:
    messages = broken("values: [bp1]}\n    precondition", "values: [bp1, bp1]}\n    precondition")
    assert any("duplicate operation name 'tighten_bp1'" in m for m in messages)


def test_an_operation_s_duration_is_seconds_above_zero() -> None:
    text = MINI.read_text().replace(
        'effects: ["{bolt}.state := placed"]',
        'effects: ["{bolt}.state := placed"]\n    duration: 4.5',
    )
    assert load_station(text, "station.yaml").operation("place_bp1").duration == 4.5
    assert load_station(MINI.read_text(), "station.yaml").operation("place_bp1").duration is None
    for bad in ("0", "-1", "soon", ".inf"):
        (message,) = broken(
            'effects: ["{bolt}.state := placed"]',
            f'effects: ["{{bolt}}.state := placed"]\n    duration: {bad}',
        )
        assert message.startswith("station.yaml:55:15: the duration of operation 'place_{bolt}'")
        assert "a number above 0" in message
