"""Self-checks of the reference oracle on hand-made models whose answers are known.

The oracle is what the real planner is judged against, so it must itself be checked
against cases worked out by hand (priority, effect chains, maintenance, phi, ...).
"""

from __future__ import annotations

import itertools
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support import oracle as O
from tests.support import strategies as S
from tests.support import strategies_structured as SS


def load(text: str) -> O.OracleModel:
    return O.parse_model(yaml.safe_load(text))


def st_(m: O.OracleModel, **values: object) -> O.State:
    """State from keyword values; dots in names are written as double underscores."""
    return O.state_from_dict(m, {k.replace("__", "."): v for k, v in values.items()})


# --------------------------------------------------------------------------- parsing

TWO_BOOLS = """
variables:
  - {name: a, domain: bool}
  - {name: b, domain: bool}
"""


def test_defaults_and_yaml_scalars() -> None:
    m = load(
        """
variables:
  - {name: r1.pos, domain: [home, tool, bp1], kind: measured}
  - {name: n, domain: [0, 1, 2], initial: 2}
  - {name: flag, domain: bool}
transitions:
  - {name: t}
  - {name: u, kind: automatic, guard: "n == 1", actions: ["n := 0"]}
specifications:
  - {name: s, invariant: "n != 0 || !flag"}
"""
    )
    assert [v.kind for v in m.variables] == ["measured", "estimated", "estimated"]
    assert m.variables[1].domain == ("0", "1", "2")
    assert O.initial_state(m) == ("home", "2", False)
    t = m.transitions[0]
    assert (t.kind, t.guard, t.actions) == ("controlled", "true", ())
    assert len(list(O.all_states(m))) == 18
    s = O.state_from_dict(m, {"r1.pos": "tool", "n": 1, "flag": True})
    assert s == ("tool", "1", True)
    assert O.state_to_dict(m, s) == {"r1.pos": "tool", "n": "1", "flag": True}
    assert O.steps(m, s, maintenance=False) == [("u", ("tool", "0", True))]


@pytest.mark.parametrize(
    "model",
    [
        {"variables": [{"name": "a", "domain": "int"}]},
        {"variables": [{"name": "a", "domain": []}]},
        {"variables": [{"name": "a", "domain": ["x", "x"]}]},
        {"variables": [{"name": "a", "domain": ["x"], "initial": "y"}]},
        {"variables": [{"name": "a", "domain": "bool"}, {"name": "a", "domain": "bool"}]},
        {"variables": [{"name": "1a", "domain": "bool"}]},
        {"variables": [{"name": "true", "domain": "bool"}]},
        {"transitions": [{"name": "t", "kind": "magic"}]},
        {"transitions": [{"name": "t", "guard": "nope"}]},
        {
            "variables": [{"name": "a", "domain": ["x", "y"]}],
            "transitions": [{"name": "t", "guard": "a"}],
        },
        {
            "variables": [{"name": "a", "domain": ["x", "y"]}],
            "transitions": [{"name": "t", "guard": "a == z"}],
        },
        {
            "variables": [{"name": "a", "domain": "bool"}],
            "transitions": [{"name": "t", "guard": "a &&"}],
        },
        {
            "variables": [{"name": "a", "domain": "bool"}],
            "transitions": [{"name": "t", "guard": "(a"}],
        },
        {
            "variables": [{"name": "a", "domain": "bool"}],
            "transitions": [{"name": "t", "guard": "a b"}],
        },
        {
            "variables": [{"name": "a", "domain": "bool"}],
            "transitions": [{"name": "t", "guard": "a = true"}],
        },
        {
            "variables": [{"name": "a", "domain": "bool"}],
            "transitions": [{"name": "t", "actions": ["a = true"]}],
        },
        {
            "variables": [{"name": "a", "domain": "bool"}],
            "transitions": [{"name": "t", "actions": ["a := x"]}],
        },
        {
            "variables": [{"name": "a", "domain": "bool"}],
            "transitions": [{"name": "t", "actions": ["a := true", "a := false"]}],
        },
        {
            "variables": [{"name": "a", "domain": ["x", "y"]}, {"name": "b", "domain": ["x", "z"]}],
            "transitions": [{"name": "t", "guard": "a == b"}],
        },
        {"variables": [{"name": "a", "domain": "bool"}], "specifications": [{"name": "s"}]},
        {"transitions": [{"name": "t"}, {"name": "t"}]},
    ],
)
def test_nonsense_is_rejected(model: dict[str, Any]) -> None:
    with pytest.raises(ValueError):
        O.parse_model(model)


