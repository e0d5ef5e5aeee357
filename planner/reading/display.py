"""Reading a model's words for people: `display` and `display_values` (docs/models.md).

A `display` is what a person reads instead of a model name ("bolt pair 3" for `bp3.state`);
`display_values` gives words for the values of a variable or of a parameter.  They are words
only: no planner reads them.  Bad ones are reported like every other model problem, at their
line and column, so that a page never shows an empty, overlong or half-filled name.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING

import yaml

from planner.model.expressions import Value

if TYPE_CHECKING:
    from planner.reading.yaml_reader import Reader

MAX_DISPLAY_CHARS = 80
"""The longest words accepted: two lines of a 320 px watch card."""

PLACEHOLDER = re.compile(r"\{([^{}]*)\}")
_STRING = "tag:yaml.org,2002:str"
_NOT_WORDS = {
    "tag:yaml.org,2002:int": "a number",
    "tag:yaml.org,2002:float": "a number",
    "tag:yaml.org,2002:bool": "a yes/no value",
}


def read_words(
    reader: Reader,
    node: yaml.Node,
    what: str,
    parameters: Collection[str] = (),
    limit: int = MAX_DISPLAY_CHARS,
) -> str | None:
    """The words of one `display` (or of one value), checked; None (an error recorded) if bad.

    `parameters` are the placeholders the words may name (`{bp}`); they are filled later,
    per instance, by `fill`.
    """
    if not isinstance(node, yaml.ScalarNode):
        reader.error(node, f"{what} must be words, not a list or mapping")
        return None
    text = str(node.value)
    if node.tag.endswith(":null") or not text.strip():
        reader.error(node, f"{what} is empty; write the words a person reads, or leave it out")
        return None
    if node.tag != _STRING:
        kind = _NOT_WORDS.get(node.tag, "not words")
        reader.error(node, f"{what} must be words, not {kind} ({text}); put it in quotes")
        return None
    if "\n" in text.strip():
        reader.error(node, f"{what} must be one line")
        return None
    text = text.strip()
    if len(text) > limit:
        reader.error(node, _too_long(what, text, limit))
        return None
    ok = True
    for match in PLACEHOLDER.finditer(text):
        name = match.group(1)
        if name not in parameters:
            where = reader.at_offset(node, match.start())
            if parameters:
                known = ", ".join("{" + p + "}" for p in parameters)
                reader.error_at(where, f"{what} names '{{{name}}}'; it may only name {known}")
            else:
                reader.error_at(where, f"{what} names '{{{name}}}', but there is no parameter")
            ok = False
    rest = PLACEHOLDER.sub("", text)
    for brace in "{}":
        if brace in rest:
            offset = _unmatched(text, brace)
            reader.error_at(
                reader.at_offset(node, offset),
                f"{what} has a '{brace}' that opens or closes no placeholder",
            )
            ok = False
            break
    return text if ok else None


def _too_long(what: str, text: str, limit: int = MAX_DISPLAY_CHARS) -> str:
    return f"{what} is {len(text)} characters; at most {limit} fit a watch card"


def _unmatched(text: str, brace: str) -> int:
    """The offset of the first `brace` that is not part of a `{name}` placeholder."""
    inside = [range(m.start(), m.end()) for m in PLACEHOLDER.finditer(text)]
    for offset, char in enumerate(text):
        if char == brace and not any(offset in span for span in inside):
            return offset
    return 0


def read_value_words(
    reader: Reader, node: yaml.Node, what: str, domain: tuple[Value, ...]
) -> tuple[tuple[Value, str], ...]:
    """`display_values: {value: words, ...}` over `domain` (a variable's or a parameter's);
    booleans are written `true` and `false`.  Values left out keep their own name."""
    if not isinstance(node, yaml.MappingNode):
        reader.error(node, f"the display_values of {what} must be a mapping (value: words)")
        return ()
    is_bool = domain == (False, True)
    result: dict[Value, str] = {}
    for key_node, value_node in node.value:
        text = str(key_node.value)
        value: Value = text.lower() == "true" if is_bool else text
        if (is_bool and text.lower() not in ("true", "false")) or (
            not is_bool and text not in domain
        ):
            values = "true, false" if is_bool else ", ".join(str(v) for v in domain)
            hints = difflib.get_close_matches(text, [str(v) for v in domain], n=1, cutoff=0.6)
            hint = f" (did you mean '{hints[0]}'?)" if hints else ""
            reader.error(key_node, f"'{text}' is not a value of {what}{hint}; its values: {values}")
            continue
        if value in result:
            reader.error(key_node, f"'{text}' is given words twice in the display_values of {what}")
            continue
        words = read_words(reader, value_node, f"the words for '{text}' of {what}")
        if words is not None:
            result[value] = words
    return tuple(result.items())


def fill(text: str, words: Mapping[str, str]) -> str:
    """`{param}` placeholders replaced by the words of this instance's value."""
    return PLACEHOLDER.sub(lambda m: words.get(m.group(1), m.group(0)), text)


def fill_checked(
    reader: Reader, node: yaml.Node | None, what: str, text: str, words: Mapping[str, str]
) -> str:
    """`fill`, and an error at `node` if the filled words grow too long for a card."""
    filled = fill(text, words)
    if node is not None and len(filled) > MAX_DISPLAY_CHARS:
        reader.error(node, f"{_too_long(what, filled)} once filled in: '{filled}'")
    return filled


def parameter_words(words: Mapping[str, str], values: Mapping[str, str]) -> dict[str, str]:
    """The words that fill each placeholder for one instance: the parameter value's
    `display_values`, else the value humanised."""
    return {key: words.get(value, humanised(value)) for key, value in values.items()}


def humanised(name: str) -> str:
    """A name as words when the model gives none: `r1_tc.lock` → `r1 tc lock`."""
    return " ".join(name.replace("_", " ").replace(".", " ").split())
