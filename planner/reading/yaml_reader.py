"""The YAML reader under every model file: located errors for file, line, column and problem.

The YAML is composed into nodes (not constructed into plain dicts) so that every scalar keeps
its position; expression errors are mapped from their offset inside the scalar back to the
line and column in the file.  All problems found are collected before raising, so an
engineer sees every mistake at once.  Pure: text in, `Model` out.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import yaml

from planner.model.expression_syntax import (
    is_name,
    parse_assign_syntax,
    parse_syntax,
    substitute,
)
from planner.model.expression_text import Scope, resolve, resolve_assign
from planner.model.expressions import Assign, Expr, ExpressionError, Value, size
from planner.model.flat import (
    SourceLocation,
)

try:  # the C loader composes several times faster; fall back where libyaml is missing
    _Loader: type = yaml.CSafeLoader
except AttributeError:  # pragma: no cover
    _Loader = yaml.SafeLoader

T = TypeVar("T")
Fields = dict[str, tuple[yaml.Node, yaml.Node]]  # a mapping's keys -> (key node, value node)

MAX_YAML_NESTING = 100
"""Lists and mappings nested deeper are refused: a model needs about 8 levels, and libyaml's
composer recurses in C, so that `[[[[...` 100,000 deep kills the process (editor included)."""
MAX_ALIAS_NODES = 100_000
"""Nodes that aliases may add to a model beyond those written out in its text: ten anchors
of ten aliases each stand for 10^10 nodes, which reading would walk one by one."""
MAX_MODEL_TERMS = 2_000_000
"""Distinct nodes all of a model's expressions may hold (each alone stands for at most
`MAX_TERMS` written out): what reading keeps in memory.  A predicate named by a thousand
guards is held once.  The demo station has some 1,800; a 1.5 MB station of 560 cells some
70,000."""


@dataclass(frozen=True, slots=True)
class Diagnostic:
    location: SourceLocation
    message: str

    def __str__(self) -> str:
        return f"{self.location}: {self.message}"


class ModelError(Exception):
    """A model that cannot be used; `diagnostics` lists every problem found, in file order."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        unique = dict.fromkeys(diagnostics)  # an ability template reports once, not per value
        self.diagnostics = sorted(unique, key=lambda d: (d.location.line, d.location.column))
        super().__init__("\n".join(str(d) for d in self.diagnostics))


def closest(name: str, candidates: Iterable[str]) -> str | None:
    """The known name most like `name`, for 'did you mean' hints."""
    matches = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return matches[0] if matches else None