@pytest.mark.parametrize(
    ("expr", "expected"),
    [
        ("false -> true -> false", True),  # right-associative
        ("true || false && false", True),  # && binds tighter than ||
        ("!true || true", True),  # ! binds tighter than ||
        ("!(true || true)", False),
        ("false && true -> false", True),  # -> is loosest
        ("true -> false || true", True),
        ("a", True),
        ("!a && b", False),
        ("a == true && b != true && a != b", True),
        ("b == false -> a == b", False),
        ("!a == true", False),  # ! over a comparison: !(a == true)
        ("((a))&&!b", True),
    ],
)
def test_expression_precedence(expr: str, expected: bool) -> None:
    m = load(TWO_BOOLS)
    assert O.evaluate(m, expr, (True, False)) is expected


def test_word_on_right_is_variable_first_and_actions_read_prestate() -> None:
    m = load(
        """
variables:
  - {name: x, domain: [p, q], initial: p}
  - {name: y, domain: [q, p], initial: q}
  - {name: p, domain: [p, q], initial: q}
transitions:
  - {name: swap, actions: ["x := y", "y := x"]}
  - {name: copy, actions: ["x := p"]}
"""
    )
    s = O.initial_state(m)
    assert O.evaluate(m, "x == p", s) is False  # p is the variable p (= q), not the value
    assert O.evaluate(m, "x != y", s)
    assert O.steps(m, s, maintenance=False) == [
        ("swap", ("q", "p", "q")),
        ("copy", ("q", "q", "q")),
    ]


# --------------------------------------------------------------------------- priority

PRIORITY = """
variables:
  - {name: door, domain: bool}
  - {name: light, domain: bool}
  - {name: done, domain: bool}
transitions:
  - {name: open, guard: "!door", actions: ["door := true"]}
  - {name: auto_light, kind: automatic, guard: "door && !light", actions: ["light := true"]}
  - {name: shortcut, guard: door, actions: ["done := true"]}
  - {name: finish, guard: light, actions: ["done := true"]}
"""


def test_plan_needs_automatic_priority() -> None:
    m = load(PRIORITY)
    s0 = O.initial_state(m)
    opened = st_(m, door=True, light=False, done=False)
    assert O.steps(m, opened, maintenance=True) == [
        ("auto_light", st_(m, door=True, light=True, done=False))
    ]
    assert O.plan(m, s0, "done", max_steps=5) == O.OracleResult("found", 3, [])
    assert O.plan(m, s0, "done", max_steps=2).status == "unreachable"
    assert O.replay(m, s0, ["open", "auto_light", "shortcut"], "done") is None
    msg = O.replay(m, s0, ["open", "shortcut"], "done")
    assert msg is not None and "step 1 (shortcut)" in msg
    # A disabled automatic transition no longer pre-empts anything.
    assert O.plan(m, s0, "done", max_steps=5, disabled=frozenset({"auto_light"})).length == 2
    assert O.replay(m, s0, ["open", "auto_light"], "light", disabled=frozenset({"auto_light"}))


def test_plan_may_end_where_an_automatic_step_is_pending() -> None:
    """Goal reached in a state with an automatic step pending still counts (plans may end)."""
    m = load(PRIORITY)
    result = O.plan(m, O.initial_state(m), "door && !light", max_steps=3)
    assert result == O.OracleResult("found", 1, [])


# --------------------------------------------------------------------------- bad states

