"""Words, not names (issue 16): display names in the model, checked and located; the words
a page shows for every name; and the demo station worded throughout."""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import pytest
import yaml

from planner.model.expressions import Equals, Not
from planner.model.station import Station
from planner.reading import load_model, load_station
from planner.reading.yaml_reader import ModelError
from planner.words import Wording, clean, sentence
from tests.support.paths import REPOSITORY
from tests.web.test_no_internal_names import internal_names, offences

ROOT = REPOSITORY
DEMO = ROOT / "models" / "demo_station.yaml"

MODEL = """\
station: mini_station
display: "the mini station"
variables:
  - {name: bp1.state, domain: [empty, placed], kind: decision, display: "bolt pair 1",
     display_values: {empty: "not placed", placed: "placed"}}
resources:
  - name: r1
    display: "robot 1"
    variables:
      - {name: pos, domain: [home, bp1], kind: measured, display: "where robot 1 is"}
      - {name: ref, domain: [home, bp1], kind: command}
      - {name: busy, domain: bool, display: "robot 1's work",
         display_values: {true: "busy", false: "free"}}
    abilities:
      - name: goto
        display: "go to {target}"
        parameter: {name: target, values: [home, bp1], display_values: {bp1: "bolt pair 1"}}
        predicates:
          enabled: "pos == ref && ref != {target}"
          executing: "pos != ref"
        transitions:
          - {name: start, guard: enabled, actions: ["ref := {target}"]}
          - {name: arrive, kind: effect, guard: executing, actions: ["pos := ref"],
             display: "arrive"}
    transitions:
      - {name: push_home, kind: maintenance, actions: ["pos := home", "ref := home"],
         description: "push robot 1 home by hand (E6, E7)"}
  - name: nr
    description: smart nutrunner (seed 003 Table I)
    variables:
      - {name: run, domain: bool, kind: command}
specifications:
  - {name: one_at_bp1, invariant: "!(r1.pos == bp1 && nr.run)", display: "never both at once"}
operations:
  - name: place_{bp}
    display: "place {bp}"
    parameter: {name: bp, values: [bp1], display_values: {bp1: "bolt pair 1"}}
    precondition: "{bp}.state == empty"
    effects: ["{bp}.state := placed"]
intentions:
  - {name: assemble, goal: "bp1.state == placed", display: "assemble it"}
"""


@pytest.fixture(scope="module")
def words() -> Wording:
    return Wording(load_station(MODEL, "mini.yaml"))


def problems(old: str, new: str) -> list[str]:
    assert MODEL.count(old) == 1, old
    with pytest.raises(ModelError) as raised:
        load_station(MODEL.replace(old, new), "mini.yaml")
    return [str(d) for d in raised.value.diagnostics]


def at(old: str, new: str, fragment: str) -> str:
    """`file:line:column` of `fragment` (inside `new`) once `old` is replaced by `new`."""
    text = MODEL.replace(old, new)
    offset = text.index(new) + new.index(fragment)
    line = text[:offset].count("\n") + 1
    column = offset - (text.rfind("\n", 0, offset) + 1) + 1
    return f"mini.yaml:{line}:{column}"


# ---- located errors ---------------------------------------------------------------------------

# each kind of item, by the display it has in MODEL, and what a message calls it
KINDS = [
    ('display: "the mini station"', "station 'mini_station'"),
    ('display: "robot 1"', "resource 'r1'"),
    ('display: "bolt pair 1",', "variable 'bp1.state'"),
    ('display: "where robot 1 is"', "variable 'r1.pos'"),
    ('display: "go to {target}"', "ability 'r1.goto'"),
    ('display: "arrive"', "transition 'r1.goto.arrive'"),
    ('display: "never both at once"', "specification 'one_at_bp1'"),
    ('display: "place {bp}"', "operation 'place_{bp}'"),
    ('display: "assemble it"', "intention 'assemble'"),
]
BAD = [
    ("3", "must be words, not a number (3); put it in quotes"),
    ("true", "must be words, not a yes/no value (true); put it in quotes"),
    ('""', "is empty; write the words a person reads, or leave it out"),
    ("null", "is empty; write the words a person reads, or leave it out"),
    ("[a, b]", "must be words, not a list or mapping"),
    ('"' + "x" * 81 + '"', "is 81 characters; at most 80 fit a watch card"),
    ('"a } b"', "has a '}' that opens or closes no placeholder"),
]


