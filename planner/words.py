"""Words for people: what a page calls each name of the model, and plain sentences.

People read display names, never model identifiers (`bp3.state`, `nr`) or references to the
papers ("(seed 000 Figure 6)").  `Wording` answers, for every name a page may show, the words
written in the model (docs/models.md, "Words for people"), computed once per station so that
pages can ask on every render.  When the model gives no `display`, the fallback is:

1. the item's `description`, without its references (`clean`);
2. else the name humanised: `_` and `.` become spaces (`r1_tc.lock` → "r1 tc lock").

An ability's `start` transition falls back on its ability's display before that; the station
on its name (its description is a paragraph).  Words come back as written, not capitalised, to
be used inside a sentence; `sentence` makes a title of them.  Unknown names are humanised,
never an error: a page must render whatever the runner reports.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping

from planner.model.expressions import (
    And,
    BoolVar,
    Const,
    Equals,
    Expr,
    Implies,
    Not,
    Or,
    SameValue,
    Value,
)
from planner.model.flat import TransitionKind, Variable
from planner.model.station import Station
from planner.reading.display import humanised
from planner.runner.vocabulary import PlanLevel, RecoveryFlag, ReplanReason

_GROUP = re.compile(r"\s*\(([^()]*)\)")
_REFERENCE = re.compile(
    r"""
    seed\s+\d+\b.*                                    # seed 003 PlaceBolt_i, seed 000 6.4
    | (?:experiments?\s+)?E\d+(?:\s*(?:[-\u2013/]|and|or)\s*E?\d+)*    # E6, E5-E7, E1/E2
    | (?:Fig(?:ure|\.)|Tables?|Definitions?|[Ss]ections?|[Ss]ec\.)\s+[\dIVXLC].*  # Table VI
    | DESIGN\.md\b.*
    | (?:operation|intention|resource|transition|specification|variable|ability)
      \s+[A-Za-z_][\w.]*                              # (operation get_nr_r2)
    """,
    re.VERBOSE,
)


def _without_references(group: re.Match[str]) -> str:
    """A parenthesis without its references: dropped whole when it starts with one ("(seed
    003 GetNRTool, GetLFTool)"), else cut where the references start ("(by hand, E1/E2)")."""
    items = [item.strip() for item in re.split(r"[,;]", group.group(1))]
    first = next((k for k, item in enumerate(items) if _REFERENCE.fullmatch(item)), None)
    if first is None:
        return group.group(0)
    if first == 0:
        return ""
    space = group.group(0)[: len(group.group(0)) - len(group.group(0).lstrip())]
    return f"{space}({', '.join(items[:first])})"


def clean(text: str) -> str:
    """Text without the model's references to papers, experiments and its own names in
    parentheses ("(seed 003 PlaceBolt_i)", "(E6, E7)", "(operation get_nr_r2)"), its spaces
    tidied; not capitalised."""
    text = _GROUP.sub(_without_references, text)
    text = " ".join(text.split())
    return re.sub(r"\s+([,.;:!?])", r"\1", text).strip()


def sentence(text: str) -> str:
    """Plain words for a person: `clean`, and capitalised."""
    text = clean(text)
    return text[:1].upper() + text[1:]


_NAME = re.compile(r"(?<![\w.])[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*(?!\w)")
_BOOL_WORDS = {True: "yes", False: "no"}
_ACRONYM = re.compile(r"[b-df-hj-np-tv-xzB-DF-HJ-NP-TV-XZ]{2,5}")  # no vowel: read letter by letter


def _first(*texts: str) -> str:
    return next((clean(t) for t in texts if t and clean(t)), "")


