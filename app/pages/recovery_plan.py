"""A forbidden-state recovery plan in work terms: what each machine step acts on, and the
whole plan in one line ("Bolt pairs 2-4 tightened: 6 machine steps").

The plan alone says "the nutrunner: start tightening" six times; which bolt pair each run
tightens depends on where the robot holding the nutrunner is by then.  So the rest of the
plan is simulated from the current state with the planner's semantics (each block's step,
then its effects and automatic steps, as far as their guards hold), and each step is named
by what it changes in the product (its decision variables: "bolt pair 2 tightened"), else by
where its resource is ("the nutrunner on robot 1").  Pure: reads a `StationView`.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

from app.station.view import StationView
from planner.model.expressions import Value
from planner.model.flat import VariableKind
from planner.model.kept_out import kept_out
from planner.model.semantics import State
from planner.runner import TransitionPlan
from planner.runner.forbidden import numbered
from planner.words import Wording, sentence

_NUMBERED = re.compile(r"^(.*\S)\s+(\d+)$")  # "bolt pair 2": a kind and its number


@dataclass(frozen=True)
class PlanStep:
    """One machine step of the plan, in words."""

    step: int  # the plan's block
    number: int  # as people see it numbered: among the plan's machine steps, from 1
    transition: str
    words: str  # "Robot 1: move down onto bolt pair 2"
    result: str  # "bolt pair 2 is tightened", or where its resource is; "" if neither is known
    changes: tuple[tuple[str, str], ...]  # the decisions it makes: (variable, value)

    @property
    def line(self) -> str:
        return f"{self.words} \u2014 {self.result}" if self.result else self.words


def plan_steps(view: StationView, plan: TransitionPlan, steps: list[int]) -> list[PlanStep]:
    """`steps` of `plan` in words, the rest of the plan simulated from the current state in
    plan order.  A decision an effect or automatic step makes (a bolt pair tightened) is the
    work of its resource's step taken last (the nutrunner's run), or, for a station-wide
    one, of the step taken last."""
    index = view.runner.index
    model = index.model
    owner_of = view.model.station.owner_of
    decisions = [v.name for v in model.variables if v.kind is VariableKind.DECISION]
    state = index.as_state(view.state.values)
    before: dict[int, State] = {}
    made: dict[int, dict[str, str]] = {}
    last: dict[str, int] = {}
    latest = -1
    for k, block in enumerate(plan.blocks):
        if k in plan.taken:
            continue
        before[k] = state
        for name in block.steps:
            transition = index.transition(name)
            if not transition.guard(state):
                continue
            after = transition.apply(state)
            if name == block.transition:
                last[owner_of(name)], latest = k, k
            by = last.get(owner_of(name), latest) if owner_of(name) else latest
            for v in decisions:
                at = model.variable_index[v]
                if after[at] != state[at] and by >= 0:
                    made.setdefault(by, {})[v] = str(after[at])
            state = after
    words = view.model.words
    out = []
    for k in steps:
        name = plan.blocks[k].transition
        changes = tuple(made.get(k, {}).items())
        said = "; ".join(words.value(v, x) for v, x in changes)
        written = plan.blocks[k].writes
        result = said or _where(view, name, before.get(k, state), written)
        number = numbered(index, plan, k)[0]
        out.append(PlanStep(k, number, name, sentence(words.step(name)), result, changes))
    return out


def _where(view: StationView, transition: str, state: State, written: frozenset[str]) -> str:
    """Where the step's resource is ("the nutrunner on robot 1"), unless the step moves it
    (a robot's move names where it goes); else ""."""
    owner = view.model.station.owner_of(transition)
    model = view.runner.index.model
    place = resource_place(view, owner, lambda v: state[model.variable_index[v]])
    if not owner or not place or _place_variable(view, owner) in written:
        return ""
    return f"{view.model.words.resource(owner)} {place}"


def resource_place(view: StationView, owner: str, value_of: Callable[[str], Value]) -> str:
    """Where a resource is, in words ("above the engine"): the value of its own variable,
    the one the model words as the resource itself (robot 2's position is "robot 2");
    "" when it has none."""
    variable = _place_variable(view, owner)
    return view.model.words.value_name(variable, value_of(variable)) if variable else ""


def _place_variable(view: StationView, owner: str) -> str:
    """The resource's own variable: the one the model words as the resource itself."""
    if not owner:
        return ""
    words = view.model.words
    for variable in view.runner.index.model.variables:
        mine = variable.name.startswith(owner + ".") and not variable.is_bool
        if mine and words.variable(variable.name) == words.resource(owner):
            return variable.name
    return ""


def kept_out_words(view: StationView, owner: str, value_of: Callable[[str], Value]) -> str:
    """What a resource stopped where it was last seen keeps the others out of, in words:
    "robot 1 cannot go there" when its own place is among the places forbidden to them
    (`planner.model.kept_out`), else the places ("robot 1 cannot be where the nutrunner
    hangs"); "" when the specifications forbid the others nothing because of it."""
    station = view.model.station
    stopped = next((r for r in station.resources if r.name == owner), None)
    if stopped is None:
        return ""
    words = view.model.words
    fixed = {name: value_of(name) for name in stopped.variables}
    places = {r.name: _place_variable(view, r.name) for r in station.resources if r is not stopped}
    forbidden = kept_out(station.model, fixed, [v for v in places.values() if v])
    here = fixed.get(_place_variable(view, owner))
    there, elsewhere = [], {}
    for other, variable in places.items():
        values = forbidden.get(variable, ())
        if here in values:
            there.append(words.resource(other))
        elif values:
            names = [words.value_name(variable, v) for v in values]
            elsewhere[words.resource(other)] = " or ".join(names)
    said = [f"{' and '.join(there)} cannot go there"] if there else []
    said += [f"{who} cannot be {where}" for who, where in elsewhere.items()]
    return "; ".join(said)


def headline(words: Wording, steps: list[PlanStep]) -> str:
    """The plan in one line: what it makes of the product, grouped ("bolt pairs 2-4
    tightened"), and how many machine steps."""
    count = f"{len(steps)} machine step{'s' if len(steps) != 1 else ''}"
    changes = [change for s in steps for change in s.changes]
    if not changes:
        first = steps[0].words if steps else "Put it right"
        return f"{first}: {count}" if len(steps) == 1 else f"{first} and more: {count}"
    return f"{sentence(grouped(words, changes))}: {count}"


def grouped(words: Wording, changes: list[tuple[str, str]]) -> str:
    """Decisions in words, like ones together: "bolt pairs 2-4 tightened and oil filter 1
    tightened" (numbered names of one kind with the same value are one group)."""
    groups: dict[tuple[str, str], list[int]] = {}
    loose: list[str] = []
    for variable, value in dict(changes).items():
        name, said = words.variable(variable), words.value_name(variable, value)
        numbered = _NUMBERED.match(name)
        if numbered:
            groups.setdefault((numbered.group(1), said), []).append(int(numbered.group(2)))
        else:
            loose.append(words.value(variable, value))
    parts = [f"{_numbers(kind, sorted(set(ns)))} {said}" for (kind, said), ns in groups.items()]
    parts += loose
    return ", ".join(parts[:-1]) + " and " + parts[-1] if len(parts) > 1 else "".join(parts)


def _numbers(kind: str, numbers: list[int]) -> str:
    """ "bolt pair 2", "bolt pairs 2-4", "bolt pairs 1, 3 and 4"."""
    if len(numbers) == 1:
        return f"{kind} {numbers[0]}"
    if numbers == list(range(numbers[0], numbers[-1] + 1)):
        return f"{kind}s {numbers[0]}\u2013{numbers[-1]}"
    listed = [str(n) for n in numbers]
    return f"{kind}s {', '.join(listed[:-1])} and {listed[-1]}"