@pytest.mark.parametrize(("display", "kind"), KINDS)
@pytest.mark.parametrize(("bad", "message"), BAD)
def test_a_bad_display_is_located_at_its_value(
    display: str, kind: str, bad: str, message: str
) -> None:
    new = display.replace(display.split(": ", 1)[1].rstrip(","), bad)
    found = problems(display, new)
    fragment = "}" if "}" in bad else bad
    assert found == [f"{at(display, new, fragment)}: the display of {kind} {message}"]


@pytest.mark.parametrize(("display", "kind"), KINDS)
def test_an_unknown_placeholder_is_located_at_its_brace(display: str, kind: str) -> None:
    new = display.replace(display.split(": ", 1)[1].rstrip(","), '"to {where} now"')
    (found,) = problems(display, new)
    location, message = found.split(": ", 1)
    assert location == at(display, new, "{where}")
    assert message.startswith(f"the display of {kind} names '{{where}}'")
    # a parameterised item says which placeholders it has
    if kind.startswith(("ability", "operation", "transition")):
        assert message.endswith("it may only name {target}" if "r1" in kind else "{bp}")
    else:
        assert message.endswith("but there is no parameter")


def test_a_multi_line_display_is_refused() -> None:
    (found,) = problems('    display: "robot 1"\n', "    display: |\n      robot\n      one\n")
    assert found == "mini.yaml:8:14: the display of resource 'r1' must be one line"


def test_a_misspelt_key_is_refused_with_a_hint() -> None:
    (found,) = problems('    display: "robot 1"', '    dispaly: "robot 1"')
    assert found.startswith("mini.yaml:8:5: unknown key 'dispaly' in a resource")
    assert "(did you mean 'display'?)" in found


DISPLAY_VALUES = [
    (
        '{empty: "not placed", placed: "placed"}',
        '{empty: "not placed", plced: "placed"}',
        "plced",
        "'plced' is not a value of variable 'bp1.state' (did you mean 'placed'?); "
        "its values: empty, placed",
    ),
    (
        '{true: "busy", false: "free"}',
        '{true: "busy", maybe: "free"}',
        "maybe",
        "'maybe' is not a value of variable 'r1.busy'; its values: true, false",
    ),
    (
        '{true: "busy", false: "free"}',
        '{true: "busy", true: "free"}',
        'true: "free"',
        "'true' is given words twice in the display_values of variable 'r1.busy'",
    ),
    (
        '{true: "busy", false: "free"}',
        '{true: "", false: "free"}',
        '""',
        "the words for 'true' of variable 'r1.busy' is empty; write the words a person "
        "reads, or leave it out",
    ),
    (
        '{true: "busy", false: "free"}',
        "[busy, free]",
        "[busy",
        "the display_values of variable 'r1.busy' must be a mapping (value: words)",
    ),
    (
        'values: [home, bp1], display_values: {bp1: "bolt pair 1"}',
        'values: [home, bp1], display_values: {bp7: "bolt pair 7"}',
        "bp7",
        "'bp7' is not a value of the parameter 'target' of ability 'goto' (did you mean "
        "'bp1'?); its values: home, bp1",
    ),
]


@pytest.mark.parametrize(("old", "new", "fragment", "message"), DISPLAY_VALUES)
def test_bad_display_values_are_located(old: str, new: str, fragment: str, message: str) -> None:
    assert MODEL.count(old) == 1 or "busy" in old
    text = MODEL.replace(old, new, 1)
    with pytest.raises(ModelError) as raised:
        load_station(text, "mini.yaml")
    offset = text.index(new) + new.index(fragment)
    line = text[:offset].count("\n") + 1
    column = offset - (text.rfind("\n", 0, offset) + 1) + 1
    assert [str(d) for d in raised.value.diagnostics] == [f"mini.yaml:{line}:{column}: {message}"]