class Reader:
    """Walks composed YAML nodes, recording located diagnostics instead of failing early."""

    def __init__(self, text: str, file: str) -> None:
        self.text = text
        self.file = file
        self.diagnostics: list[Diagnostic] = []
        self.terms = 0  # distinct nodes of the expressions read so far (`MAX_MODEL_TERMS`)
        self.sizes: dict[int, tuple[Expr, int]] = {}  # `size`'s memory, shared by them all

    def at(self, node: yaml.Node) -> SourceLocation:
        mark = node.start_mark
        return SourceLocation(self.file, mark.line + 1, mark.column + 1)

    def at_offset(self, node: yaml.Node, offset: int) -> SourceLocation:
        """The file position of character `offset` of a scalar's value."""
        start, end = node.start_mark, node.end_mark
        style = getattr(node, "style", None)
        value = str(node.value)
        if start.line == end.line and style in (None, "'", '"'):
            quote = 0 if style is None else 1
            return SourceLocation(self.file, start.line + 1, start.column + 1 + quote + offset)
        if style == "|":
            lines = value.split("\n")
            line_no, col = 0, offset
            while line_no < len(lines) - 1 and col > len(lines[line_no]):
                col -= len(lines[line_no]) + 1
                line_no += 1
            source_lines = self.text.splitlines()
            first = start.line + 1 + line_no
            if first < len(source_lines):
                indent = len(source_lines[first]) - len(source_lines[first].lstrip())
                return SourceLocation(self.file, first + 1, indent + col + 1)
        # folded or multi-line flow scalars: find the text near the offset in the source
        snippet = value[offset : offset + 12].split("\n")[0].strip()
        region = self.text[start.index : end.index]
        found = region.find(snippet) if snippet else -1
        if found >= 0:
            before = self.text[: start.index + found]
            line = before.count("\n") + 1
            column = len(before) - (before.rfind("\n") + 1) + 1
            return SourceLocation(self.file, line, column)
        return self.at(node)

    def error(self, node: yaml.Node, message: str) -> None:
        self.diagnostics.append(Diagnostic(self.at(node), message))

    def error_at(self, location: SourceLocation, message: str) -> None:
        self.diagnostics.append(Diagnostic(location, message))

    def raise_if_errors(self) -> None:
        if self.diagnostics:
            raise ModelError(self.diagnostics)

    def compose(self) -> yaml.Node | None:
        self.check_nesting()
        try:
            return yaml.compose(self.text, Loader=_Loader)  # type: ignore[no-any-return]
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            line, column = (mark.line + 1, mark.column + 1) if mark else (1, 1)
            problem = exc.problem or "invalid YAML"
            context = f" ({exc.context})" if exc.context else ""
            raise ModelError(
                [Diagnostic(SourceLocation(self.file, line, column), f"YAML: {problem}{context}")]
            ) from None
        except yaml.YAMLError as exc:
            raise ModelError(
                [Diagnostic(SourceLocation(self.file, 1, 1), f"YAML: {exc}")]
            ) from None

    def check_nesting(self) -> None:
        """Refuse nesting beyond `MAX_YAML_NESTING`, and aliases that would make the model
        more than `MAX_ALIAS_NODES` nodes larger than its text (a few hundred bytes of
        anchors naming anchors grow exponentially when read), from the parser's events (a
        flat stream, no recursion), before the composer sees it; other YAML errors are left
        to it."""
        open_: list[list[Any]] = []  # per open collection: its anchor, its nodes so far
        sizes: dict[str, int] = {}  # anchor -> how many nodes it stands for
        extra = 0
        try:
            for event in yaml.parse(self.text, Loader=_Loader):
                if isinstance(event, yaml.CollectionStartEvent):
                    open_.append([event.anchor, 1])
                    if len(open_) > MAX_YAML_NESTING:
                        message = f"lists and mappings nested more than {MAX_YAML_NESTING} deep"
                        self._refuse(event, message)
                    continue
                if isinstance(event, yaml.CollectionEndEvent):
                    anchor, nodes = open_.pop()
                elif isinstance(event, yaml.AliasEvent):
                    anchor, nodes = None, sizes.get(event.anchor or "", 1)
                    extra += nodes - 1
                    if extra > MAX_ALIAS_NODES:
                        self._refuse(event, f"aliases repeat more than {MAX_ALIAS_NODES} nodes")
                elif isinstance(event, yaml.ScalarEvent):
                    anchor, nodes = event.anchor, 1
                else:
                    continue
                if anchor:
                    sizes[anchor] = nodes
                if open_:
                    open_[-1][1] += nodes
        except yaml.YAMLError:
            return

    def _refuse(self, event: yaml.Event, message: str) -> None:
        mark = event.start_mark
        where = SourceLocation(self.file, mark.line + 1, mark.column + 1)
        raise ModelError([Diagnostic(where, f"YAML: {message}")])

    def mapping(
        self, node: yaml.Node, what: str, allowed: Iterable[str], required: Iterable[str] = ()
    ) -> Fields | None:
        """Keys of a mapping node → (key node, value node); unknown or missing keys are errors."""
        if not isinstance(node, yaml.MappingNode):
            self.error(node, f"{what} must be a mapping (key: value)")
            return None
        allowed = list(allowed)
        result: Fields = {}
        for key_node, value_node in node.value:
            key = str(key_node.value)
            if key in result:
                self.error(key_node, f"duplicate key '{key}' in {what}")
                continue
            if key not in allowed:
                hint = closest(key, allowed)
                extra = f" (did you mean '{hint}'?)" if hint else ""
                self.error(
                    key_node,
                    f"unknown key '{key}' in {what}{extra}; allowed: {', '.join(allowed)}",
                )
                continue
            result[key] = (key_node, value_node)
        for key in required:
            if key not in result:
                self.error(node, f"{what} needs '{key}'")
        return result

    def sequence(self, node: yaml.Node, what: str) -> list[yaml.Node]:
        if isinstance(node, yaml.ScalarNode) and node.tag.endswith(":null"):
            return []
        if not isinstance(node, yaml.SequenceNode):
            self.error(node, f"{what} must be a list")
            return []
        return list(node.value)

    def scalar(self, node: yaml.Node, what: str) -> str | None:
        if not isinstance(node, yaml.ScalarNode):
            self.error(node, f"{what} must be a single value, not a list or mapping")
            return None
        return str(node.value)

    def name(self, node: yaml.Node, what: str) -> str | None:
        text = self.scalar(node, what)
        if text is None:
            return None
        if not is_name(text):
            self.error(
                node,
                f"{what} '{text}' is not a name: use letters, digits and '_' in parts joined "
                "by '.', not starting with a digit",
            )
            return None
        if text in ("true", "false"):
            self.error(node, f"{what} cannot be '{text}': it is a boolean literal")
            return None
        return text

    def unique(
        self,
        items: list[tuple[str, yaml.Node]],
        what: str,
    ) -> None:
        seen: dict[str, yaml.Node] = {}
        for name, node in items:
            if name in seen:
                first = self.at(seen[name])
                self.error(
                    node, f"duplicate {what} name '{name}' (first defined at line {first.line})"
                )
            else:
                seen[name] = node

    def template(
        self, node: yaml.Node, what: str, values: Mapping[str, str] | None
    ) -> tuple[str, Callable[[int], int]] | None:
        """A scalar's text with `{param}` placeholders filled in, and the offset map back."""
        text = self.scalar(node, what)
        if text is None:
            return None
        if isinstance(node, yaml.ScalarNode) and node.tag.endswith(":bool"):
            text = text.lower()  # YAML's True/yes spelled as a guard
        if not values:
            return text, lambda offset: offset
        return substitute(text, values)

    def expression(
        self, node: yaml.Node, scope: Scope, what: str, values: Mapping[str, str] | None = None
    ) -> Expr | None:
        held = len(self.sizes)  # the scope measures as it resolves, in `sizes` when shared
        expr = self._parse(node, what, values, lambda text: resolve(parse_syntax(text), scope))
        if expr is not None:
            size(expr, self.sizes)  # refused by `&&`/`||` past MAX_TERMS written out, each
            self.terms += len(self.sizes) - held  # the terms new to the model: what it holds
            if self.terms > MAX_MODEL_TERMS:
                message = (
                    f"in {what}: the model's expressions hold more than {MAX_MODEL_TERMS} terms"
                )
                raise ModelError([*self.diagnostics, Diagnostic(self.at(node), message)])
        return expr

    def action(
        self, node: yaml.Node, scope: Scope, what: str, values: Mapping[str, str] | None = None
    ) -> Assign | None:
        return self._parse(
            node, what, values, lambda text: resolve_assign(parse_assign_syntax(text), scope)
        )

    def _parse(
        self,
        node: yaml.Node,
        what: str,
        values: Mapping[str, str] | None,
        parse: Callable[[str], T],
    ) -> T | None:
        """Parse a scalar (placeholders filled in); an error is recorded at its position."""
        filled = self.template(node, what, values)
        if filled is None:
            return None
        text, back = filled
        try:
            return parse(text)
        except ExpressionError as exc:
            self.error_at(self.at_offset(node, back(exc.offset)), f"in {what}: {exc.message}")
            return None


