"""The pieces every part of a scenario is read with: where in the file a problem is (a path
of keys and indexes, located by `app.station.scenario`), numbers, mappings and lists checked,
`at`/`when`/`after` of a fault or an action, and unknown keys refused."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from planner.model.expression_text import parse_expr
from planner.model.expressions import Expr

Path = tuple[str | int, ...]


class Problem(Exception):
    """A problem at a place in the scenario (a path of keys and indexes)."""

    def __init__(self, path: Path, text: str) -> None:
        super().__init__(text)
        self.path = path
        self.text = text


def number(value: Any, path: Path, *, integer: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise Problem(path, f"{value!r} is not a number")
    if integer and not isinstance(value, int):
        raise Problem(path, f"{value!r} is not a whole number")
    if value < 0:
        raise Problem(path, f"{value!r} is negative")
    return value


def mapping(value: Any, path: Path, what: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise Problem(path, f"{what} must be a mapping")
    return value


def sequence(value: Any, path: Path, what: str) -> list[Any]:
    if value is None:
        return []
    if not isinstance(value, list):
        raise Problem(path, f"{what} must be a list")
    return value


def after_of(entry: dict[str, Any], where: Path, when: Expr | None) -> float:
    """`after`: seconds from the moment a `when` condition first holds."""
    after = number(entry.get("after", 0.0), (*where, "after"))
    if after and when is None:
        raise Problem((*where, "after"), "'after' counts from a 'when' condition: give one")
    return after


def when_of(entry: dict[str, Any], where: Path, scope: Any) -> Expr | None:
    when = None
    if "when" in entry:
        try:
            when = parse_expr(str(entry["when"]), scope)
        except Exception as exc:  # the expression parser's own located message
            raise Problem((*where, "when"), str(exc)) from None
    if "at" not in entry and when is None:
        raise Problem(where, "give 'at' (seconds) or 'when' (a condition)")
    return when


def known(where: Path, what: str, data: Mapping[str, Any], keys: tuple[str, ...]) -> None:
    if not isinstance(data, dict):
        raise Problem(where, f"{what} must be a mapping")
    for key in data:
        if key not in keys:
            raise Problem((*where, key), f"unknown {what} key '{key}'; use {', '.join(keys)}")
