"""Issue 26: predicates that each name the one before twice doubled the loader's time and
memory per line (23 lines: 7 s and +420 MB).  Reading is now linear: an expression is refused,
at its place, once it would stand for more than `MAX_TERMS` terms, so however many lines
follow, the work stops at the same line."""

from __future__ import annotations

import pytest

from planner.model.expression_text import parse_expr
from planner.model.expressions import MAX_TERMS, And, BoolVar, Expr, Implies, size
from planner.reading import load_station
from planner.reading.yaml_reader import ModelError, scope_for
from tests.support.bombs import predicate_bomb


@pytest.mark.parametrize("join", ["&&", "||", "->"])
def test_a_predicate_bomb_is_refused_at_the_same_line_however_long(join: str) -> None:
    refused = []
    for levels in (30, 60, 200):
        with pytest.raises(ModelError) as caught:
            load_station(predicate_bomb(levels, join), "bomb.yaml")
        first = caught.value.diagnostics[0]
        assert f"more than {MAX_TERMS} terms" in first.message
        assert first.location.file == "bomb.yaml" and first.location.column > 1
        refused.append((first.location.line, first.message))
    # the line where 2^k first passes the limit, whatever follows it: linear in the levels
    assert refused[0] == refused[1] == refused[2]
    assert 20 <= refused[0][0] <= 30


def test_a_few_levels_load_and_count_their_terms() -> None:
    station = load_station(predicate_bomb(10), "small.yaml")
    assert station.model.transitions


def test_size_counts_a_shared_part_each_time_in_time_linear_in_what_is_held() -> None:
    expr = And((BoolVar("a"), BoolVar("b")))
    for _ in range(200):  # 2^200 nodes written out; 200 held
        expr = Implies(expr, expr)
    assert size(expr) == 2**200 * 4 - 1


@pytest.mark.parametrize(
    "text",
    [
        "p && q",
        "p || q",
        "(a && b) && (c || a) && p",
        "true && p && (q || false)",
        "false || p || (a && b) || q",
        "p && true",
        "!(p && q) || (p -> q)",
        "(p && q) && (p && q)",
    ],
)
def test_a_join_is_measured_from_its_parts_as_walking_it_would(text: str) -> None:
    """`&&` and `||` keep their result's size from their parts' (so that a guard naming a
    large predicate is not walked again): the same number a fresh walk counts."""
    booleans = {name: (False, True) for name in "abc"}
    predicates = {"p": parse_expr("a && (b || c)", scope_for(booleans))}
    predicates["q"] = parse_expr("!a || c || p", scope_for(booleans, predicates))
    sizes: dict[int, tuple[Expr, int]] = {}
    expr = parse_expr(text, scope_for(booleans, predicates, sizes=sizes))
    assert size(expr, sizes) == size(expr)
