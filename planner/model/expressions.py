"""Predicates and actions over finite-domain variables (DESIGN.md section 8).

The typed `Expr` every planner, the runner and the pages work on, with its constructors
and formatting, and the `Assign` of an action; text becomes these in
`planner.model.expression_syntax` (parsed) and `planner.model.expression_text` (resolved).

Nesting is bounded (`MAX_NESTING`, docs/models.md), so that a hostile or generated model is
refused with a located error instead of overflowing the stack of whatever walks it later.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

Value = bool | str
"""A value of a variable's domain: `False`/`True` for booleans, a name for enumerations."""

MAX_NESTING = 100
"""How deep an expression may nest: far beyond any real guard, and shallow enough that every
recursive walker over expressions (parser, resolution, formatting, the BDD and SAT compilers,
the runner's predicates) stays well within Python's recursion limit."""

MAX_TERMS = 100_000
"""How many nodes one expression may have with the predicates it names written out: a
predicate naming the one before twice doubles per line, so 20 lines of text would stand for
millions of nodes that joining copies and every planner walks (issue 26)."""


class ExpressionError(Exception):
    """A problem in expression or action text, at a character offset of that text."""

    def __init__(self, message: str, offset: int) -> None:
        super().__init__(message)
        self.message = message
        self.offset = offset


@dataclass(frozen=True, slots=True)
class Const:
    value: bool


@dataclass(frozen=True, slots=True)
class BoolVar:
    """A boolean variable used as a predicate."""

    name: str


@dataclass(frozen=True, slots=True)
class Equals:
    """`name == value`; `!=` is `Not(Equals(...))`."""

    name: str
    value: Value


@dataclass(frozen=True, slots=True)
class SameValue:
    """`left == right` for two variables of the same domain."""

    left: str
    right: str


@dataclass(frozen=True, slots=True)
class Not:
    arg: Expr


@dataclass(frozen=True, slots=True)
class And:
    args: tuple[Expr, ...]


@dataclass(frozen=True, slots=True)
class Or:
    args: tuple[Expr, ...]


@dataclass(frozen=True, slots=True)
class Implies:
    left: Expr
    right: Expr


Expr = Const | BoolVar | Equals | SameValue | Not | And | Or | Implies

TRUE = Const(True)
FALSE = Const(False)


def conjunction(args: list[Expr] | tuple[Expr, ...]) -> Expr:
    """`a && b && ...`, flattening nested conjunctions and dropping `true`."""
    flat: list[Expr] = []
    for arg in args:
        if isinstance(arg, And):
            flat.extend(arg.args)
        elif arg == TRUE:
            continue
        elif arg == FALSE:
            return FALSE
        else:
            flat.append(arg)
    if not flat:
        return TRUE
    return flat[0] if len(flat) == 1 else And(tuple(flat))


def conjuncts(expr: Expr) -> tuple[Expr, ...]:
    """The top-level parts of a conjunction (the expression itself if it is not one)."""
    if isinstance(expr, And):
        return tuple(part for arg in expr.args for part in conjuncts(arg))
    return (expr,)


def disjunction(args: list[Expr] | tuple[Expr, ...]) -> Expr:
    """`a || b || ...`, flattening nested disjunctions and dropping `false`."""
    flat: list[Expr] = []
    for arg in args:
        if isinstance(arg, Or):
            flat.extend(arg.args)
        elif arg == FALSE:
            continue
        elif arg == TRUE:
            return TRUE
        else:
            flat.append(arg)
    if not flat:
        return FALSE
    return flat[0] if len(flat) == 1 else Or(tuple(flat))


def negation(arg: Expr) -> Expr:
    if isinstance(arg, Not):
        return arg.arg
    if isinstance(arg, Const):
        return Const(not arg.value)
    return Not(arg)


def _operands(expr: Expr) -> tuple[Expr, ...]:
    match expr:
        case Not(arg):
            return (arg,)
        case And(args) | Or(args):
            return args
        case Implies(left, right):
            return (left, right)
    return ()