EFFECT_CHAIN = """
variables:
  - {name: r.ref, domain: [home, bp]}
  - {name: r.pos, domain: [home, mid, bp]}
  - {name: q.pos, domain: [home, bp], initial: bp}
transitions:
  - {name: goto_bp, guard: "r.ref == home", actions: ["r.ref := bp"]}
  - {name: go_home, guard: "r.ref == bp", actions: ["r.ref := home"]}
  - {name: move, kind: effect, guard: "r.ref == bp && r.pos == home", actions: ["r.pos := mid"]}
  - {name: arrive, kind: effect, guard: "r.ref == bp && r.pos == mid", actions: ["r.pos := bp"]}
  - {name: back, kind: effect, guard: "r.ref == home && r.pos != home", actions: ["r.pos := home"]}
  - {name: q.leave, kind: maintenance, guard: "q.pos == bp", actions: ["q.pos := home"]}
specifications:
  - {name: not_both_at_bp, invariant: "!(r.pos == bp && q.pos == bp)"}
"""


def test_bad_state_reached_only_via_effect_chain() -> None:
    m = load(EFFECT_CHAIN)
    s0 = O.initial_state(m)
    requested = st_(m, r__ref="bp", r__pos="home", q__pos="bp")
    assert O.evaluate(m, "!(r.pos == bp && q.pos == bp)", requested)  # no direct violation
    assert requested in O.bad_states(m)  # ... but two effect steps lead into one
    assert O.violated(m, requested) == ["not_both_at_bp"]
    assert st_(m, r__ref="home", r__pos="mid", q__pos="bp") not in O.bad_states(m)
    assert O.plan(m, s0, "r.ref == bp", max_steps=6).status == "unreachable"
    msg = O.replay(m, s0, ["goto_bp"], "r.ref == bp")
    assert msg is not None and "bad" in msg
    # Once q has left, r may go: goto_bp, move, arrive.
    s1 = st_(m, r__ref="home", r__pos="home", q__pos="home")
    assert O.plan(m, s1, "r.pos == bp", max_steps=6) == O.OracleResult("found", 3, [])
    # Maintenance transitions are neither uncontrollable nor allowed unless asked for.
    assert O.plan(m, s0, "q.pos == home", max_steps=3).status == "unreachable"
    assert O.plan(m, s0, "q.pos == home", max_steps=3, maintenance=True).length == 1


def test_bad_states_ignore_query_disabled() -> None:
    m = load(EFFECT_CHAIN)
    s0 = O.initial_state(m)
    off = frozenset({"move", "arrive"})
    assert O.plan(m, s0, "r.ref == bp", max_steps=6, disabled=off).status == "unreachable"


def test_automatic_step_preempts_effect_in_bad_closure() -> None:
    """An enabled automatic transition means the dangerous effect cannot happen there."""
    m = load(
        EFFECT_CHAIN
        + """
  - {name: unused, invariant: "true"}
"""
    )
    guarded = yaml.safe_load(EFFECT_CHAIN)
    guarded["transitions"].append(
        {
            "name": "abort",
            "kind": "automatic",
            "guard": "r.ref == bp && r.pos == home && q.pos == bp",
            "actions": ["r.ref := home"],
        }
    )
    g = O.parse_model(guarded)
    requested = st_(g, r__ref="bp", r__pos="home", q__pos="bp")
    assert requested not in O.bad_states(g)
    assert O.steps(g, requested, maintenance=True) == [("abort", O.initial_state(g))]
    assert O.plan(g, O.initial_state(g), "r.ref == bp", max_steps=2).length == 1
    assert O.violated(m, requested) == ["not_both_at_bp"]


def test_automatic_step_into_violation_is_bad_and_maintenance_is_not() -> None:
    m = load(
        TWO_BOOLS
        + """
transitions:
  - {name: set_a, guard: "!a", actions: ["a := true"]}
  - {name: auto_b, kind: automatic, guard: "a && !b", actions: ["b := true"]}
  - {name: maint, kind: maintenance, guard: "!b", actions: ["b := true"]}
specifications:
  - {name: s, invariant: "!b"}
"""
    )
    assert O.bad_states(m) == frozenset({(True, False), (True, True), (False, True)})
    assert O.plan(m, (False, False), "a", max_steps=4).status == "unreachable"