def test_a_transition_made_once_cannot_name_the_parameter() -> None:
    old, new = 'display: "arrive"', 'display: "arrive at {target}"'
    (found,) = problems(old, new)
    assert found == (
        f"{at(old, new, new[9:])}: "
        "transition 'r1.goto.arrive' is the same for every value of 'target', so it is made "
        "once: its display cannot name '{target}'"
    )


def test_words_too_long_once_filled_in_are_refused() -> None:
    long = "a bolt pair with a name so much longer than any card on a watch could show it"  # 77
    (found,) = problems(
        'display_values: {bp1: "bolt pair 1"}}\n        predicates',
        f'display_values: {{bp1: "{long}"}}}}\n        predicates',
    )
    display = 'display: "go to {target}"'
    filled = f"go to {long}"
    assert found == (
        f"{at(display, display, display[9:])}: the display of ability 'r1.goto' is "
        f"{len(filled)} characters; at most 80 fit a watch card once filled in: '{filled}'"
    )


def test_every_problem_is_reported_at_once() -> None:
    text = MODEL.replace('display: "robot 1"', "display: 3").replace(
        'display: "assemble it"', 'display: ""'
    )
    with pytest.raises(ModelError) as raised:
        load_station(text, "mini.yaml")
    assert len(raised.value.diagnostics) == 2


# ---- the flat form: unchanged, with the same keys added -----------------------------------------

FLAT = """\
variables:
  - {name: r1.pos, domain: [home, tool, bp1], initial: home, kind: estimated}
  - {name: nr.running, domain: bool, initial: false, kind: measured}
transitions:
  - {name: r1.goto_bp1, guard: "r1.pos == home && !nr.running", actions: ["r1.pos := bp1"]}
specifications:
  - {name: not_at_bp1, invariant: "!(r1.pos == bp1 && nr.running)"}
"""


def test_the_flat_form_takes_display_keys_as_words_only() -> None:
    worded = (
        FLAT.replace(
            "kind: estimated}\n  - {name: nr",
            'kind: estimated,\n     display: "robot 1", display_values: {bp1: "on bolt pair 1"}}\n'
            "  - {name: nr",
        )
        .replace('actions: ["r1.pos := bp1"]}', 'actions: ["r1.pos := bp1"], display: "go"}')
        .replace('nr.running)"}', 'nr.running)", display: "never both"}')
    )
    plain, flat = load_model(FLAT, "flat.yaml"), load_model(worded, "flat.yaml")
    assert plain == flat  # words change no variable, transition or specification
    words = Wording(load_station(worded, "flat.yaml"))
    assert words.value("r1.pos", "bp1") == "robot 1 is on bolt pair 1"
    assert words.transition("r1.goto_bp1") == "go"
    assert words.specification("not_at_bp1") == "never both"
    # without words, a flat model's names are humanised
    bare = Wording(load_station(FLAT, "flat.yaml"))
    assert (bare.variable("nr.running"), bare.transition("r1.goto_bp1")) == (
        "nr running",
        "r1 goto bp1",
    )


def test_a_bad_display_in_the_flat_form_is_located() -> None:
    text = FLAT.replace('nr.running)"}', 'nr.running)", display: 7}')
    with pytest.raises(ModelError) as raised:
        load_model(text, "flat.yaml")
    assert [str(d) for d in raised.value.diagnostics] == [
        "flat.yaml:7:78: the display of specification 'not_at_bp1' must be words, not a "
        "number (7); put it in quotes"
    ]


def _without_words(node: Any) -> Any:
    if isinstance(node, dict):
        return {
            k: _without_words(v) for k, v in node.items() if k not in ("display", "display_values")
        }
    if isinstance(node, list):
        return [_without_words(v) for v in node]
    return node