def depth(expr: Expr, measured: dict[int, tuple[Expr, int]] | None = None) -> int:
    """How many operators deep `expr` nests (0 for a variable or constant).

    Iterative, so that it can measure what is too deep to walk recursively.  `measured` (id ->
    the node and its depth; holding the node keeps its id from being another's) carries what
    was measured from call to call: the guards that name one large predicate walk it once.
    """
    return _measure(expr, measured, lambda below: 1 + max(below) if below else 0)


def size(expr: Expr, measured: dict[int, tuple[Expr, int]] | None = None) -> int:
    """How many nodes `expr` has written out as a tree (a shared part counted each time it
    appears), counted over its shared nodes once each, as `depth` is: linear in what is held,
    whatever it stands for."""
    return _measure(expr, measured, lambda below: 1 + sum(below))


def _measure(
    expr: Expr, measured: dict[int, tuple[Expr, int]] | None, combine: Callable[[list[int]], int]
) -> int:
    """`combine` of the operands' measures, node by node from the leaves up, each shared node
    once (`measured`: id -> the node and its measure, kept between calls)."""
    known = {} if measured is None else measured
    todo = [expr]
    while todo:
        node = todo[-1]
        entry = known.get(id(node))
        if entry is not None and entry[0] is node:
            todo.pop()
            continue
        operands = _operands(node)
        waiting = [o for o in operands if (e := known.get(id(o))) is None or e[0] is not o]
        if waiting:
            todo.extend(waiting)
            continue
        todo.pop()
        known[id(node)] = (node, combine([known[id(o)][1] for o in operands]))
    return known[id(expr)][1]


def variables_of(expr: Expr) -> frozenset[str]:
    """The variables an expression reads (one pass with one set: the planner asks this of
    every guard of a model of thousands of transitions)."""
    found: set[str] = set()
    todo = [expr]
    while todo:
        node = todo.pop()
        if isinstance(node, Equals | BoolVar):
            found.add(node.name)
        elif isinstance(node, And | Or):
            todo.extend(node.args)
        elif isinstance(node, Not):
            todo.append(node.arg)
        elif isinstance(node, SameValue):
            found.update((node.left, node.right))
        elif isinstance(node, Implies):
            todo.extend((node.left, node.right))
        elif not isinstance(node, Const):
            raise TypeError(node)
    return frozenset(found)


def format_value(value: Value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return value


_PRECEDENCE = {Implies: 1, Or: 2, And: 3}


def format_expr(expr: Expr) -> str:
    """Text in the section 8 syntax that parses back to the same expression."""
    return _format(expr, 0)


def _format(expr: Expr, parent: int) -> str:
    match expr:
        case Const(value):
            return format_value(value)
        case BoolVar(name):
            return name
        case Equals(name, value):
            return f"{name} == {format_value(value)}"
        case SameValue(left, right):
            return f"{left} == {right}"
        case Not(Equals(name, value)):
            return f"{name} != {format_value(value)}"
        case Not(SameValue(left, right)):
            return f"{left} != {right}"
        case Not(arg):
            return "!" + _format(arg, 4)
        case And(args) | Or(args):
            level = _PRECEDENCE[type(expr)]
            text = (" && " if isinstance(expr, And) else " || ").join(
                _format(a, level + 1) for a in args
            )
            return f"({text})" if parent > level else text
        case Implies(left, right):
            text = f"{_format(left, 2)} -> {_format(right, 1)}"
            return f"({text})" if parent > 1 else text
    raise TypeError(expr)


@dataclass(frozen=True, slots=True)
class Assign:
    """`target := value` or, when `source` is set, `target := source` (another variable)."""

    target: str
    value: Value | None = None
    source: str | None = None

    def __str__(self) -> str:
        if self.source is not None:
            return f"{self.target} := {self.source}"
        assert self.value is not None
        return f"{self.target} := {format_value(self.value)}"


def assigned(actions: Iterable[Assign], values: Mapping[str, Value]) -> dict[str, Value]:
    """The values `actions` assign, every one reading `values` (the state before them)."""
    out: dict[str, Value] = {}
    for action in actions:
        value = values[action.source] if action.source is not None else action.value
        assert value is not None
        out[action.target] = value
    return out
