"""Expression and action text resolved against a model: names, values, types (section 8).

The second of two stages, so that every error can be located: `planner.model.expression_syntax`
parses the text into a syntax tree that remembers character offsets, then names are resolved
here against the model's variables (and, for rich models, named predicates), which yields the
typed `Expr` of `planner.model.expressions`.  `parse_expr` does both.  Depth is bounded by
`MAX_NESTING` here too: a named predicate stands for its whole expression.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from planner.model.expression_syntax import AssignSyntax, SyntaxNode, Word, parse_syntax
from planner.model.expressions import (
    MAX_NESTING,
    MAX_TERMS,
    And,
    Assign,
    BoolVar,
    Const,
    Equals,
    Expr,
    ExpressionError,
    Implies,
    Not,
    Or,
    SameValue,
    Value,
    conjunction,
    depth,
    disjunction,
    negation,
    size,
)


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
        sizes: dict[int, tuple[Expr, int]] | None = None,
    ) -> None:
        self.domains = domains
        self.predicates = predicates or {}
        self.suggest = suggest or (lambda name: None)
        self.aliases = aliases or {}
        self.depths: dict[int, tuple[Expr, int]] = {}  # the predicates' `depth`s, as measured
        # their `size`s: a model's reader shares one memory among all its scopes
        self.sizes: dict[int, tuple[Expr, int]] = {} if sizes is None else sizes

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
    _bounded([expr], scope)
    return expr


def _bounded(parts: list[Expr], scope: Scope) -> None:
    """Refuse what would be more than `MAX_TERMS` nodes written out, before it is made: a
    join copies the parts of the parts it flattens, so predicates that each name the one
    before twice would double the work, line by line (issue 26)."""
    terms = len(parts) - 1 + sum(size(part, scope.sizes) for part in parts)
    if terms > MAX_TERMS:
        raise ExpressionError(
            f"more than {MAX_TERMS} terms with the predicates it names written out (a "
            "predicate that names another twice doubles it): name fewer, or write it out",
            0,
        )


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
            _bounded([part for part, _ in parts], scope)
            join = conjunction if node.op == "&&" else disjunction
            expr = join([part for part, _ in parts])
            _joined_size(expr, [part for part, _ in parts], scope)
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


def _joined_size(joined: Expr, parts: list[Expr], scope: Scope) -> None:
    """Keep the `size` of `conjunction(parts)` or `disjunction(parts)`, from the parts'
    (`_bounded` measured them): they drop constants and hoist the operands of parts of their
    own kind.  Measuring the join itself would walk those operands again: a thousand guards
    naming a predicate of 20,000 conjuncts each, 20,000 times a thousand."""
    kind = type(joined)
    if kind not in (And, Or) or any(part is joined for part in parts):
        return
    total = 1
    for part in parts:
        measured = scope.sizes[id(part)][1]
        if isinstance(part, kind):
            total += measured - 1
        elif not isinstance(part, Const):
            total += measured
    scope.sizes[id(joined)] = (joined, total)


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
