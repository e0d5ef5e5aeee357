"""A template's parameter: `parameter: {name, values, display_values}` of an ability or an
operation, which is made once per value with `{name}` filled in (docs/models.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from planner.reading.display import read_value_words
from planner.reading.yaml_reader import Fields, Reader

PARAMETER_KEYS = ("name", "values", "display_values")


@dataclass(frozen=True)
class Parameter:
    """`parameter: {name, values, display_values}` of an ability or operation."""

    name: str
    values: list[str]
    words: dict[str, str]  # value → words for people (display_values), where given


def read_parameter(reader: Reader, fields: Fields, what: str) -> Parameter | None:
    """The parameter of `what`; None when absent or broken (errors recorded)."""
    if "parameter" not in fields:
        return None
    node = fields["parameter"][1]
    parameter = reader.mapping(node, f"the parameter of {what}", PARAMETER_KEYS, ("name", "values"))
    if parameter is None or "name" not in parameter or "values" not in parameter:
        return None
    name = reader.name(parameter["name"][1], "parameter name")
    values = [
        reader.scalar(v, "parameter value")
        for v in reader.sequence(parameter["values"][1], "values")
    ]
    if name is None or not values or any(v is None for v in values):
        if not values:
            reader.error(parameter["values"][1], "a parameter needs at least one value")
        return None
    given = [v for v in values if v is not None]
    words: dict[str, str] = {}
    if "display_values" in parameter:
        about = f"the parameter '{name}' of {what}"
        pairs = read_value_words(reader, parameter["display_values"][1], about, tuple(given))
        words = {str(value): text for value, text in pairs}
    return Parameter(name, given, words)


def filled(description: str, values: Mapping[str, str]) -> str:
    """A template's description for one parameter value: `{bp}` becomes `bp3`."""
    for key, value in values.items():
        description = description.replace("{" + key + "}", value)
    return description
