"""Expression and action text: tokens, a syntax tree with offsets, names resolved (section 8).

Parsing happens in two stages so that every error can be located: the text is first parsed
into a syntax tree that remembers character offsets, then names are resolved against the
model's variables (and, for rich models, named predicates), which yields the typed `Expr`
of `planner.model.expressions`.  `!` binds tightest, then `&&`, `||`, `->` (right-associative).
Nesting is bounded by `MAX_NESTING`, with a located error.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from planner.model.expressions import (
    MAX_NESTING,
    Assign,
    BoolVar,
    Const,
    Equals,
    Expr,
    ExpressionError,
    Implies,
    Not,
    SameValue,
    Value,
    conjunction,
    depth,
    disjunction,
    negation,
)

# ---- syntax ---------------------------------------------------------------------------------

_TOKEN = re.compile(
    r"\s*(?:(?P<op>==|!=|&&|\|\||->|:=|!|\(|\))"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*)"
    r"|(?P<number>-?[0-9]+))"
)
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*\Z")


def is_name(text: str) -> bool:
    """A dotted identifier, as section 8 requires of every name."""
    return _NAME.match(text) is not None


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str  # "op", "name", "number", "end"
    text: str
    offset: int


def _tokenize(text: str) -> list[_Token]:
    tokens: list[_Token] = []
    pos, end = 0, len(text.rstrip())  # not text[pos:].strip() per token: quadratic
    while pos < end:
        match = _TOKEN.match(text, pos)
        if match is None or match.end() == pos:
            start = pos + len(text[pos:]) - len(text[pos:].lstrip())
            if text[start] == "=":
                raise ExpressionError(
                    "'=' is not an operator: use '==' to compare, ':=' to assign", start
                )
            raise ExpressionError(f"unexpected character {text[start]!r}", start)
        kind = match.lastgroup
        assert kind is not None
        tokens.append(_Token(kind, match.group(kind), match.start(kind)))
        pos = match.end()
    tokens.append(_Token("end", "", len(text.rstrip())))
    return tokens


@dataclass(frozen=True, slots=True)
class Word:
    """A name, number or literal in the syntax tree, with its offset."""

    text: str
    offset: int


@dataclass(frozen=True, slots=True)
class SyntaxNode:
    """Untyped syntax: op is one of `word`, `cmp`, `!`, `&&`, `||`, `->`."""

    op: str
    offset: int
    args: tuple[SyntaxNode, ...] = ()
    word: Word | None = None
    compare: str = ""  # "==" or "!=" for op "cmp"
    right: Word | None = None


class _Parser:
    def __init__(self, text: str) -> None:
        self.tokens = _tokenize(text)
        self.index = 0
        self.depth = 0  # open '(', '!' and '->' around the current token: the recursion depth

    def deeper(self, token: _Token) -> None:
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise ExpressionError(
                f"nested more than {MAX_NESTING} deep (each '(', '!' and '->' opens a level)",
                token.offset,
            )

    @property
    def current(self) -> _Token:
        return self.tokens[self.index]

    def take(self) -> _Token:
        token = self.tokens[self.index]
        self.index += 1
        return token

    def expect_end(self) -> None:
        token = self.current
        if token.kind != "end":
            raise ExpressionError(f"unexpected {token.text!r}", token.offset)

    def implication(self) -> SyntaxNode:
        left = self.disjunction()
        if self.current.text == "->":
            arrow = self.take()
            self.deeper(arrow)
            right = self.implication()
            self.depth -= 1
            return SyntaxNode("->", arrow.offset, (left, right))
        return left

    def disjunction(self) -> SyntaxNode:
        args = [self.conjunction()]
        while self.current.text == "||":
            self.take()
            args.append(self.conjunction())
        return args[0] if len(args) == 1 else SyntaxNode("||", args[0].offset, tuple(args))

    def conjunction(self) -> SyntaxNode:
        args = [self.unary()]
        while self.current.text == "&&":
            self.take()
            args.append(self.unary())
        return args[0] if len(args) == 1 else SyntaxNode("&&", args[0].offset, tuple(args))

    def unary(self) -> SyntaxNode:
        token = self.current
        if token.text == "!":
            self.take()
            self.deeper(token)
            arg = self.unary()
            self.depth -= 1
            return SyntaxNode("!", token.offset, (arg,))
        if token.text == "(":
            self.take()
            self.deeper(token)
            inner = self.implication()
            if self.current.text != ")":
                raise ExpressionError(
                    f"expected ')' to close the '(' at offset {token.offset}"
                    + (f", found {self.current.text!r}" if self.current.kind != "end" else ""),
                    self.current.offset,
                )
            self.take()
            self.depth -= 1
            return inner
        if token.kind in ("name", "number"):
            self.take()
            word = Word(token.text, token.offset)
            if self.current.text in ("==", "!="):
                compare = self.take().text
                right = self.current
                if right.kind not in ("name", "number"):
                    raise ExpressionError(
                        f"expected a value or variable after {compare!r}", right.offset
                    )
                self.take()
                return SyntaxNode(
                    "cmp",
                    token.offset,
                    word=word,
                    compare=compare,
                    right=Word(right.text, right.offset),
                )
            return SyntaxNode("word", token.offset, word=word)
        if token.kind == "end":
            raise ExpressionError("expression ends too early", token.offset)
        raise ExpressionError(f"unexpected {token.text!r}", token.offset)


def parse_syntax(text: str) -> SyntaxNode:
    """Parse expression text into an untyped tree; raises `ExpressionError` on bad syntax."""
    parser = _Parser(text)
    node = parser.implication()
    parser.expect_end()
    return node


@dataclass(frozen=True, slots=True)
class AssignSyntax:
    target: Word
    value: Word


def parse_assign_syntax(text: str) -> AssignSyntax:
    """Parse `x := v`; raises `ExpressionError` on bad syntax."""
    tokens = _tokenize(text)
    if len(tokens) < 2 or tokens[0].kind != "name":
        raise ExpressionError("an action must look like 'variable := value'", tokens[0].offset)
    if tokens[1].text != ":=":
        raise ExpressionError(f"expected ':=' after {tokens[0].text!r}", tokens[1].offset)
    if len(tokens) < 3 or tokens[2].kind not in ("name", "number"):
        raise ExpressionError("expected a value or variable after ':='", tokens[2].offset)
    if tokens[3].kind != "end":
        raise ExpressionError(f"unexpected {tokens[3].text!r} after the action", tokens[3].offset)
    return AssignSyntax(
        Word(tokens[0].text, tokens[0].offset), Word(tokens[2].text, tokens[2].offset)
    )


# ---- name resolution ------------------------------------------------------------------------


class Scope:
    """What names mean while resolving: variable domains and named predicates.

    `domains` maps each variable to its domain (a tuple of values, `(False, True)` for bool).
    `predicates` maps extra names (an ability's `enabled`, an operation's `goal`, ...) to
    already resolved expressions.  `suggest` proposes the closest known name in messages.
    """

    def __init__(
        self,
        domains: Mapping[str, tuple[Value, ...]],
        predicates: Mapping[str, Expr] | None = None,
        suggest: Callable[[str], str | None] | None = None,
        aliases: Mapping[str, str] | None = None,
    ) -> None:
        self.domains = domains
        self.predicates = predicates or {}
        self.suggest = suggest or (lambda name: None)
        self.aliases = aliases or {}
        self.depths: dict[int, tuple[Expr, int]] = {}  # the predicates' `depth`s, as measured

    def canonical(self, word: Word) -> Word:
        """The word with a local name (a resource's `ref`) replaced by its global name."""
        name = self.aliases.get(word.text)
        return word if name is None else Word(name, word.offset)

    def is_bool(self, name: str) -> bool:
        return self.domains[name] == (False, True)

    def unknown(self, word: Word, what: str = "variable") -> ExpressionError:
        hint = self.suggest(word.text)
        extra = f" (did you mean '{hint}'?)" if hint else ""
        return ExpressionError(f"unknown {what} '{word.text}'{extra}", word.offset)

    def value_of(self, variable: str, word: Word) -> Value:
        """The domain value `word` names for `variable`, or an error naming the domain."""
        domain = self.domains[variable]
        if domain == (False, True):
            if word.text in ("true", "false"):
                return word.text == "true"
            raise ExpressionError(
                f"'{word.text}' is not a value of boolean variable '{variable}' "
                "(use true or false)",
                word.offset,
            )
        if word.text in domain:
            return word.text
        shown = ", ".join(str(v) for v in domain)
        raise ExpressionError(
            f"'{word.text}' is not a value of '{variable}' (domain: {shown})", word.offset
        )


def resolve(node: SyntaxNode, scope: Scope) -> Expr:
    """Turn a syntax tree into a typed expression, checking names, values, types and depth:
    named predicates stand for their expressions, so the parser alone cannot bound it."""
    expr, levels = _resolve(node, scope)
    if levels > MAX_NESTING:
        raise ExpressionError(
            f"nested more than {MAX_NESTING} deep ({levels} operators, counting those of the "
            "predicates it names)",
            0,  # the whole expression is too deep, not one place in it
        )
    return expr


def _resolve(node: SyntaxNode, scope: Scope) -> tuple[Expr, int]:
    """The typed expression and its `depth`, counted as it is built: walking the result would
    cost a guard that names a predicate of 10,000 conjuncts those 10,000 again."""
    match node.op:
        case "!":
            arg, levels = _resolve(node.args[0], scope)
            if isinstance(arg, Const):
                return negation(arg), 0
            return negation(arg), levels - 1 if isinstance(arg, Not) else levels + 1
        case "&&" | "||":
            parts = [_resolve(a, scope) for a in node.args]
            join = conjunction if node.op == "&&" else disjunction
            expr = join([part for part, _ in parts])
            return expr, _joined_depth(expr, parts)
        case "->":
            (left, on_left), (right, on_right) = (_resolve(a, scope) for a in node.args)
            return Implies(left, right), 1 + max(on_left, on_right)
        case "word":
            assert node.word is not None
            expr = _resolve_word(scope.canonical(node.word), scope)
            return expr, depth(expr, scope.depths)  # a predicate is measured once per scope
        case "cmp":
            assert node.word is not None and node.right is not None
            left_word, right_word = scope.canonical(node.word), scope.canonical(node.right)
            expr = _resolve_comparison(left_word, right_word, scope)
            expr = negation(expr) if node.compare == "!=" else expr
            return expr, int(isinstance(expr, Not))  # a variable, value or pair, or its negation
    raise AssertionError(node.op)


def _joined_depth(joined: Expr, parts: list[tuple[Expr, int]]) -> int:
    """The depth of `conjunction(parts)` or `disjunction(parts)` from the parts' depths: they
    drop constants and flatten parts of their own kind by one level."""
    for part, levels in parts:
        if part is joined:
            return levels
    if isinstance(joined, Const):
        return 0
    kind = type(joined)
    return 1 + max(
        levels - 1 if isinstance(part, kind) else levels
        for part, levels in parts
        if not isinstance(part, Const)
    )


def _resolve_word(word: Word, scope: Scope) -> Expr:
    if word.text in ("true", "false"):
        return Const(word.text == "true")
    if word.text in scope.domains:
        if not scope.is_bool(word.text):
            raise ExpressionError(
                f"'{word.text}' is not boolean; compare it with a value, "
                f"e.g. '{word.text} == {scope.domains[word.text][0]}'",
                word.offset,
            )
        return BoolVar(word.text)
    if word.text in scope.predicates:
        return scope.predicates[word.text]
    raise scope.unknown(word)


def _resolve_comparison(left: Word, right: Word, scope: Scope) -> Expr:
    if left.text not in scope.domains:
        if left.text in scope.predicates or left.text in ("true", "false"):
            raise ExpressionError(
                f"'{left.text}' is a predicate; only variables can be compared", left.offset
            )
        raise scope.unknown(left)
    if right.text in scope.domains:
        if scope.domains[right.text] != scope.domains[left.text]:
            raise ExpressionError(
                f"cannot compare '{left.text}' with '{right.text}': their domains differ",
                right.offset,
            )
        return SameValue(left.text, right.text)
    value = scope.value_of(left.text, right)
    if isinstance(value, bool):
        return BoolVar(left.text) if value else Not(BoolVar(left.text))
    return Equals(left.text, value)


def parse_expr(text: str, scope: Scope) -> Expr:
    """Parse and resolve expression text in one go."""
    return resolve(parse_syntax(text), scope)


def resolve_assign(syntax: AssignSyntax, scope: Scope) -> Assign:
    target, value = scope.canonical(syntax.target), scope.canonical(syntax.value)
    if target.text not in scope.domains:
        raise scope.unknown(target)
    if value.text in scope.domains:
        if scope.domains[value.text] != scope.domains[target.text]:
            raise ExpressionError(
                f"cannot assign '{value.text}' to '{target.text}': their domains differ",
                value.offset,
            )
        return Assign(target.text, source=value.text)
    return Assign(target.text, value=scope.value_of(target.text, value))


_PLACEHOLDER = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\}")


def substitute(text: str, values: Mapping[str, str]) -> tuple[str, Callable[[int], int]]:
    """Replace `{param}` placeholders (instantiation per parameter).

    Returns the text and a function mapping an offset in it back to the template, so that
    errors in an instantiated expression still point at the template the engineer wrote.
    """
    pieces: list[str] = []
    spans: list[tuple[int, int, int]] = []  # (start in result, start in template, length)
    position = 0
    for match in _PLACEHOLDER.finditer(text):
        name = match.group(1)
        if name not in values:
            continue
        pieces.append(text[position : match.start()])
        start = sum(map(len, pieces))
        spans.append((start, match.start(), len(values[name])))
        pieces.append(values[name])
        position = match.end()
    pieces.append(text[position:])
    result = "".join(pieces)

    def back(offset: int) -> int:
        shift = 0
        for start, template_start, length in spans:
            if offset < start:
                break
            if offset < start + length:
                return template_start
            shift = (
                template_start
                + (len(text[template_start:].split("}", 1)[0]) + 1)
                - (start + length)
            )
        return offset + shift

    return result, back