@pytest.mark.parametrize("text", [MODEL, DEMO.read_text()], ids=["mini", "demo"])
def test_display_keys_are_words_only(text: str) -> None:
    """The same station with every display key removed plans exactly the same."""
    worded = load_station(text, "m.yaml")
    plain = load_station(yaml.safe_dump(_without_words(yaml.safe_load(text))), "m.yaml")

    def semantics(station: Station) -> tuple[object, ...]:
        model = station.model
        return (
            [(v.name, v.domain, v.initial, v.kind) for v in model.variables],
            [(t.name, t.kind, t.guard, t.actions, t.description) for t in model.transitions],
            [(s.name, s.invariant) for s in model.specifications],
            [dataclasses.replace(o, display="") for o in station.operations],
            [dataclasses.replace(i, display="") for i in station.intentions],
            [dataclasses.replace(a, display="") for a in station.abilities],
            [dataclasses.replace(r, display="") for r in station.resources],
            station.predicates,
            station.restart_transitions,
        )

    assert semantics(worded) == semantics(plain)
    assert any(t.display for t in worded.model.transitions)
    assert not any(t.display for t in plain.model.transitions)


# ---- the words a page shows ----------------------------------------------------------------------


def test_display_names_are_used(words: Wording) -> None:
    assert words.station() == "the mini station"
    assert words.resource("r1") == "robot 1"
    assert words.variable("bp1.state") == "bolt pair 1"
    assert words.specification("one_at_bp1") == "never both at once"
    assert words.intention("assemble") == "assemble it"


def test_placeholders_are_filled_per_instance(words: Wording) -> None:
    # a value with words gets them; one without is humanised
    assert words.ability("r1.goto_bp1") == "go to bolt pair 1"
    assert words.ability("r1.goto_home") == "go to home"
    # an ability's start transition is the ability, unless it has a display of its own
    assert words.transition("r1.goto_bp1") == "go to bolt pair 1"
    assert words.operation("place_bp1") == "place bolt pair 1"


def test_fallbacks_are_the_description_then_the_name(words: Wording) -> None:
    # no display: the description, without its references
    assert words.resource("nr") == "smart nutrunner"
    assert words.transition("r1.push_home") == "push robot 1 home by hand"
    # neither: the name humanised (a resource's own transition without its resource)
    assert words.variable("r1.ref") == "r1 ref"
    assert words.variable("nr.run") == "nr run"
    assert words.station() != "mini_station"
    assert Wording(load_station(MODEL.replace('display: "the mini station"\n', ""))).station() == (
        "mini station"
    )
    # names the model does not have are humanised, never an error
    assert words.operation("no_such_thing") == "no such thing"
    assert words.transition("r9.fly.away") == "r9 fly away"


def test_values_read_as_statements(words: Wording) -> None:
    assert words.value("bp1.state", "placed") == "bolt pair 1 is placed"
    assert words.not_value("bp1.state", "placed") == "bolt pair 1 is not placed"
    assert words.value_name("bp1.state", "empty") == "not placed"
    # a boolean: its words, also when a form sends "true"/"false" as text
    assert words.value("r1.busy", True) == "robot 1's work is busy"
    assert words.value("r1.busy", "false") == "robot 1's work is free"
    assert words.not_value("r1.busy", True) == "robot 1's work is free"
    # no words for the value: a colon, never "is" before a bare value
    assert words.value("r1.pos", "bp1") == "where robot 1 is: bp1"
    assert words.value("nr.run", True) == "nr run: yes"
    assert words.not_value("r1.ref", "home") == "r1 ref: not home"


def test_conditions_in_words(words: Wording) -> None:
    station = load_station(MODEL, "mini.yaml")
    assert words.condition(station.operation("place_bp1").precondition) == (
        "bolt pair 1 is not placed"
    )
    spec = station.model.specifications[0].invariant
    assert words.condition(spec) == "not (where robot 1 is: bp1 and nr run: yes)"
    assert words.condition(Not(Equals("r1.pos", "home"))) == "where robot 1 is: not home"


