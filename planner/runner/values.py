"""Small helpers over live values."""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from planner.expressions import Assign, Value


def assigned(actions: Iterable[Assign], values: Mapping[str, Value]) -> dict[str, Value]:
    """The values `actions` assign, every one reading `values` (the state before them)."""
    out: dict[str, Value] = {}
    for action in actions:
        value = values[action.source] if action.source is not None else action.value
        assert value is not None
        out[action.target] = value
    return out
