"""Broken models get messages naming file, line, column and the problem (issue 3, point 3)."""

from __future__ import annotations

import textwrap

import pytest

from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model
from planner.reading.yaml_reader import ModelError

GOOD = """\
variables:
  - {name: r1.pos, domain: [home, tool, bp1], initial: home, kind: measured}
  - {name: r1.ref, domain: [home, tool, bp1], initial: home, kind: command}
  - {name: nr.running, domain: bool, initial: false, kind: measured}
transitions:
  - {name: r1.goto_bp1, guard: "r1.pos == home && !nr.running", actions: ["r1.ref := bp1"]}
  - {name: r1.arrive, kind: effect, guard: "r1.ref != r1.pos", actions: ["r1.pos := r1.ref"]}
specifications:
  - {name: not_at_bp1, invariant: "!(r1.pos == bp1 && nr.running)"}
"""


def errors(text: str) -> list[str]:
    with pytest.raises(ModelError) as caught:
        TransitionPlanner(load_model(textwrap.dedent(text), "station.yaml"))
    return [str(d) for d in caught.value.diagnostics]


def test_a_good_model_loads() -> None:
    model = load_model(GOOD, "station.yaml")
    assert [v.name for v in model.variables] == ["r1.pos", "r1.ref", "nr.running"]
    assert model.transition("r1.goto_bp1").kind.value == "controlled"


def test_unknown_variable_names_the_closest_known_name() -> None:
    text = GOOD.replace('guard: "r1.pos == home', 'guard: "r1.poss == home')
    assert errors(text) == [
        "station.yaml:6:33: in the guard of transition 'r1.goto_bp1': "
        "unknown variable 'r1.poss' (did you mean 'r1.pos'?)"
    ]


def test_value_outside_the_domain_lists_the_domain() -> None:
    text = GOOD.replace('"r1.ref := bp1"', '"r1.ref := bp7"')
    (message,) = errors(text)
    assert message.startswith("station.yaml:6:")
    assert "'bp7' is not a value of 'r1.ref' (domain: home, tool, bp1)" in message


def test_initial_value_outside_the_domain() -> None:
    text = GOOD.replace("initial: home, kind: command", "initial: away, kind: command")
    assert errors(text) == [
        "station.yaml:3:56: initial value 'away' of 'r1.ref' is outside its domain "
        "[home, tool, bp1]"
    ]


def test_duplicate_names_point_at_the_second_and_mention_the_first() -> None:
    text = GOOD.replace("name: r1.arrive", "name: r1.goto_bp1")
    assert errors(text) == [
        "station.yaml:7:12: duplicate transition name 'r1.goto_bp1' (first defined at line 6)"
    ]


def test_type_mismatch_between_compared_variables() -> None:
    text = GOOD.replace('"r1.ref != r1.pos"', '"r1.ref != nr.running"')
    (message,) = errors(text)
    assert message.startswith("station.yaml:7:")
    assert "cannot compare 'r1.ref' with 'nr.running': their domains differ" in message


def test_enumeration_used_as_a_boolean() -> None:
    text = GOOD.replace('"!(r1.pos == bp1 && nr.running)"', '"!(r1.pos && nr.running)"')
    (message,) = errors(text)
    assert message.startswith("station.yaml:9:38: ")
    assert "'r1.pos' is not boolean; compare it with a value" in message


def test_syntax_error_in_an_expression_is_located_at_the_offending_token() -> None:
    text = GOOD.replace('"r1.pos == home && !nr.running"', '"r1.pos == home && && !nr.running"')
    assert errors(text) == [
        "station.yaml:6:51: in the guard of transition 'r1.goto_bp1': unexpected '&&'"
    ]


def test_unclosed_parenthesis() -> None:
    text = GOOD.replace('"!(r1.pos == bp1 && nr.running)"', '"!(r1.pos == bp1 && nr.running"')
    (message,) = errors(text)
    assert "expected ')' to close" in message
    assert message.startswith("station.yaml:9:")


def test_controlled_transition_may_not_assign_a_measured_variable() -> None:
    text = GOOD.replace('"r1.ref := bp1"', '"r1.pos := bp1"')
    (message,) = errors(text)
    assert message.startswith("station.yaml:6:")
    assert "controlled transition 'r1.goto_bp1' assigns measured variable 'r1.pos'" in message


def test_automatic_cycle_is_reported_not_looped() -> None:
    text = """\
    variables:
      - {name: a, domain: bool}
      - {name: b, domain: bool}
    transitions:
      - {name: up, kind: automatic, guard: "!a", actions: ["a := true"]}
      - {name: down, kind: automatic, guard: "a && !b", actions: ["a := false"]}
    """
    (message,) = errors(text)
    assert message.startswith("station.yaml:5:5: automatic transitions can cycle forever:")
    assert "up -> down -> up" in message or "down -> up -> down" in message


def test_yaml_syntax_error_is_located() -> None:
    (message,) = errors("variables:\n  - {name: a, domain: bool\ntransitions: []\n")
    assert message.startswith("station.yaml:3:")
    assert "YAML" in message


def test_unknown_keys_get_suggestions_and_every_error_is_reported() -> None:
    text = GOOD.replace("guard:", "gaurd:", 1).replace("initial: false", "initial: maybe")
    messages = errors(text)
    assert len(messages) == 2
    assert "outside its domain bool" in messages[0]
    assert "unknown key 'gaurd' in a transition (did you mean 'guard'?)" in messages[1]


def test_names_must_be_dotted_identifiers() -> None:
    text = GOOD.replace("name: r1.arrive", "name: r1.arrive-now")
    (message,) = errors(text)
    assert message.startswith("station.yaml:7:12: transition name 'r1.arrive-now' is not a name")


def test_action_syntax() -> None:
    text = GOOD.replace('"r1.ref := bp1"', '"r1.ref = bp1"')
    (message,) = errors(text)
    assert message.startswith("station.yaml:6:83: ")
    assert "':=' to assign" in message


def test_single_equals_in_a_guard() -> None:
    text = GOOD.replace('"r1.pos == home &&', '"r1.pos = home &&')
    (message,) = errors(text)
    assert message.startswith("station.yaml:6:40: ")
    assert "'=' is not an operator: use '==' to compare" in message