def test_steps_name_who_does_them(words: Wording) -> None:
    assert words.owner("r1.goto.arrive") == "robot 1"
    assert words.step("r1.goto.arrive") == "robot 1: arrive"
    assert words.owner("r1.pos") == "robot 1"
    assert words.owner("bp1.state") == ""
    assert words.step("no.such") == "no such"


def test_names_in_free_text_become_words(words: Wording) -> None:
    assert words.name("place_bp1") == "place bolt pair 1"
    assert words.names(["r1", "nr", "assemble"]) == "robot 1, smart nutrunner and assemble it"
    assert words.text("place_bp1 failed: r1.goto.arrive timed out (operation place_bp1)") == (
        "place bolt pair 1 failed: arrive timed out"
    )
    # a name its own words contain is left alone ("assemble" → "assemble it")
    assert words.text("assemble the engine") == "assemble the engine"


# ---- sentences ---------------------------------------------------------------------------------

REFERENCES = [
    ("the operator places bolt pair 1 (seed 003 PlaceBolt_i)", "The operator places bolt pair 1"),
    ("move r2 home by hand (E6, E7)", "Move r2 home by hand"),
    ("every bolt pair tightened (seed 000 Figure 6)", "Every bolt pair tightened"),
    ("Failed: r2 docks onto nr (operation get_nr_r2)", "Failed: r2 docks onto nr"),
    ("holds one robot (seed 000 6.1, E6)", "Holds one robot"),
    ("r1 docks onto it (seed 003 GetNRTool, GetLFTool)", "R1 docks onto it"),
    ("the frame (seed 003 Table VI: lf = onMir / onEngine)", "The frame"),
    ("restart mode only (seed 001 VIII-A), as for r1", "Restart mode only, as for r1"),
    ("E1 (seed 000 Table 1): a bolt pair", "E1: a bolt pair"),
    ("plans use r1 alone (experiments E5-E7).", "Plans use r1 alone."),
    ("bolts placed (by hand, E1/E2)", "Bolts placed (by hand)"),
    (
        "off the pose (pushed aside, stopped mid-way)",
        "Off the pose (pushed aside, stopped mid-way)",
    ),
]


@pytest.mark.parametrize(("text", "expected"), REFERENCES)
def test_sentence_strips_references(text: str, expected: str) -> None:
    assert sentence(text) == expected


PAPER = re.compile(
    r"\bseed \d|\bE\d+\b|\bFig(?:ure|\.)|\bTables? [\dIVX]|\bDefinition|\bsec\. \d|DESIGN\.md"
)


def _strings(node: yaml.Node) -> list[str]:
    if isinstance(node, yaml.ScalarNode):
        return [str(node.value)] if node.tag.endswith(":str") else []
    children = node.value if isinstance(node, yaml.SequenceNode) else []
    if isinstance(node, yaml.MappingNode):
        children = [v for _, v in node.value]
    return [s for child in children for s in _strings(child)]


def test_sentence_strips_every_reference_in_the_models() -> None:
    """Every parenthesised reference in any text of models/ is gone after `clean`."""
    texts = [
        s
        for path in sorted((ROOT / "models").rglob("*.yaml"))
        for s in _strings(yaml.compose(path.read_text()))
    ]
    referring = [t for t in texts if re.search(r"\([^()]*(?:seed \d|E\d|Table|Figure)", t)]
    assert len(referring) >= 15  # the check looks at real texts
    for text in referring:
        cleaned = clean(text)
        assert not re.search(r"\([^()]*" + PAPER.pattern.replace("\\bE\\d+\\b|", ""), cleaned), (
            text,
            cleaned,
        )
        assert not re.search(r"\([^()]*\bE\d", cleaned), (text, cleaned)


# ---- the demo station: words for everything a person sees ------------------------------------


@pytest.fixture(scope="module")
def demo() -> Station:
    return load_station(DEMO.read_text(), str(DEMO))


def identifiers_in(words: str, station: Station) -> list[str]:
    """The model identifiers in `words`, by the rule every page is scanned with
    (tests/web/test_no_internal_names.py)."""
    return offences(words, internal_names(station))


