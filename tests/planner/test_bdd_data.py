"""Named BDDs as plain data: the same functions come back in a manager of another order."""

from __future__ import annotations

import json
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.bdd.data import from_data, to_data
from planner.bdd.symbolic import cudd

BITS = [f"b{i}" for i in range(6)]


def manager(order: list[str]) -> Any:
    bdd = cudd.BDD()
    bdd.declare(*order)
    return bdd


# a function as a formula: a bit, its negation, a constant, or two joined
formulas = st.recursive(
    st.sampled_from(BITS).map(lambda b: ("bit", b)) | st.sampled_from([("true",), ("false",)]),
    lambda inner: st.tuples(st.sampled_from(["and", "or", "xor", "not"]), inner, inner),
    max_leaves=12,
)


def build(bdd: Any, formula: tuple[Any, ...]) -> Any:
    match formula:
        case ("bit", b):
            return bdd.var(b)
        case ("true",):
            return bdd.true
        case ("false",):
            return bdd.false
        case ("not", f, _):
            return ~build(bdd, f)
        case (op, f, g):
            x, y = build(bdd, f), build(bdd, g)
            return {"and": x & y, "or": x | y, "xor": (x & ~y) | (~x & y)}[op]
    raise AssertionError(formula)


@settings(max_examples=60, deadline=None)
@given(st.lists(formulas, min_size=1, max_size=6), st.permutations(BITS))
def test_roots_come_back_the_same_in_another_order(
    chosen: list[tuple[Any, ...]], order: list[str]
) -> None:
    source = manager(BITS)
    roots = {f"r{i}": build(source, f) for i, f in enumerate(chosen)}
    data = json.loads(json.dumps(to_data(roots)))  # through the text a cache file holds
    target = manager(order)
    back = from_data(target, data)
    assert set(back) == set(roots)
    for name, f in roots.items():
        assert target.copy(back[name], source) == f, name
    # a node and its negation share one entry
    assert len(data["nodes"]) <= sum(source.copy(f, source).dag_size for f in roots.values())


def test_constants_need_no_nodes() -> None:
    bdd = manager(BITS)
    data = to_data({"never": bdd.false, "always": bdd.true})
    assert data == {"nodes": [], "roots": {"never": 1, "always": 0}}


@pytest.mark.parametrize(
    ("data", "problem"),
    [
        ({"nodes": [["b0", 0, 7]], "roots": {"r": 2}}, "out of range"),
        ({"nodes": [["zz", 0, 1]], "roots": {"r": 2}}, "unknown bit 'zz'"),
        ({"nodes": [["b0", 0]], "roots": {"r": 2}}, "not \\[bit, low, high\\]"),
        ({"nodes": [], "roots": {"r": "x"}}, "out of range"),
    ],
)
def test_damaged_data_is_a_value_error(data: dict[str, Any], problem: str) -> None:
    with pytest.raises(ValueError, match=problem):
        from_data(manager(BITS), data)


def test_the_sat_engine_flattens_a_bdd_deeper_than_the_recursion_limit() -> None:
    """At 10,000 transitions the bad states read 8,000 bits along one path: the SAT
    engine's if-then-else circuit is built without recursion, one gate per node."""
    import sys
    from types import SimpleNamespace

    from planner.planning.bmc import BddCircuit

    depth = sys.getrecursionlimit() + 500
    bits = [f"x{i}" for i in range(depth)]
    bdd = manager(bits)
    chain = bdd.true
    for b in reversed(bits):
        chain = bdd.var(b) & chain  # x0 && x1 && ... : one node per bit, one path
    sym = SimpleNamespace(true=bdd.true, false=bdd.false)
    circuit = BddCircuit(sym, ~chain)  # type: ignore[arg-type]
    assert len(circuit.gates) == depth
    assert circuit.root == -(depth + 1)  # the last gate, x0's, negated
    assert circuit.gates[-1].bit == "x0"
