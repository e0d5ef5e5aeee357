"""Reading models from YAML text with errors that name file, line, column and the problem.

The YAML is composed into nodes (not constructed into plain dicts) so that every scalar keeps
its position; expression errors are mapped from their offset inside the scalar back to the
line and column in the file.  All problems found are collected before raising, so an
engineer sees every mistake at once.  Pure: text in, `Model` out.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import TypeVar

import yaml

from planner.display_keys import fill_checked, read_value_words, read_words
from planner.expressions import (
    TRUE,
    Assign,
    Expr,
    ExpressionError,
    Scope,
    Value,
    is_name,
    parse_assign_syntax,
    parse_syntax,
    resolve,
    resolve_assign,
    substitute,
)
from planner.model import (
    BOOL,
    Model,
    SourceLocation,
    Specification,
    Transition,
    TransitionKind,
    Variable,
    VariableKind,
)

try:  # the C loader composes several times faster; fall back where libyaml is missing
    _Loader: type = yaml.CSafeLoader
except AttributeError:  # pragma: no cover
    _Loader = yaml.SafeLoader

T = TypeVar("T")

MAX_YAML_NESTING = 100
"""Lists and mappings nested deeper are refused: a model needs about 8 levels, and libyaml's
composer recurses in C, so that `[[[[...` 100,000 deep kills the process (editor included)."""


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

    # -- locations -----------------------------------------------------------------------------

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

    # -- structure -----------------------------------------------------------------------------

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
        """Refuse nesting beyond `MAX_YAML_NESTING` from the parser's events (a flat stream,
        no recursion), before the composer sees it; other YAML errors are left to it."""
        level = 0
        try:
            for event in yaml.parse(self.text, Loader=_Loader):
                if isinstance(event, yaml.CollectionStartEvent):
                    level += 1
                    if level > MAX_YAML_NESTING:
                        mark = event.start_mark
                        where = SourceLocation(self.file, mark.line + 1, mark.column + 1)
                        message = f"lists and mappings nested more than {MAX_YAML_NESTING} deep"
                        raise ModelError([Diagnostic(where, f"YAML: {message}")])
                elif isinstance(event, yaml.CollectionEndEvent):
                    level -= 1
        except yaml.YAMLError:
            return

    def mapping(
        self, node: yaml.Node, what: str, allowed: Iterable[str], required: Iterable[str] = ()
    ) -> dict[str, tuple[yaml.Node, yaml.Node]] | None:
        """Keys of a mapping node → (key node, value node); unknown or missing keys are errors."""
        if not isinstance(node, yaml.MappingNode):
            self.error(node, f"{what} must be a mapping (key: value)")
            return None
        allowed = list(allowed)
        result: dict[str, tuple[yaml.Node, yaml.Node]] = {}
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

    # -- expressions ---------------------------------------------------------------------------

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
        return self._parse(node, what, values, lambda text: resolve(parse_syntax(text), scope))

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
) -> Scope:
    """Names known to an expression: variables, named predicates, and local aliases."""

    def suggest(name: str) -> str | None:  # only for a message: the names listed then
        return closest(name, [*domains, *(predicates or {}), *(aliases or {})])

    return Scope(domains, predicates, suggest, aliases)


def _each(
    reader: Reader, nodes: list[yaml.Node], parse: Callable[[yaml.Node], T | None]
) -> Iterator[T]:
    for node in nodes:
        item = parse(node)
        if item is not None:
            yield item


# ---- the flat model (section 8) -------------------------------------------------------------

FLAT_KEYS = ("variables", "transitions", "specifications")
_VARIABLE_KEYS = ("name", "domain", "initial", "kind", "description", "display", "display_values")
_TRANSITION_KEYS = ("name", "kind", "guard", "actions", "description", "display")
_SPECIFICATION_KEYS = ("name", "invariant", "description", "display")


def read_variable(reader: Reader, node: yaml.Node, prefix: str = "") -> Variable | None:
    fields = reader.mapping(node, "a variable", _VARIABLE_KEYS, required=("name", "domain"))
    if fields is None or "name" not in fields or "domain" not in fields:
        return None
    name = reader.name(fields["name"][1], "variable name")
    domain = read_domain(reader, fields["domain"][1])
    # A variable with a bad kind or initial value is still returned (its error recorded), so
    # that expressions using it do not add "unknown variable" errors of their own.
    kind = VariableKind.ESTIMATED
    if "kind" in fields:
        kind_text = reader.scalar(fields["kind"][1], "variable kind")
        options = [k.value for k in VariableKind]
        if kind_text is not None and kind_text not in options:
            hint = closest(kind_text, options)
            extra = f" (did you mean '{hint}'?)" if hint else ""
            reader.error(
                fields["kind"][1],
                f"unknown variable kind '{kind_text}'{extra}; use one of {', '.join(options)}",
            )
        elif kind_text is not None:
            kind = VariableKind(kind_text)
    if name is None or domain is None:
        return None
    initial: Value = domain[0]
    if "initial" in fields:
        initial_node = fields["initial"][1]
        text = reader.scalar(initial_node, "initial value")
        value = _domain_value(text, initial_node, domain == BOOL) if text is not None else None
        if text is not None and value not in domain:
            reader.error(
                initial_node,
                f"initial value '{text}' of '{prefix}{name}' is outside its domain "
                f"{_show_domain(domain)}",
            )
        elif value is not None:
            initial = value
    what = f"variable '{prefix}{name}'"
    return Variable(
        prefix + name,
        domain,
        initial,
        kind,
        reader.at(node),
        read_description(reader, fields),
        read_display(reader, fields, what),
        read_value_words(reader, fields["display_values"][1], what, domain)
        if "display_values" in fields
        else (),
    )


def read_description(reader: Reader, fields: Mapping[str, tuple[yaml.Node, yaml.Node]]) -> str:
    if "description" not in fields:
        return ""
    return reader.scalar(fields["description"][1], "description") or ""


def read_display(
    reader: Reader,
    fields: Mapping[str, tuple[yaml.Node, yaml.Node]],
    what: str,
    parameters: Collection[str] = (),
) -> str:
    """The `display` of `what` as written (placeholders unfilled); "" if none or bad."""
    if "display" not in fields:
        return ""
    return read_words(reader, fields["display"][1], f"the display of {what}", parameters) or ""


def _domain_value(text: str, node: yaml.Node, is_bool: bool) -> Value:
    if is_bool and isinstance(node, yaml.ScalarNode) and text.lower() in ("true", "false"):
        return text.lower() == "true"
    return text


def _show_domain(domain: tuple[Value, ...]) -> str:
    if domain == BOOL:
        return "bool"
    return "[" + ", ".join(str(v) for v in domain) + "]"


def read_domain(reader: Reader, node: yaml.Node) -> tuple[Value, ...] | None:
    if isinstance(node, yaml.ScalarNode):
        if node.value == "bool":
            return BOOL
        reader.error(node, f"domain must be 'bool' or a list of values, not '{node.value}'")
        return None
    values = reader.sequence(node, "domain")
    if not values:
        if isinstance(node, yaml.SequenceNode):
            reader.error(node, "domain must have at least one value")
        return None
    result: list[str] = []
    for value_node in values:
        text = reader.scalar(value_node, "domain value")
        if text is None:
            return None
        if value_node.tag.endswith(":bool") or text in ("true", "false"):
            reader.error(
                value_node,
                "use 'domain: bool' for booleans; true/false cannot be enumeration values",
            )
            return None
        if not (is_name(text) and "." not in text) and not text.lstrip("-").isdigit():
            reader.error(value_node, f"domain value '{text}' must be a plain name or an integer")
            return None
        if text in result:
            reader.error(value_node, f"duplicate domain value '{text}'")
            return None
        result.append(text)
    return tuple(result)


def read_transition(
    reader: Reader,
    node: yaml.Node,
    scope: Scope,
    kinds: Mapping[str, Variable],
    values: Mapping[str, str] | None = None,
    label: str = "",
    words: Mapping[str, str] | None = None,
) -> Transition | None:
    """A transition as written; `values` fill `{param}` placeholders (ability instances),
    and `words` (the values' words for people) fill those of its `display`.

    `label` prefixes the name in messages (`r1.goto.` for an ability's transitions).
    """
    fields = reader.mapping(node, "a transition", _TRANSITION_KEYS, required=("name",))
    if fields is None or "name" not in fields:
        return None
    name = reader.name(fields["name"][1], "transition name")
    about = read_description(reader, fields)
    display = read_display(reader, fields, f"transition '{label}{name}'", (values or {}).keys())
    if display and words:
        what = f"the display of transition '{label}{name}'"
        display = fill_checked(reader, fields["display"][1], what, display, words)
    kind = TransitionKind.CONTROLLED
    if "kind" in fields:
        text = reader.scalar(fields["kind"][1], "transition kind")
        options = [k.value for k in TransitionKind]
        if text is not None and text not in options:
            hint = closest(text, options)
            extra = f" (did you mean '{hint}'?)" if hint else ""
            reader.error(
                fields["kind"][1],
                f"unknown transition kind '{text}'{extra}; use one of {', '.join(options)}",
            )
            return None
        if text is not None:
            kind = TransitionKind(text)
    where = f"transition '{label}{name}'"
    guard: Expr | None = None
    if "guard" in fields:
        guard = reader.expression(fields["guard"][1], scope, f"the guard of {where}", values)
        if guard is None:
            return None
    actions = read_actions(reader, fields.get("actions"), scope, where, kind, kinds, values)
    if name is None or actions is None:
        return None
    if guard is None:
        guard = TRUE
    return Transition(name, kind, guard, actions, reader.at(node), about, display)


def read_actions(
    reader: Reader,
    entry: tuple[yaml.Node, yaml.Node] | None,
    scope: Scope,
    where: str,
    kind: TransitionKind,
    variables: Mapping[str, Variable],
    values: Mapping[str, str] | None = None,
) -> tuple[Assign, ...] | None:
    if entry is None:
        return ()
    nodes = reader.sequence(entry[1], f"the actions of {where}")
    actions: list[Assign] = []
    ok = True
    for action_node in nodes:
        action = reader.action(action_node, scope, f"an action of {where}", values)
        if action is None:
            ok = False
            continue
        if any(a.target == action.target for a in actions):
            reader.error(action_node, f"'{action.target}' is assigned twice in {where}")
            ok = False
            continue
        target = variables[action.target]
        if target.kind is VariableKind.MEASURED and kind in (
            TransitionKind.CONTROLLED,
            TransitionKind.AUTOMATIC,
        ):
            reader.error(
                action_node,
                f"{kind.value} {where} assigns measured variable '{action.target}'; measured "
                "variables change only through effect or maintenance transitions",
            )
            ok = False
            continue
        actions.append(action)
    return tuple(actions) if ok else None


def read_specification(reader: Reader, node: yaml.Node, scope: Scope) -> Specification | None:
    fields = reader.mapping(
        node, "a specification", _SPECIFICATION_KEYS, required=("name", "invariant")
    )
    if fields is None or "name" not in fields or "invariant" not in fields:
        return None
    name = reader.name(fields["name"][1], "specification name")
    invariant = reader.expression(
        fields["invariant"][1], scope, f"the invariant of specification '{name}'"
    )
    if name is None or invariant is None:
        return None
    what = f"specification '{name}'"
    return Specification(
        name,
        invariant,
        reader.at(node),
        read_description(reader, fields),
        read_display(reader, fields, what),
    )


def read_flat(reader: Reader, top: dict[str, tuple[yaml.Node, yaml.Node]]) -> Model:
    """Read the three section 8 lists into a checked `Model`."""
    variable_nodes = reader.sequence(top["variables"][1], "variables") if "variables" in top else []
    variables = list(_each(reader, variable_nodes, lambda n: read_variable(reader, n)))
    at = name_nodes(variable_nodes)
    reader.unique([(v.name, at(v.source)) for v in variables], "variable")
    by_name = {v.name: v for v in variables}
    scope = scope_for({v.name: v.domain for v in variables})

    transition_nodes = (
        reader.sequence(top["transitions"][1], "transitions") if "transitions" in top else []
    )
    transitions = list(
        _each(reader, transition_nodes, lambda n: read_transition(reader, n, scope, by_name))
    )
    at = name_nodes(transition_nodes)
    reader.unique([(t.name, at(t.source)) for t in transitions], "transition")

    spec_nodes = (
        reader.sequence(top["specifications"][1], "specifications")
        if "specifications" in top
        else []
    )
    specifications = list(_each(reader, spec_nodes, lambda n: read_specification(reader, n, scope)))
    at = name_nodes(spec_nodes)
    reader.unique([(s.name, at(s.source)) for s in specifications], "specification")
    reader.raise_if_errors()
    return Model(tuple(variables), tuple(transitions), tuple(specifications), reader.file)


def name_nodes(nodes: list[yaml.Node]) -> Callable[[SourceLocation | None], yaml.Node]:
    """The node a located item was read from (for duplicate-name messages): its `name`
    value, else the item's node, else the first node.  Indexed once by location, so that a
    model of 10,000 items is not scanned 10,000 times."""
    index: dict[tuple[int, int], yaml.Node] = {}
    for node in nodes:
        fields = node.value if isinstance(node, yaml.MappingNode) else []
        named = next((value for key, value in fields if key.value == "name"), node)
        index.setdefault((node.start_mark.line + 1, node.start_mark.column + 1), named)

    def at(location: SourceLocation | None) -> yaml.Node:
        if location is not None and (location.line, location.column) in index:
            return index[(location.line, location.column)]
        return nodes[0]

    return at


def load_model(text: str, file: str = "<model>") -> Model:
    """Parse a model file's text (flat or station form) into a checked flat `Model`.

    Raises `ModelError` listing every problem with its location.
    """
    from planner.station import load_station  # the station form builds on this module

    return load_station(text, file).model


def read_top(
    text: str, file: str, station_keys: tuple[str, ...]
) -> tuple[Reader, dict[str, tuple[yaml.Node, yaml.Node]]]:
    """The composed top-level mapping of a model file, its keys checked."""
    reader = Reader(text, file)
    root = reader.compose()
    if root is None:
        raise ModelError([Diagnostic(SourceLocation(file, 1, 1), "the model file is empty")])
    top = reader.mapping(root, "the model", FLAT_KEYS + station_keys)
    reader.raise_if_errors()
    assert top is not None
    return reader, top
