"""Expression and action text as syntax: tokens, and a tree that remembers offsets (section 8).

The first of the two stages of reading an expression, so that every error can be located:
the text is parsed into a `SyntaxNode` tree whose words keep their character offsets, and
`planner.model.expression_text` resolves its names against the model.  `!` binds
tightest, then `&&`, `||`, `->` (right-associative).  Nesting is bounded by `MAX_NESTING`,
with a located error.  `substitute` fills a template's `{param}` placeholders in the text
before it is parsed, keeping the way back to the template's offsets.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from planner.model.expressions import MAX_NESTING, ExpressionError

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