def test_bad_start_reports_violated_names() -> None:
    m = load(
        EFFECT_CHAIN
        + """
  - {name: a_never_mid, invariant: "r.pos != mid"}
  - {name: z_q_home, invariant: "q.pos == bp"}
"""
    )
    requested = st_(m, r__ref="bp", r__pos="home", q__pos="bp")
    assert O.violated(m, requested) == ["a_never_mid", "not_both_at_bp"]
    assert O.bad_for_spec(m, "z_q_home") == frozenset(
        s for s in O.all_states(m) if O.state_to_dict(m, s)["q.pos"] == "home"
    )
    result = O.plan(m, requested, "true", max_steps=3)
    assert result == O.OracleResult("bad_start", None, ["a_never_mid", "not_both_at_bp"])
    both = O.plan(m, requested, "true", max_steps=3, forbidden=("false", "r.ref == bp"))
    assert both.violated == ["a_never_mid", "not_both_at_bp", "forbidden[1]"]
    assert O.replay(m, requested, [], "true") is not None
    with pytest.raises(ValueError):
        O.bad_for_spec(m, "nope")


# --------------------------------------------------------------------------- query extensions

DIAMOND = """
variables:
  - {name: x, domain: [s0, s1, s2, s3, g]}
transitions:
  - {name: a, guard: "x == s0", actions: ["x := s1"]}
  - {name: b, guard: "x == s1", actions: ["x := g"]}
  - {name: c, guard: "x == s0", actions: ["x := s2"]}
  - {name: d, guard: "x == s2", actions: ["x := s3"]}
  - {name: e, guard: "x == s3", actions: ["x := g"]}
"""


def test_phi_until() -> None:
    m = load(DIAMOND)
    s0 = O.initial_state(m)
    assert O.plan(m, s0, "x == g", max_steps=5).length == 2
    assert O.plan(m, s0, "x == g", max_steps=5, phi="x != s1").length == 3
    assert O.plan(m, s0, "x == g", max_steps=5, phi="x != g").length == 2  # last state exempt
    assert O.plan(m, s0, "x == g", max_steps=5, phi="x != s0").status == "unreachable"
    assert O.plan(m, s0, "x == s0", max_steps=5, phi="false").length == 0  # 0 steps: no phi
    assert O.replay(m, s0, ["c", "d", "e"], "x == g", phi="x != s1") is None
    msg = O.replay(m, s0, ["a", "b"], "x == g", phi="x != s1")
    assert msg is not None and "phi" in msg and "step 1" in msg


def test_forbidden_states() -> None:
    m = load(DIAMOND)
    s0 = O.initial_state(m)
    assert O.plan(m, s0, "x == g", max_steps=5, forbidden=("x == s1",)).length == 3
    both = ("x == s1", "x == s3")
    assert O.plan(m, s0, "x == g", max_steps=5, forbidden=both).status == "unreachable"
    assert O.plan(m, s0, "x == g", max_steps=5, forbidden=("x == g",)).status == "unreachable"
    result = O.plan(m, s0, "x == g", max_steps=5, forbidden=("x == s3", "x != g", "x == s0"))
    assert result == O.OracleResult("bad_start", None, ["forbidden[1]", "forbidden[2]"])
    msg = O.replay(m, s0, ["a", "b"], "x == g", forbidden=("x == s1",))
    assert msg is not None and "forbidden[0]" in msg


def test_forbidden_is_not_extended_backwards() -> None:
    m = load(EFFECT_CHAIN)
    s1 = st_(m, r__ref="home", r__pos="home", q__pos="home")
    result = O.plan(m, s1, "r.ref == bp", max_steps=3, forbidden=("r.pos == bp",))
    assert result.length == 1
    # ... although the effect chain from there would end in a forbidden state.
    assert O.plan(m, s1, "r.pos == bp", max_steps=6, forbidden=("r.pos == bp",)).length is None


def test_disabled_and_max_steps() -> None:
    m = load(DIAMOND)
    s0 = O.initial_state(m)
    assert O.plan(m, s0, "x == g", max_steps=5, disabled=frozenset({"b"})).length == 3
    assert O.plan(m, s0, "x == g", max_steps=2, disabled=frozenset({"b"})).status == "unreachable"
    assert O.plan(m, s0, "x == g", max_steps=0).status == "unreachable"
    msg = O.replay(m, s0, ["a", "b"], "x == g", disabled=frozenset({"b"}))
    assert msg is not None and "step 1 (b)" in msg
    assert O.replay(m, s0, ["a"], "x == g") is not None  # goal not reached
    with pytest.raises(ValueError):
        O.plan(m, s0, "x == g", max_steps=3, disabled=frozenset({"zz"}))