class Wording:
    """The words for people of one station's names, computed once (see the module docstring).

    Methods take model names and return words: `resource("nr")` → "the nutrunner",
    `value("bp3.state", "placed")` → "bolt pair 3 is placed on the frame".
    """

    def __init__(self, station: Station) -> None:
        model = station.model
        self._owner_of = station.owner_of
        self._station = _first(station.display) or humanised(station.name)
        self._resources = {r.name: _first(r.display, r.description) for r in station.resources}
        self._variables: dict[str, Variable] = {v.name: v for v in model.variables}
        self._variable_words = {v.name: _first(v.display, v.description) for v in model.variables}
        self._value_words = {
            (v.name, value): clean(words)
            for v in model.variables
            for value, words in v.display_values
        }
        self._specifications = {
            s.name: _first(s.display, s.description) for s in model.specifications
        }
        self._operations = {o.name: _first(o.display, o.description) for o in station.operations}
        self._intentions = {i.name: _first(i.display, i.description) for i in station.intentions}
        self._abilities = {a.qualified: _first(a.display, a.description) for a in station.abilities}
        self._safety = {t.name: clean(t.safety) for t in model.transitions if t.safety}
        self._maintenance = frozenset(
            t.name for t in model.transitions if t.kind is TransitionKind.MAINTENANCE
        )
        starts = {a.qualified: a for a in station.abilities}
        self._transitions: dict[str, str] = {}
        for t in model.transitions:
            ability = starts.get(t.name)
            self._transitions[t.name] = (
                _first(t.display, ability.display, t.description, ability.description)
                if ability
                else _first(t.display, t.description)
            )
        # any name, for `name` and `text`: the first kind listed wins
        self._any: dict[str, str] = {}
        for kind in (
            self._transitions,
            self._operations,
            self._intentions,
            self._specifications,
            self._variable_words,
            self._abilities,
            self._resources,
        ):
            for name in kind:
                self._any.setdefault(name, self._lookup(kind, name))

    @staticmethod
    def _lookup(words: dict[str, str], name: str) -> str:
        return words.get(name) or humanised(name)

    sentence = staticmethod(sentence)

    def station(self) -> str:
        """The station's name for people: its display, else its name humanised."""
        return self._station

    def resource(self, name: str) -> str:
        """A resource's words; a device that is no resource (the PLC) by its name, an
        acronym kept upper case ("plc" is "PLC", never "Plc")."""
        if name not in self._resources and _ACRONYM.fullmatch(name):
            return name.upper()
        return self._lookup(self._resources, name)

    def variable(self, name: str) -> str:
        return self._lookup(self._variable_words, name)

    def value_name(self, variable: str, value: Value | str) -> str:
        """One value's words alone (a table cell beside `variable`): its `display_values`,
        else "yes"/"no" for a boolean, else the value humanised."""
        value = self._value(variable, value)
        words = self._value_words.get((variable, value))
        if words:
            return words
        if isinstance(value, bool):
            return _BOOL_WORDS[value]
        return humanised(str(value))

    def value(self, variable: str, value: Value | str) -> str:
        """`variable == value` as a statement: "bolt pair 3 is placed on the frame" when the
        model words the value (written to follow "is"), else "bolt pair 3: placed"."""
        value = self._value(variable, value)
        if (variable, value) in self._value_words:
            return f"{self.variable(variable)} is {self._value_words[(variable, value)]}"
        return f"{self.variable(variable)}: {self.value_name(variable, value)}"

    def not_value(self, variable: str, value: Value | str) -> str:
        """`variable != value` as a statement; for a boolean, the other value."""
        value = self._value(variable, value)
        if isinstance(value, bool):
            return self.value(variable, not value)
        if (variable, value) in self._value_words:
            return f"{self.variable(variable)} is not {self._value_words[(variable, value)]}"
        return f"{self.variable(variable)}: not {self.value_name(variable, value)}"

    def _value(self, variable: str, value: Value | str) -> Value:
        """A form's "true"/"false" read as the boolean it names."""
        known = self._variables.get(variable)
        text = value.lower() if isinstance(value, str) else ""
        if known is not None and known.is_bool and text in ("true", "false"):
            return text == "true"
        return value

    def specification(self, name: str) -> str:
        """What the specification protects ("oil filters only after every bolt pair is
        tightened")."""
        return self._lookup(self._specifications, name)

    def operation(self, name: str) -> str:
        return self._lookup(self._operations, name)

    def intention(self, name: str) -> str:
        return self._lookup(self._intentions, name)

    def ability(self, qualified: str) -> str:
        """An ability instance by its qualified name (`r1.goto_bp3`)."""
        return self._lookup(self._abilities, qualified)

    def transition(self, name: str) -> str:
        """What the step does ("move down onto bolt pair 3"), without who does it."""
        words = self._transitions.get(name)
        if words:
            return words
        owner = self._owner_of(name)
        return humanised(name[len(owner) + 1 :] if owner else name)

    def is_maintenance(self, name: str) -> bool:
        """Whether transition `name` is a person's maintenance step."""
        return name in self._maintenance

    def safety(self, name: str) -> str:
        """A maintenance step's safety note as the model writes it ("" when it has none)."""
        return self._safety.get(name, "")

    def owner(self, name: str) -> str:
        """The words of the resource a transition or variable belongs to; "" if station-wide."""
        owner = self._owner_of(name)
        return self.resource(owner) if owner else ""

    def step(self, name: str) -> str:
        """A transition with who does it: "robot 1: move down onto bolt pair 3"."""
        owner = self.owner(name)
        return f"{owner}: {self.transition(name)}" if owner else self.transition(name)

    def name(self, name: str) -> str:
        """The words of any model name (transitions first, then operations, intentions,
        specifications, variables, abilities and resources); else the name humanised."""
        return self._any.get(name) or humanised(name)

    def names(self, names: Iterable[str]) -> str:
        """Several names, each in words, joined with commas ("a, b and c")."""
        words = [self.name(n) for n in names]
        return ", ".join(words[:-1]) + " and " + words[-1] if len(words) > 1 else "".join(words)

    def text(self, text: str) -> str:
        """Free text (a runner's reason) with every model name in it replaced by its words and
        references removed.  A name that its own words contain as a word ("operator" → "the
        operator") is left as it is."""

        def words(match: re.Match[str]) -> str:
            name = match.group(0)
            if name not in self._any:
                return name
            replacement = self._any[name]
            if re.search(rf"(?<![\w.]){re.escape(name)}(?![\w])", replacement):
                return name
            return replacement

        return _NAME.sub(words, clean(text))  # references first: they hold names

    def condition(self, expr: Expr) -> str:
        """An expression in words: "bolt pair 1 is tightened and the ladder frame is on the
        engine" (for why a precondition does not hold)."""
        return self._condition(expr, False)

    def _condition(self, expr: Expr, nested: bool) -> str:
        match expr:
            case Const(value):
                return "always" if value else "never"
            case BoolVar(name):
                return self.value(name, True)
            case Equals(name, value):
                return self.value(name, value)
            case SameValue(left, right):
                return f"{self.variable(left)} is the same as {self.variable(right)}"
            case Not(BoolVar(name)):
                return self.value(name, False)
            case Not(Equals(name, value)):
                return self.not_value(name, value)
            case Not(SameValue(left, right)):
                return f"{self.variable(left)} is not the same as {self.variable(right)}"
            case Not(arg):
                return f"not ({self._condition(arg, False)})"
            case And(args) | Or(args):
                joiner = " and " if isinstance(expr, And) else " or "
                text = joiner.join(self._condition(a, True) for a in args)
            case Implies(left, right):
                text = f"if {self._condition(left, True)}, then {self._condition(right, True)}"
            case _:
                raise TypeError(expr)
        return f"({text})" if nested else text  # "a or (b and c)": no precedence to know