def _everything(station: Station, words: Wording) -> dict[str, str]:
    """Every name a page can show, with its words."""
    model = station.model
    shown = {f"station {station.name}": words.station()}
    shown |= {f"resource {r.name}": words.resource(r.name) for r in station.resources}
    for v in model.variables:
        shown[f"variable {v.name}"] = words.variable(v.name)
        for value in v.domain:
            shown[f"value {v.name}={value}"] = words.value(v.name, value)
            shown[f"not {v.name}={value}"] = words.not_value(v.name, value)
    shown |= {f"spec {s.name}": words.specification(s.name) for s in model.specifications}
    shown |= {f"operation {o.name}": words.operation(o.name) for o in station.operations}
    shown |= {f"intention {i.name}": words.intention(i.name) for i in station.intentions}
    shown |= {f"ability {a.qualified}": words.ability(a.qualified) for a in station.abilities}
    shown |= {f"transition {t.name}": words.step(t.name) for t in model.transitions}
    return shown


def test_the_demo_names_everything_in_words(demo: Station) -> None:
    words = Wording(demo)
    shown = _everything(demo, words)
    assert len(shown) > 400
    leaks = {k: w for k, w in shown.items() if identifiers_in(w, demo) or PAPER.search(w)}
    assert leaks == {}
    assert all(w and len(w) <= 100 for w in shown.values())


def test_the_demo_gives_every_item_its_own_display(demo: Station) -> None:
    """Not a fallback anywhere: each item has words of its own, and people can tell apart
    the variables, steps, operations and specifications by their words."""
    model = demo.model
    assert demo.display
    missing = [r.name for r in demo.resources if not r.display]
    missing += [v.name for v in model.variables if not v.display]
    missing += [
        f"{v.name}={x}"
        for v in model.variables
        for x in v.domain
        if x not in dict(v.display_values)
    ]
    missing += [s.name for s in model.specifications if not s.display]
    missing += [o.name for o in demo.operations if not o.display]
    missing += [i.name for i in demo.intentions if not i.display]
    missing += [a.qualified for a in demo.abilities if not a.display]
    starts = {a.qualified for a in demo.abilities}
    missing += [t.name for t in model.transitions if not t.display and t.name not in starts]
    assert missing == []
    words = Wording(demo)
    for kind, items in (
        ("variable", [words.variable(v.name) for v in model.variables]),
        ("step", [words.step(t.name) for t in model.transitions]),
        ("operation", [words.operation(o.name) for o in demo.operations]),
        ("specification", [words.specification(s.name) for s in model.specifications]),
    ):
        assert len(set(items)) == len(items), kind


def test_the_demo_reads_well(demo: Station) -> None:
    words = Wording(demo)
    assert words.value("bp3.state", "placed") == "bolt pair 3 is placed on the frame"
    assert words.specification("oil_filters_after_bolts") == (
        "oil filters only after every bolt pair is tightened"
    )
    assert words.transition("operator.remove_oil_filters") == (
        "take off the oil filters mounted too early"
    )
    assert words.operation("get_nr_r2") == "robot 2 takes the nutrunner"
    assert words.step("r1.goto_bp3") == "robot 1: move down onto bolt pair 3"
    assert words.transition("operator.place_bolts_bp2") == "place bolt pair 2 on the ladder frame"
    assert sentence(words.transition("operator.move_r2_home")) == "Move robot 2 home by hand"
    assert words.station() == "engine assembly"


# ---- the runner's causes, as pages put them in words ---------------------------------------------


