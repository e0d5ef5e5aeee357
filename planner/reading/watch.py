"""A person's `watch:` read from YAML and checked against the person's variables and effects
(`planner.model.watch.Watch`)."""

from __future__ import annotations

from collections.abc import Mapping

import yaml

from planner.model.flat import Transition, TransitionKind, Variable, VariableKind
from planner.model.watch import IDLE, Watch
from planner.reading.yaml_reader import Reader

WATCH_KEYS = ("card", "done", "confirm")


def read_watch(
    reader: Reader,
    node: yaml.Node,
    resource: str,
    variables: Mapping[str, Variable],
    transitions: Mapping[str, Transition],
) -> Watch | None:
    """The `watch:` of resource `resource`, checked; None (and errors) when it is wrong."""
    fields = reader.mapping(node, "a watch", WATCH_KEYS, required=WATCH_KEYS)
    if fields is None or any(key not in fields for key in WATCH_KEYS):
        return None
    names = {}
    for key in WATCH_KEYS:
        local = reader.name(fields[key][1], f"the watch's {key}")
        if local is None:
            return None
        names[key] = f"{resource}.{local}"
    card, done = variables.get(names["card"]), variables.get(names["done"])
    confirm = transitions.get(names["confirm"])
    problems = [
        (key, problem)
        for key, problem in (
            ("card", _card_problem(card)),
            ("done", _done_problem(card, done)),
            ("confirm", _confirm_problem(confirm)),
        )
        if problem
    ]
    for key, problem in problems:
        reader.error(fields[key][1], f"the watch of '{resource}': {problem}")
    if problems:
        return None
    return Watch(names["card"], names["done"], names["confirm"])


def _card_problem(card: Variable | None) -> str:
    if card is None:
        return "'card' names none of the resource's variables"
    if card.kind is not VariableKind.COMMAND:
        return f"its card '{card.name}' must be a command variable (the station shows it)"
    if IDLE not in card.domain:
        return f"its card '{card.name}' needs the value '{IDLE}' (no card shown)"
    return ""


def _done_problem(card: Variable | None, done: Variable | None) -> str:
    if done is None:
        return "'done' names none of the resource's variables"
    if done.kind is not VariableKind.MEASURED:
        return f"its done '{done.name}' must be a measured variable (the watch reports it)"
    if card is not None and set(done.domain) != set(card.domain):
        return f"its done '{done.name}' must have the same values as its card '{card.name}'"
    return ""


def _confirm_problem(confirm: Transition | None) -> str:
    if confirm is None:
        return "'confirm' names none of the resource's own transitions"
    if confirm.kind is not TransitionKind.EFFECT:
        return f"its confirm '{confirm.name}' must be an effect (the person's tap)"
    return ""