REASON_WORDS: Mapping[ReplanReason, str] = {
    ReplanReason.GOALS: "planned for the operations running now",
    ReplanReason.INTENTIONS: "planned for the intentions",
    ReplanReason.DEVIATION: "planned again after a deviation",
    ReplanReason.TIMEOUT: "planned again after a time-out",
    ReplanReason.AVAILABILITY: "planned again: a resource stopped answering or answers again",
    ReplanReason.ERROR: "planned around operations in error",
    ReplanReason.MAINTENANCE: "maintenance planned",
    ReplanReason.FORBIDDEN_STATE: "recovery from a forbidden state planned",
    ReplanReason.RESET: "planned to reset an operation",
    ReplanReason.RESTART: "planned again for restart mode",
    ReplanReason.ESTIMATED: "planned again after an estimate was set",
    ReplanReason.RECOVERED: "planned again after recovery",
    ReplanReason.CLEARED: "planned again: an operation left its error",
    ReplanReason.REENABLED: "planned again: an effect was re-enabled",
}
"""Why the runner planned again (`ReplanReason`), in words for people."""


def replan_words(reason: str) -> str:
    """A planning event's `reason` in words ("planned again" for one this code does not know)."""
    try:
        return REASON_WORDS[ReplanReason(reason)]
    except ValueError:
        return "planned again"


_LEVEL_WORDS: Mapping[PlanLevel, str] = {
    PlanLevel.OPERATIONS: "the order of the work planned again",
    PlanLevel.TRANSITIONS: "the machines' steps planned again",
}
_FLAG_WORDS: Mapping[RecoveryFlag, str] = {
    RecoveryFlag.EFFECT_TIMED_OUT: "without what did not happen in time",
    RecoveryFlag.RESOURCE_TIMED_OUT: "without the machine that stopped answering",
    RecoveryFlag.MAINTENANCE: "with a person's maintenance steps",
    RecoveryFlag.DISABLED_OPERATIONS: "without the work in error",
}


def recovery_words(label: str) -> str:
    """A planning action's Table 1 label ("TP w/RTO", "OP w/DO", "TP w/MT") in plain words
    ("the machines' steps planned again without the machine that stopped answering"); the
    label itself is a technical detail for engineers, shown beside it.  A label this code
    cannot read comes back as it is."""
    level, *flags = label.replace(" w/", " ").split() or [""]
    try:
        said = [_LEVEL_WORDS[PlanLevel(level)]]
        said += [_FLAG_WORDS[RecoveryFlag(flag)] for flag in flags]
    except ValueError:
        return label
    return " ".join(said[:1]) + ("" if len(said) == 1 else " " + " and ".join(said[1:]))