def test_a_cause_names_what_blocks_it_and_reads_in_words() -> None:
    """An operation in error says what keeps its goal out of reach (E6: a camera cannot find
    the tools because r2 stopped answering), in model names that pages put in words."""
    from planner.runner import OperationState
    from planner.runner.tick import Tick
    from planner.runner.transitions import fail_operations
    from tests.planner.runner.test_runner_safety import PRESS, runner_for

    worded = PRESS.replace("  - name: press\n", '  - name: press\n    display: "the machine"\n')
    runner = runner_for(worded)
    state = runner.initial(0.0)
    state.operations["press_part"] = OperationState.EXECUTING
    state.unavailable.add("press")
    state.timed_out.add("curtain.hand_enters")
    fail_operations(Tick(runner, state, 1.0), ["press_part"])
    cause = state.operation_causes["press_part"]
    assert cause == (
        "its goal cannot be reached while press does not answer and curtain.hand_enters is "
        "disabled after a time-out"
    )
    assert Wording(runner.station).text(cause) == (
        "its goal cannot be reached while the machine does not answer and curtain hand enters "
        "is disabled after a time-out"
    )
    # nothing blocking: the goal alone
    state = runner.initial(0.0)
    state.operations["press_part"] = OperationState.EXECUTING
    fail_operations(Tick(runner, state, 1.0), ["press_part"])
    assert state.operation_causes["press_part"] == "its goal cannot be reached"


# ---- safety notes of maintenance steps ---------------------------------------------------------

PUSH = 'description: "push robot 1 home by hand (E6, E7)"}'


def test_a_maintenance_step_carries_its_safety_note_in_words() -> None:
    note = 'safety: "press robot 1\'s emergency stop first (E6)"'
    station = load_station(MODEL.replace(PUSH, PUSH[:-1] + ", " + note + "}"), "mini.yaml")
    words = Wording(station)
    assert words.safety("r1.push_home") == "press robot 1's emergency stop first"
    assert words.safety("r1.goto.arrive") == ""


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ("3", "must be words, not a number (3); put it in quotes"),
        ("[a, b]", "must be words, not a list or mapping"),
        ('"' + "x" * 201 + '"', "is 201 characters; at most 200 fit a watch card"),
    ],
)
def test_a_bad_safety_note_is_located_at_its_value(bad: str, message: str) -> None:
    new = PUSH[:-1] + ", safety: " + bad + "}"
    found = problems(PUSH, new)
    fragment = bad
    assert found == [
        f"{at(PUSH, new, fragment)}: the safety note of transition 'push_home' {message}"
    ]


def test_a_safety_note_is_for_maintenance_steps_only() -> None:
    old = 'display: "arrive"}'
    (found,) = problems(old, 'display: "arrive", safety: "stand back"}')
    location, message = found.split(": ", 1)
    assert location == at(old, 'display: "arrive", safety: "stand back"}', "safety")
    assert message.startswith("safety of transition 'r1.goto.arrive'")
    assert "only a maintenance transition" in message


def test_the_product_intention_is_marked_true_or_false_and_a_bad_mark_located() -> None:
    old = 'display: "assemble it"'
    station = load_station(MODEL.replace(old, old + ", product: true"), "mini.yaml")
    assert [i.name for i in station.intentions if i.product] == ["assemble"]
    assert not any(i.product for i in load_station(MODEL, "mini.yaml").intentions)
    new = old + ", product: 3"
    assert problems(old, new) == [
        f"{at(old, new, '3')}: the product of intention 'assemble' is true or false, not '3'"
    ]


def test_words_that_misled_people_read_plainly() -> None:
    """Issue 29: the Table 1 labels in plain words (the label stays a technical detail),
    and a device named by an acronym keeps it upper case."""
    from planner.words import recovery_words

    assert recovery_words("TP w/RTO") == (
        "the machines' steps planned again without the machine that stopped answering"
    )
    assert (
        recovery_words("OP w/DO") == "the order of the work planned again without the work in error"
    )
    assert (
        recovery_words("TP w/MT")
        == "the machines' steps planned again with a person's maintenance steps"
    )
    assert recovery_words("TP w/ETO w/MT").count(" and ") == 1
    assert recovery_words("XY w/Q") == "XY w/Q"  # unknown: as it is
    words = Wording(load_station(MODEL, "mini.yaml"))
    assert sentence(words.resource("plc")) == "PLC"
    assert words.resource("r1") == "robot 1"