def test_maintenance_only_when_allowed() -> None:
    m = load(
        TWO_BOOLS
        + """
transitions:
  - {name: calibrate, kind: maintenance, guard: "!a", actions: ["a := true"]}
  - {name: work, guard: a, actions: ["b := true"]}
"""
    )
    s0 = O.initial_state(m)
    assert O.steps(m, s0, maintenance=False) == []
    assert O.steps(m, s0, maintenance=True) == [("calibrate", (True, False))]
    assert O.plan(m, s0, "b", max_steps=4).status == "unreachable"
    assert O.plan(m, s0, "b", max_steps=4, maintenance=True).length == 2
    assert O.replay(m, s0, ["calibrate", "work"], "b") is not None
    assert O.replay(m, s0, ["calibrate", "work"], "b", maintenance=True) is None


# --------------------------------------------------------------------------- cycles


@pytest.mark.parametrize(
    ("transitions", "expected"),
    [
        ([{"name": "t", "kind": "automatic", "guard": "!a", "actions": ["a := true"]}], False),
        ([{"name": "t", "kind": "automatic", "guard": "a", "actions": ["a := true"]}], True),
        ([{"name": "t", "kind": "automatic", "guard": "a && b"}], True),  # no actions: self-loop
        (
            [
                {"name": "t", "kind": "automatic", "guard": "a", "actions": ["a := false"]},
                {"name": "u", "kind": "automatic", "guard": "!a", "actions": ["a := true"]},
            ],
            True,
        ),
        (
            [
                {"name": "t", "kind": "effect", "guard": "a", "actions": ["a := false"]},
                {"name": "u", "kind": "effect", "guard": "!a", "actions": ["a := true"]},
            ],
            False,
        ),
        (
            [
                {"name": "t", "kind": "automatic", "guard": "a && !b", "actions": ["b := true"]},
                {"name": "u", "kind": "automatic", "guard": "b", "actions": ["b := false"]},
            ],
            True,
        ),
    ],
)
def test_automatic_cycle(transitions: list[dict[str, Any]], expected: bool) -> None:
    model = yaml.safe_load(TWO_BOOLS)
    model["transitions"] = transitions
    assert O.has_automatic_cycle(O.parse_model(model)) is expected


# --------------------------------------------------------------------------- strategies


def brute_force_length(
    m: O.OracleModel, start: O.State, goal: str, max_steps: int, **query: Any
) -> int | None:
    """Shortest legal plan by enumerating every name sequence and replaying it."""
    names = [t.name for t in m.transitions]
    for k in range(max_steps + 1):
        for seq in itertools.product(names, repeat=k):
            if O.replay(m, start, list(seq), goal, **query) is None:
                return k
    return None


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_strategies_yield_valid_models_and_plan_agrees_with_replay(data: st.DataObject) -> None:
    d = data.draw(S.flat_models(max_vars=3, max_transitions=4))
    m = O.parse_model(d)
    q = data.draw(S.queries(d))
    ext = data.draw(S.query_extensions(d, q["start"]))
    start = O.state_from_dict(m, q["start"])
    query: dict[str, Any] = {
        "maintenance": q["maintenance"],
        "forbidden": tuple(ext["forbidden"]),
        "phi": ext["phi"],
        "disabled": frozenset(ext["disabled"]),
    }
    max_steps = min(ext["max_steps"], 3)
    result = O.plan(m, start, q["goal"], max_steps=max_steps, **query)
    if result.status == "bad_start":
        assert result.violated
        assert O.replay(m, start, [], q["goal"], **query) is not None
    else:
        assert result.length == brute_force_length(m, start, q["goal"], max_steps, **query)


# --------------------------------------------------------------------------- recovery