def scope_for(
    domains: Mapping[str, tuple[Value, ...]],
    predicates: Mapping[str, Expr] | None = None,
    aliases: Mapping[str, str] | None = None,
    sizes: dict[int, tuple[Expr, int]] | None = None,
) -> Scope:
    """Names known to an expression: variables, named predicates, and local aliases; `sizes`
    the reader's memory of what its expressions measure (`Reader.sizes`), when reading."""

    def suggest(name: str) -> str | None:  # only for a message: the names listed then
        return closest(name, [*domains, *(predicates or {}), *(aliases or {})])

    return Scope(domains, predicates, suggest, aliases, sizes)


def each(
    reader: Reader, nodes: list[yaml.Node], parse: Callable[[yaml.Node], T | None]
) -> Iterator[T]:
    for node in nodes:
        item = parse(node)
        if item is not None:
            yield item


def key_node(node: yaml.Node, key: str) -> yaml.Node | None:
    """The value node of `key` in a mapping node, if it has one."""
    if isinstance(node, yaml.MappingNode):
        for key_part, value in node.value:
            if key_part.value == key:
                return value  # type: ignore[no-any-return]
    return None


def name_node(node: yaml.Node) -> yaml.Node:
    """An item's `name` value node (where a duplicate name is reported), else the item's."""
    found = key_node(node, "name")
    return node if found is None else found