# r may stand at bp while q is there only in recovery; `r.pos == mid` is forbidden by a kept
# specification, and an effect chain makes every state on the way in bad by closure
RECOVERY = """
variables:
  - {name: r.ref, domain: [home, bp]}
  - {name: r.pos, domain: [home, mid, bp]}
  - {name: q.pos, domain: [home, bp], initial: bp}
transitions:
  - {name: goto_bp, guard: "r.ref == home", actions: ["r.ref := bp"]}
  - {name: go_home, guard: "r.ref == bp", actions: ["r.ref := home"]}
  - {name: move, kind: effect, guard: "r.ref == bp && r.pos == home", actions: ["r.pos := mid"]}
  - {name: arrive, kind: effect, guard: "r.ref == bp && r.pos == mid", actions: ["r.pos := bp"]}
  - {name: back, kind: effect, guard: "r.ref == home && r.pos == bp", actions: ["r.pos := home"]}
  - {name: q.leave, kind: maintenance, guard: "q.pos == bp", actions: ["q.pos := home"]}
specifications:
  - {name: not_both_at_bp, invariant: "!(r.pos == bp && q.pos == bp)"}
  - {name: a_never_mid_with_q_home, invariant: "!(r.pos == mid && q.pos == home)"}
"""


def test_relaxed_plan_may_cross_the_dropped_specification_and_ends_good() -> None:
    m = load(RECOVERY)
    collided = st_(m, r__ref="bp", r__pos="bp", q__pos="bp")
    assert O.violated(m, collided) == ["not_both_at_bp"]
    relaxed = frozenset({"not_both_at_bp"})
    assert O.plan(m, collided, "true", max_steps=5).status == "bad_start"
    # go_home, back: r leaves q; the start violates the dropped specification itself
    result = O.plan(m, collided, "true", max_steps=5, relaxed=relaxed)
    assert result == O.OracleResult("found", 2, [])
    assert O.replay(m, collided, ["go_home", "back"], "true", relaxed=relaxed) is None
    # stopping half-way is no recovery: the last state must be good
    msg = O.replay(m, collided, ["go_home"], "true", relaxed=relaxed)
    assert msg is not None and "be good" in msg
    # a goal state that is good is a plan of no steps; one that is not, is no plan
    good = st_(m, r__ref="home", r__pos="home", q__pos="bp")
    assert O.plan(m, good, "true", max_steps=3, relaxed=relaxed).length == 0
    assert O.plan(m, collided, "q.pos == bp", max_steps=1, relaxed=relaxed).status == (
        "unreachable"
    )
    with pytest.raises(ValueError):
        O.plan(m, collided, "true", max_steps=3, relaxed=frozenset({"nope"}))


def test_relaxed_plan_keeps_the_supervisor_of_the_other_specifications() -> None:
    m = load(RECOVERY)
    relaxed = frozenset({"not_both_at_bp"})
    s0 = st_(m, r__ref="home", r__pos="home", q__pos="home")
    # goto_bp makes the state bad by closure of the kept specification (move leads to mid
    # with q home): a normal plan may not go there, and a recovery plan may not either
    requested = st_(m, r__ref="bp", r__pos="home", q__pos="home")
    assert O.violated(m, requested) == ["a_never_mid_with_q_home"]
    assert O.plan(m, s0, "r.ref == bp", max_steps=3).status == "unreachable"
    assert O.plan(m, s0, "r.ref == bp", max_steps=3, relaxed=relaxed).status == "unreachable"
    msg = O.replay(m, s0, ["goto_bp", "go_home"], "r.ref == home", relaxed=relaxed)
    assert msg is not None and "a_never_mid_with_q_home" in msg


def test_relaxed_drops_the_specifications_the_start_is_already_bad_for() -> None:
    m = load(RECOVERY)
    # mid violates a_never_mid_with_q_home: recovery cannot keep its supervisor, so it is
    # dropped with the named one; the effect `arrive` leads to a good state
    mid = st_(m, r__ref="bp", r__pos="mid", q__pos="home")
    result = O.plan(m, mid, "true", max_steps=3, relaxed=frozenset({"not_both_at_bp"}))
    assert result == O.OracleResult("found", 1, [])
    assert O.replay(m, mid, ["arrive"], "true", relaxed=frozenset({"not_both_at_bp"})) is None
    # the same when the start is only bad by closure: going home makes it good
    requested = st_(m, r__ref="bp", r__pos="home", q__pos="home")
    again = O.plan(m, requested, "true", max_steps=3, relaxed=frozenset({"not_both_at_bp"}))
    assert again == O.OracleResult("found", 1, [])
    # a recovery start is bad only for a forbidden predicate
    both = O.plan(
        m,
        mid,
        "true",
        max_steps=3,
        relaxed=frozenset({"a_never_mid_with_q_home"}),
        forbidden=("q.pos == home",),
    )
    assert both.violated == ["forbidden[0]"]


# --------------------------------------------------------------------------- maintenance cost


def test_maintenance_cost_weighs_a_maintenance_step_against_steps() -> None:
    m = load(SS.SHORTCUTS)
    s0 = O.initial_state(m)
    costly = {"maintenance": True, "maintenance_cost": 10}
    assert O.plan(m, s0, "x == v3", max_steps=5, maintenance=True).length == 1
    assert O.plan(m, s0, "x == v3", max_steps=5, **costly) == O.OracleResult("found", 3, [], 0)
    # a cost of 3 ties the jump with the chain of three: the fewer maintenance steps win
    tie = {"maintenance": True, "maintenance_cost": 3}
    assert O.plan(m, s0, "x == v3", max_steps=5, **tie) == O.OracleResult("found", 3, [], 0)
    cheap = {"maintenance": True, "maintenance_cost": 2}
    assert O.plan(m, s0, "x == v3", max_steps=5, **cheap) == O.OracleResult("found", 1, [], 1)
    both = "x == v3 && y == v3"
    assert O.plan(m, s0, both, max_steps=6, **costly) == O.OracleResult("found", 6, [], 0)
    # a bound on the steps forces maintenance: one jump and one chain fit in 4
    assert O.plan(m, s0, both, max_steps=4, **costly) == O.OracleResult("found", 4, [], 1)
    assert O.plan(m, s0, both, max_steps=2, **costly) == O.OracleResult("found", 2, [], 2)
    assert O.plan(m, s0, both, max_steps=1, **costly).status == "unreachable"
    # without maintenance there is nothing to weigh: a plain query
    plain = O.plan(m, s0, both, max_steps=6, maintenance_cost=10)
    assert plain == O.OracleResult("found", 6, [])
    assert O.plan(m, s0, "x == v0", max_steps=3, **costly) == O.OracleResult("found", 0, [], 0)
    assert O.maintenance_steps(m, ["x.c0", "x.jump", "y.jump"]) == 2


def brute_force_cheapest(
    m: O.OracleModel, start: O.State, goal: str, max_steps: int, cost: int, **query: Any
) -> tuple[int, int] | None:
    """(maintenance steps, length) of the cheapest legal plan, by enumeration: a maintenance
    step costs `cost`, any other 1; ties go to fewer maintenance steps, then fewer steps."""
    names = [t.name for t in m.transitions]
    best: tuple[int, int, int] | None = None
    for k in range(max_steps + 1):
        for seq in itertools.product(names, repeat=k):
            if O.replay(m, start, list(seq), goal, **query) is None:
                steps = O.maintenance_steps(m, list(seq))
                key = (k + (cost - 1) * steps, steps, k)
                best = key if best is None else min(best, key)
    return None if best is None else (best[1], best[2])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_relaxed_and_weighted_maintenance_plans_agree_with_brute_force(
    data: st.DataObject,
) -> None:
    d = data.draw(S.flat_models(max_vars=3, max_transitions=4))
    m = O.parse_model(d)
    q = data.draw(S.queries(d))
    start = O.state_from_dict(m, q["start"])
    names = [s.name for s in m.specs]
    relaxed = frozenset(data.draw(st.lists(st.sampled_from(names), max_size=2))) if names else ()
    query: dict[str, Any] = {"maintenance": q["maintenance"], "relaxed": frozenset(relaxed)}
    max_steps = 3
    cost = data.draw(st.sampled_from([1, 2, 10]))
    result = O.plan(m, start, q["goal"], max_steps=max_steps, maintenance_cost=cost, **query)
    if result.status == "bad_start":
        assert result.violated
        assert O.replay(m, start, [], q["goal"], **query) is not None
        return
    if cost > 1 and q["maintenance"]:
        best = brute_force_cheapest(m, start, q["goal"], max_steps, cost, **query)
        found = None if result.length is None else (result.maintenance_steps, result.length)
        assert found == best
    else:
        assert result.length == brute_force_length(m, start, q["goal"], max_steps, **query)
