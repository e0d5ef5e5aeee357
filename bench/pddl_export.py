"""Export a flat Sequence Planner model to a Unified Planning problem / PDDL for Fast Downward.

The export is an independent re-implementation of the step semantics so that a planner's
optimal plan lengths can be cross-checked against Fast Downward (A* + LM-cut):

* every transition is one unit-cost instantaneous action, so optimal cost == minimal steps;
* a non-automatic action additionally requires that no automatic guard holds (priority);
* controlled/maintenance actions additionally require their supervisor guard.

Each step is one action; in Fast Downward's translator every delete effect must be matched by
a precondition, else, once it has found the variable's mutex group, it emits a conditional
effect, which LM-cut rejects ("unsupported").  So actions are split on the old value of each
assigned variable whose value the guard does not fix (booleans only when set to false), and
likewise on the value of ``y`` for each copy ``x := y`` (conditional effects are out, too).
Split actions are named ``transition[y=v,...]``; :func:`transition_of` maps them back.  UP's
own effects do read the pre-state, but its PDDL writer refuses non-constant boolean assignments.

Two encodings of finite-domain variables (``ENCODINGS``): ``onehot`` (default), one 0-ary fluent
per (variable, value), split as above; ``typed``, a unary predicate per variable over a type of
its values, with an ``?old`` parameter that Fast Downward grounds.  Both translate to the same
SAS+ task (same variables, operators and expansions on the station benchmarks); onehot gives
plain propositional PDDL, typed a ~2x smaller file.

Also provided, independent of Unified Planning: :func:`simulate` (checks a plan step by step) and
:func:`bfs_min_length` (brute-force optimal length for small models), used as test oracles.
"""

from __future__ import annotations

import itertools
import re
from collections import OrderedDict, deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import unified_planning.model as upm
from unified_planning.io import PDDLWriter
from unified_planning.shortcuts import (
    FALSE,
    TRUE,
    And,
    BoolType,
    Fluent,
    InstantaneousAction,
    MinimizeActionCosts,
    Not,
    Object,
    Or,
    Problem,
    UserType,
)

Value = str | bool
State = dict[str, Value]
ENCODINGS = ("onehot", "typed")
KINDS = ("controlled", "automatic", "effect", "maintenance")
SUPERVISED_KINDS = ("controlled", "maintenance")
CHECK_PREFIX = "$check"  # bookkeeping actions; "$" cannot occur in a model name


class ModelError(ValueError):
    """The model, an expression, a start state or a supervisor guard is malformed."""


class PlanError(ValueError):
    """A plan is not a valid sequence of steps (see :func:`simulate`)."""


# --------------------------------------------------------------------------- expressions


@dataclass(frozen=True)
class Const:
    value: bool


@dataclass(frozen=True)
class Lit:
    """``var == value`` (for booleans ``value`` is True/False)."""

    var: str
    value: Value


@dataclass(frozen=True)
class VarEq:
    """``left == right`` for two variables of the same domain."""

    left: str
    right: str


@dataclass(frozen=True)
class NotE:
    arg: Expr


@dataclass(frozen=True)
class AndE:
    args: tuple[Expr, ...]


@dataclass(frozen=True)
class OrE:
    args: tuple[Expr, ...]


Expr = Const | Lit | VarEq | NotE | AndE | OrE
T, F = Const(True), Const(False)


@dataclass(frozen=True)
class Variable:
    name: str
    domain: tuple[Value, ...]
    initial: Value | None

    @property
    def is_bool(self) -> bool:
        return self.domain == (False, True)


@dataclass(frozen=True)
class Transition:
    name: str
    kind: str
    guard: Expr
    # (target variable, constant value or source variable name if ``copy``)
    actions: tuple[tuple[str, Value, bool], ...]

    def sources(self) -> list[str]:
        return sorted({v for _, v, copy in self.actions if copy})  # type: ignore[misc]


@dataclass
class FlatModel:
    """A parsed and validated flat model."""

    variables: dict[str, Variable]
    transitions: dict[str, Transition]
    specs: dict[str, Expr] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, model: Mapping[str, Any]) -> FlatModel:
        m = cls({}, {}, {})
        for v in model.get("variables") or []:
            name, dom = str(v["name"]), v.get("domain")
            if dom == "bool":
                domain: tuple[Value, ...] = (False, True)
            elif isinstance(dom, list) and dom:
                domain = tuple(str(x) for x in dom)
                if len(set(domain)) != len(domain):
                    raise ModelError(f"{name}: duplicate domain values")
            else:
                raise ModelError(f"{name}: domain must be 'bool' or a non-empty list")
            if name in m.variables:
                raise ModelError(f"duplicate variable {name}")
            var = Variable(name, domain, None)
            init = v.get("initial")
            m.variables[name] = Variable(name, domain, None if init is None else m.value(var, init))
        for t in model.get("transitions") or []:
            name, kind = str(t["name"]), str(t.get("kind", "controlled"))
            if kind not in KINDS:
                raise ModelError(f"{name}: unknown kind {kind}")
            if name in m.transitions:
                raise ModelError(f"duplicate transition {name}")
            acts = tuple(m.parse_action(a) for a in t.get("actions") or [])
            if len({a[0] for a in acts}) != len(acts):
                raise ModelError(f"{name}: a variable is assigned twice")
            m.transitions[name] = Transition(name, kind, m.parse(str(t.get("guard", "true"))), acts)
        for s in model.get("specifications") or []:
            m.specs[str(s["name"])] = m.parse(str(s["invariant"]))
        return m

    # ---- values and states

    def value(self, var: Variable, raw: object) -> Value:
        """Normalise a start/initial value (YAML gives bools for bool vars, strings otherwise)."""
        if var.is_bool:
            if isinstance(raw, bool):
                return raw
            if str(raw) in ("true", "false"):
                return str(raw) == "true"
        elif not isinstance(raw, bool) and str(raw) in var.domain:
            return str(raw)
        raise ModelError(f"{raw!r} is not a value of {var.name}")

    def state(self, start: Mapping[str, object] | None = None) -> State:
        """Complete state: ``start`` overrides the variables' ``initial`` values."""
        start = start or {}
        unknown = set(start) - set(self.variables)
        if unknown:
            raise ModelError(f"unknown variables in start state: {sorted(unknown)}")
        out: State = {}
        for name, var in self.variables.items():
            if name in start:
                out[name] = self.value(var, start[name])
            elif var.initial is not None:
                out[name] = var.initial
            else:
                raise ModelError(f"no start value for {name}")
        return out

    def is_bad(self, state: Mapping[str, Value]) -> bool:
        return not all(evaluate(e, state) for e in self.specs.values())

    # ---- parsing

    def parse(self, text: str) -> Expr:
        """Recursive-descent parser; precedence ``!`` > ``&&`` > ``||`` > ``->`` (right-assoc)."""
        return _Parser(self, text).parse()

    def parse_action(self, text: str) -> tuple[str, Value, bool]:
        m = re.fullmatch(r"\s*([A-Za-z0-9_.]+)\s*:=\s*([A-Za-z0-9_.]+)\s*", str(text))
        if not m:
            raise ModelError(f"bad action {text!r}")
        target, rhs = m.groups()
        var = self.variables.get(target)
        if var is None:
            raise ModelError(f"{text!r}: unknown variable {target}")
        if rhs in self.variables:
            self._same_domain(target, rhs)
            return target, rhs, True
        return target, self._const(var, rhs), False

    def _const(self, var: Variable, word: str) -> Value:
        if var.is_bool and word in ("true", "false"):
            return word == "true"
        if not var.is_bool and word in var.domain:
            return word
        raise ModelError(f"{word!r} is neither a variable nor a value of {var.name}")

    def _same_domain(self, a: str, b: str) -> None:
        if set(self.variables[a].domain) != set(self.variables[b].domain):
            raise ModelError(f"{a} and {b} have different domains")


_TOKEN = re.compile(r"\s*(==|!=|&&|\|\||->|[!()]|[A-Za-z0-9_.]+)")


class _Parser:
    def __init__(self, model: FlatModel, text: str) -> None:
        self.model, self.text, self.pos = model, text, 0
        self.toks: list[str] = []
        while True:
            m = _TOKEN.match(text, self.pos)
            if not m:
                if text[self.pos :].strip():
                    raise ModelError(f"cannot tokenize {text!r} at {self.pos}")
                break
            self.toks.append(m.group(1))
            self.pos = m.end()
        self.i = 0

    def peek(self) -> str | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self, expected: str | None = None) -> str:
        tok = self.peek()
        if tok is None or (expected is not None and tok != expected):
            raise ModelError(f"in {self.text!r}: expected {expected or 'more'}, got {tok!r}")
        self.i += 1
        return tok

    def parse(self) -> Expr:
        e = self.implies()
        if self.peek() is not None:
            raise ModelError(f"in {self.text!r}: unexpected {self.peek()!r}")
        return e

    def implies(self) -> Expr:
        lhs = self.disj()
        if self.peek() == "->":
            self.take()
            return mk_or([mk_not(lhs), self.implies()])
        return lhs

    def disj(self) -> Expr:
        args = [self.conj()]
        while self.peek() == "||":
            self.take()
            args.append(self.conj())
        return args[0] if len(args) == 1 else OrE(tuple(args))

    def conj(self) -> Expr:
        args = [self.unary()]
        while self.peek() == "&&":
            self.take()
            args.append(self.unary())
        return args[0] if len(args) == 1 else AndE(tuple(args))

    def unary(self) -> Expr:
        if self.peek() == "!":
            self.take()
            return NotE(self.unary())
        if self.peek() == "(":
            self.take()
            e = self.implies()
            self.take(")")
            return e
        word = self.take()
        if not re.fullmatch(r"[A-Za-z0-9_.]+", word):
            raise ModelError(f"in {self.text!r}: unexpected {word!r}")
        if self.peek() in ("==", "!="):
            op, rhs = self.take(), self.take()
            e = self.compare(word, rhs)
            return NotE(e) if op == "!=" else e
        if word in ("true", "false"):
            return Const(word == "true")
        var = self.model.variables.get(word)
        if var is None or not var.is_bool:
            raise ModelError(f"in {self.text!r}: {word!r} is not a boolean variable")
        return Lit(word, True)

    def compare(self, lhs: str, rhs: str) -> Expr:
        variables = self.model.variables
        if lhs not in variables and rhs in variables:
            lhs, rhs = rhs, lhs
        if lhs not in variables:
            raise ModelError(f"in {self.text!r}: unknown variable {lhs!r}")
        if rhs in variables:
            self.model._same_domain(lhs, rhs)
            return VarEq(lhs, rhs)
        return Lit(lhs, self.model._const(variables[lhs], rhs))


# --------------------------------------------------------------------------- expression utils


def mk_not(e: Expr) -> Expr:
    if isinstance(e, Const):
        return Const(not e.value)
    return e.arg if isinstance(e, NotE) else NotE(e)


def mk_and(args: Iterable[Expr]) -> Expr:
    out: list[Expr] = []
    for a in args:
        if a == F:
            return F
        if a != T:
            out.extend(a.args if isinstance(a, AndE) else (a,))
    return T if not out else out[0] if len(out) == 1 else AndE(tuple(out))


def mk_or(args: Iterable[Expr]) -> Expr:
    out: list[Expr] = []
    for a in args:
        if a == T:
            return T
        if a != F:
            out.extend(a.args if isinstance(a, OrE) else (a,))
    return F if not out else out[0] if len(out) == 1 else OrE(tuple(out))


def evaluate(e: Expr, state: Mapping[str, Value]) -> bool:
    if isinstance(e, Const):
        return e.value
    if isinstance(e, Lit):
        return state[e.var] == e.value
    if isinstance(e, VarEq):
        return state[e.left] == state[e.right]
    if isinstance(e, NotE):
        return not evaluate(e.arg, state)
    if isinstance(e, AndE):
        return all(evaluate(a, state) for a in e.args)
    return any(evaluate(a, state) for a in e.args)


def partial(
    e: Expr,
    known: Mapping[str, Value],
    excluded: Mapping[str, frozenset[Value]] | None = None,
) -> Expr:
    """Simplify ``e`` given some variables' values (and values some variables cannot have).

    Used to drop automatic-priority conjuncts that cannot fire together with a guard, which
    keeps Fast Downward's DNF splitting of negated conditions small.
    """
    excluded = excluded or {}
    if isinstance(e, Lit):
        if e.var in known:
            return Const(known[e.var] == e.value)
        return F if e.value in excluded.get(e.var, ()) else e
    if isinstance(e, VarEq):
        a, b = e.left, e.right
        if a in known and b in known:
            return Const(known[a] == known[b])
        if a in known or b in known:
            var, val = (b, known[a]) if a in known else (a, known[b])
            return partial(Lit(var, val), known, excluded)
        return e
    if isinstance(e, NotE):
        return mk_not(partial(e.arg, known, excluded))
    if isinstance(e, AndE):
        return mk_and(partial(a, known, excluded) for a in e.args)
    if isinstance(e, OrE):
        return mk_or(partial(a, known, excluded) for a in e.args)
    return e


def facts(e: Expr) -> tuple[dict[str, Value], dict[str, frozenset[Value]]]:
    """Literals implied by the top-level conjuncts of ``e`` (known values, excluded values)."""
    known: dict[str, Value] = {}
    excluded: dict[str, frozenset[Value]] = {}
    for c in e.args if isinstance(e, AndE) else (e,):
        if isinstance(c, Lit):
            known[c.var] = c.value
        elif isinstance(c, NotE) and isinstance(c.arg, Lit):
            if isinstance(c.arg.value, bool):
                known[c.arg.var] = not c.arg.value
            else:
                excluded[c.arg.var] = excluded.get(c.arg.var, frozenset()) | {c.arg.value}
    return known, excluded


def variables(e: Expr) -> set[str]:
    if isinstance(e, Lit):
        return {e.var}
    if isinstance(e, VarEq):
        return {e.left, e.right}
    if isinstance(e, NotE):
        return variables(e.arg)
    if isinstance(e, (AndE, OrE)):
        return set().union(*(variables(a) for a in e.args))
    return set()


def transition_of(action_name: str) -> str | None:
    """Transition name of an exported action (strips the ``[y=v]`` copy-grounding suffix);
    None for the zero-cost bookkeeping actions, which are not steps."""
    if action_name.startswith(CHECK_PREFIX):
        return None
    return action_name.split("[", 1)[0]


# --------------------------------------------------------------------------- step semantics


def _supervisor_exprs(m: FlatModel, guards: Mapping[str, str] | None) -> dict[str, Expr]:
    out: dict[str, Expr] = {}
    for name, text in (guards or {}).items():
        t = m.transitions.get(name)
        if t is None:
            raise ModelError(f"supervisor guard for unknown transition {name}")
        e = m.parse(text)
        if t.kind not in SUPERVISED_KINDS and e != T:
            raise ModelError(f"supervisor guard given for {t.kind} transition {name}")
        out[name] = e
    return out


def _apply(t: Transition, s: Mapping[str, Value]) -> State:
    new = dict(s)
    for target, v, copy in t.actions:
        new[target] = s[v] if copy else v  # type: ignore[index]
    return new


def _steps(
    m: FlatModel, s: Mapping[str, Value], sup: Mapping[str, Expr], maintenance: bool
) -> list[Transition]:
    autos = [t for t in m.transitions.values() if t.kind == "automatic" and evaluate(t.guard, s)]
    if autos:
        return autos
    return [
        t
        for t in m.transitions.values()
        if t.kind != "automatic"
        and (maintenance or t.kind != "maintenance")
        and evaluate(t.guard, s)
        and evaluate(sup.get(t.name, T), s)
    ]


class Badness:
    """Which states are bad: violating a specification or, with ``closure``, also those of
    DESIGN.md section 8, from which a chain of uncontrollable steps (the enabled automatic
    transitions where any is enabled, else the enabled effects) reaches a violation.

    The export's ``enforce_specifications`` excludes only violating states, so Fast Downward
    and SymK may plan through states that section 8 calls bad; ``closure`` finds those.
    """

    def __init__(self, m: FlatModel, closure: bool = False) -> None:
        self.m, self.closure = m, closure
        self.names = list(m.variables)
        self.known: dict[tuple[Value, ...], bool] = {}

    def __call__(self, state: Mapping[str, Value]) -> bool:
        if not self.closure:
            return self.m.is_bad(state)
        start = tuple(state[n] for n in self.names)
        if start in self.known:
            return self.known[start]
        seen, stack = {start}, [dict(state)]
        while stack:
            s = stack.pop()
            key = tuple(s[n] for n in self.names)
            if self.known.get(key) or self.m.is_bad(s):
                self.known[start] = True
                return True
            if key != start and key in self.known:
                continue  # known not bad, and so is everything it leads to
            for t in _uncontrollable_steps(self.m, s):
                n = _apply(t, s)
                nkey = tuple(n[x] for x in self.names)
                if nkey not in seen:
                    seen.add(nkey)
                    stack.append(n)
        for key in seen:  # none of them leads to a violation
            self.known[key] = False
        return False


def _uncontrollable_steps(m: FlatModel, s: Mapping[str, Value]) -> list[Transition]:
    autos = [t for t in m.transitions.values() if t.kind == "automatic" and evaluate(t.guard, s)]
    if autos:
        return autos
    return [t for t in m.transitions.values() if t.kind == "effect" and evaluate(t.guard, s)]


def simulate(
    model: Mapping[str, Any] | FlatModel,
    start: Mapping[str, object] | None,
    plan: Sequence[str],
    goal: str | None = None,
    supervisor_guards: Mapping[str, str] | None = None,
    maintenance: bool = False,
    check_specs: bool = True,
    closure: bool = False,
) -> list[State]:
    """Replay ``plan`` (transition names) and return the visited states.

    Raises :class:`PlanError` if a step is not possible (guard, automatic priority, maintenance,
    supervisor guard), a bad state is visited (``check_specs``; with ``closure`` bad as in
    section 8, see :class:`Badness`) or the goal fails at the end.
    """
    m = model if isinstance(model, FlatModel) else FlatModel.from_dict(model)
    sup = _supervisor_exprs(m, supervisor_guards)
    is_bad = Badness(m, closure)
    s = m.state(start)
    states = [s]
    if check_specs and is_bad(s):
        raise PlanError("start state is bad")
    for i, name in enumerate(plan):
        t = m.transitions.get(transition_of(name) or "")
        if t is None:
            raise PlanError(f"step {i}: unknown transition {name}")
        if t not in _steps(m, s, sup, maintenance):
            raise PlanError(f"step {i}: {t.name} is not possible in {s}")
        s = _apply(t, s)
        states.append(s)
        if check_specs and is_bad(s):
            raise PlanError(f"step {i}: {t.name} leads to a bad state {s}")
    if goal is not None and not evaluate(m.parse(goal), s):
        raise PlanError(f"goal {goal!r} does not hold at the end: {s}")
    return states


def check_plan(
    model: Mapping[str, Any] | FlatModel,
    start: Mapping[str, object] | None,
    goal: str,
    plan: Sequence[str],
    supervisor_guards: Mapping[str, str] | None = None,
    maintenance: bool = False,
    expected_length: int | None = None,
    closure: bool = False,
) -> None:
    """Raise :class:`PlanError` unless ``plan`` is valid (see :func:`simulate`), reaches ``goal``
    and, if given, has ``expected_length`` steps."""
    simulate(model, start, plan, goal, supervisor_guards, maintenance, closure=closure)
    if expected_length is not None and len(plan) != expected_length:
        raise PlanError(f"plan has {len(plan)} steps, expected {expected_length}: {plan}")


def bfs_min_length(
    model: Mapping[str, Any] | FlatModel,
    start: Mapping[str, object] | None,
    goal: str,
    supervisor_guards: Mapping[str, str] | None = None,
    maintenance: bool = False,
    max_states: int = 1_000_000,
    closure: bool = False,
) -> int | None:
    """Minimal plan length by explicit breadth-first search (an oracle for small models).

    Bad states (with ``closure``: as in section 8, see :class:`Badness`) are never entered;
    ``supervisor_guards`` may additionally restrict steps.  Returns None if the goal is
    unreachable.
    """
    m = model if isinstance(model, FlatModel) else FlatModel.from_dict(model)
    sup = _supervisor_exprs(m, supervisor_guards)
    is_bad = Badness(m, closure)
    g = m.parse(goal)
    names = list(m.variables)
    s0 = m.state(start)
    if is_bad(s0):
        return None
    seen = {tuple(s0[n] for n in names)}
    queue = deque([(s0, 0)])
    while queue:
        s, d = queue.popleft()
        if evaluate(g, s):
            return d
        for t in _steps(m, s, sup, maintenance):
            n = _apply(t, s)
            key = tuple(n[x] for x in names)
            if key not in seen and not is_bad(n):
                if len(seen) >= max_states:
                    raise RuntimeError(f"more than {max_states} states")
                seen.add(key)
                queue.append((n, d + 1))
    return None


# --------------------------------------------------------------------------- UP export


class _Encoder:
    """Builds UP fluents/expressions for one encoding."""

    def __init__(self, m: FlatModel, encoding: str, problem: Problem) -> None:
        if encoding not in ENCODINGS:
            raise ValueError(f"encoding must be one of {ENCODINGS}")
        self.m, self.encoding, self.problem = m, encoding, problem
        self.bool_fl: dict[str, upm.Fluent] = {}
        self.var_fl: dict[str, upm.Fluent] = {}  # typed: unary predicate
        self.val_fl: dict[tuple[str, Value], upm.Fluent] = {}  # onehot: 0-ary per value
        self.types: dict[frozenset[Value], upm.Type] = {}
        self.objs: dict[tuple[frozenset[Value], Value], upm.Object] = {}
        values_in_types: dict[Value, int] = {}
        for var in m.variables.values():
            key = frozenset(var.domain)
            if not var.is_bool and encoding == "typed" and key not in self.types:
                self.types[key] = UserType(f"dom_{var.name}")
                for v in var.domain:
                    values_in_types[v] = values_in_types.get(v, 0) + 1
        for var in m.variables.values():
            if var.is_bool:
                self.bool_fl[var.name] = fl = Fluent(var.name, BoolType())
                problem.add_fluent(fl, default_initial_value=False)
            elif encoding == "typed":
                key = frozenset(var.domain)
                for v in var.domain:
                    if (key, v) not in self.objs:
                        unique = values_in_types[v] == 1 and str(v) not in {
                            *m.variables,
                            *m.transitions,
                        }
                        name = str(v) if unique else f"{v}_{self.types[key].name}"
                        self.objs[key, v] = obj = Object(name, self.types[key])
                        problem.add_object(obj)
                self.var_fl[var.name] = fl = Fluent(var.name, BoolType(), v=self.types[key])
                problem.add_fluent(fl, default_initial_value=False)
            else:
                for v in var.domain:
                    self.val_fl[var.name, v] = fl = Fluent(f"{var.name}={v}", BoolType())
                    problem.add_fluent(fl, default_initial_value=False)

    def add_flag(self, name: str, initial: bool) -> str:
        """A bookkeeping boolean fluent (not a model variable); returns its name."""
        self.bool_fl[name] = fl = Fluent(name, BoolType())
        self.problem.add_fluent(fl, default_initial_value=initial)
        return name

    def atom(self, var: str, value: Value) -> upm.FNode:
        """UP expression for ``var == value``."""
        if var in self.bool_fl:
            return self.bool_fl[var]() if value else Not(self.bool_fl[var]())
        if self.encoding == "typed":
            return self.var_fl[var](self.obj(var, value))
        return self.val_fl[var, value]()

    def obj(self, var: str, value: Value) -> upm.Object:
        return self.objs[frozenset(self.m.variables[var].domain), value]

    def expr(self, e: Expr) -> upm.FNode:
        if isinstance(e, Const):
            return TRUE() if e.value else FALSE()
        if isinstance(e, Lit):
            return self.atom(e.var, e.value)
        if isinstance(e, VarEq):
            dom = self.m.variables[e.left].domain
            return Or(*(And(self.atom(e.left, v), self.atom(e.right, v)) for v in dom))
        if isinstance(e, NotE):
            return Not(self.expr(e.arg))
        if isinstance(e, AndE):
            return And(*(self.expr(a) for a in e.args))
        return Or(*(self.expr(a) for a in e.args))

    def initial(self, state: Mapping[str, Value]) -> None:
        for name, value in state.items():
            var = self.m.variables[name]
            if var.is_bool:
                self.problem.set_initial_value(self.bool_fl[name](), bool(value))
            else:
                self.problem.set_initial_value(self.atom(name, value), True)

    def pinned(self, t: Transition, known: Mapping[str, Value]) -> list[str]:
        """Assigned variables whose unknown old value the action must be split on, so that every
        delete effect is matched by a precondition (else Fast Downward, having found the
        variable's mutex group, emits a conditional effect, which LM-cut rejects): booleans set to
        false, and in the onehot encoding every finite-domain variable (typed uses ``?old``)."""
        return [
            x
            for x, v, copy in t.actions
            if x not in known
            and (
                (x in self.bool_fl and (copy or v is False))
                or (x not in self.bool_fl and self.encoding == "onehot")
            )
        ]

    def old_params(self, targets: Iterable[str], known: Mapping[str, Value]) -> dict[str, upm.Type]:
        """Typed encoding: an ``?old`` parameter per assigned variable whose value is unknown."""
        if self.encoding != "typed":
            return {}
        return {
            f"old_{i}": self.var_fl[x].signature[0].type
            for i, x in enumerate(targets)
            if x in self.var_fl and x not in known
        }

    def add_effects(
        self, a: InstantaneousAction, new: Mapping[str, Value], known: Mapping[str, Value]
    ) -> None:
        """``target := value`` for each item; deletes only the (known or ``?old``) old value."""
        for i, (target, value) in enumerate(new.items()):
            old = known.get(target)
            if old == value:
                continue
            if target in self.bool_fl:
                a.add_effect(self.bool_fl[target](), bool(value))
                continue
            if old is not None:
                a.add_effect(self.atom(target, old), False)
            else:  # typed: FD grounds ?old (precondition and delete)
                p = a.parameter(f"old_{i}")
                a.add_precondition(self.var_fl[target](p))
                a.add_effect(self.var_fl[target](p), False)
            a.add_effect(self.atom(target, value), True)


@dataclass(frozen=True)
class _Lazy:
    """A condition tracked by a fluent that is true only when the condition is known to hold."""

    flag: str
    cond: Expr
    is_spec: bool


def to_up_problem(
    model: Mapping[str, Any] | FlatModel,
    start: Mapping[str, object] | None,
    goal: str,
    supervisor_guards: Mapping[str, str] | None = None,
    maintenance: bool = False,
    *,
    encoding: str = "onehot",
    enforce_specifications: bool = False,
) -> Problem:
    """Build the UP problem whose minimal-cost plans are the model's minimal plans.

    ``supervisor_guards`` maps controlled/maintenance transition names to guard expressions.
    With ``enforce_specifications`` bad states are excluded directly instead (no supervisor
    guards needed, so this cross-checks them); with neither, invariants are ignored.  A bad start
    state gives an unsolvable problem.

    Conjunctions of negations over many transitions' guards or invariants (automatic priority,
    invariants regressed through an action) are multiplied out into DNF by Fast Downward,
    exponentially.  So each such condition c (``!guard`` of an automatic transition, each
    invariant) gets a fluent ``ok[c]``, true only when c is known to hold.  An action that assigns
    a variable of c sets ``ok[c]`` to whether c, regressed through its effects, is constantly
    true; a zero-cost action ``$check[c]`` (precondition c and the ``ok`` of every earlier
    condition, so checks run in one fixed order, invariants first) sets it.  Every real action
    needs all invariant ``ok``s (a bad state is a dead end), non-automatic ones also all
    automatic ``ok``s, and the goal all invariant ``ok``s.  Real actions cost 1 and checks 0, so
    the optimal cost is the minimal number of steps; :func:`transition_of` gives None for checks.
    """
    m = model if isinstance(model, FlatModel) else FlatModel.from_dict(model)
    sup = _supervisor_exprs(m, supervisor_guards)
    s0 = m.state(start)
    problem = Problem("sequence_planner")
    enc = _Encoder(m, encoding, problem)
    conds = [(f"spec:{n}", e, True) for n, e in m.specs.items() if enforce_specifications]
    conds += [
        (t.name, mk_not(t.guard), False) for t in m.transitions.values() if t.kind == "automatic"
    ]
    lazy = [_Lazy(enc.add_flag(f"ok[{n}]", evaluate(c, s0)), c, sp) for n, c, sp in conds]
    costs: dict[upm.Action, upm.FNode | int] = {}
    for i, c in enumerate(lazy):
        earlier = [Lit(e.flag, True) for e in lazy[:i]]
        pre = mk_and([c.cond, NotE(Lit(c.flag, True)), *earlier])
        if pre != F:
            a = InstantaneousAction(f"{CHECK_PREFIX}[{c.flag}]")
            a.add_precondition(enc.expr(pre))
            a.add_effect(enc.bool_fl[c.flag](), True)
            problem.add_action(a)
            costs[a] = 0
    specs_ok = mk_and(Lit(c.flag, True) for c in lazy if c.is_spec)
    all_ok = mk_and(Lit(c.flag, True) for c in lazy)
    for t in m.transitions.values():
        if t.kind == "maintenance" and not maintenance:
            continue
        g_known, g_excl = facts(t.guard)
        srcs = [y for y in t.sources() if y not in g_known]
        pins = list(dict.fromkeys(srcs + enc.pinned(t, g_known)))
        for vals in itertools.product(*(m.variables[y].domain for y in pins)):
            binding = dict(zip(pins, vals, strict=True))
            if any(v in g_excl.get(y, ()) for y, v in binding.items()):
                continue
            known = {**g_known, **binding}
            new = {x: (known[str(v)] if copy else v) for x, v, copy in t.actions}
            if all(known.get(x) == v for x, v in new.items()):
                continue  # changes nothing: never part of a minimal plan (and FD needs effects)
            conj = [partial(t.guard, binding), *(Lit(y, v) for y, v in binding.items())]
            conj.append(partial(sup.get(t.name, T), known, g_excl))
            conj.append(specs_ok if t.kind == "automatic" else all_ok)
            pre = mk_and(conj)
            if pre == F:
                continue
            suffix = ",".join(f"{y}={v}" for y, v in binding.items())
            a = InstantaneousAction(
                f"{t.name}[{suffix}]" if suffix else t.name,
                OrderedDict(enc.old_params(new, known)),
            )
            if pre != T:
                a.add_precondition(enc.expr(pre))
            enc.add_effects(a, new, known)
            changed = {x for x, v in new.items() if known.get(x) != v}
            for c in lazy:
                if variables(c.cond) & changed:
                    holds = partial(partial(c.cond, new), known, g_excl) == T
                    a.add_effect(enc.bool_fl[c.flag](), holds)
            problem.add_action(a)
    enc.initial(s0)
    problem.add_goal(FALSE() if m.is_bad(s0) else enc.expr(mk_and([m.parse(goal), specs_ok])))
    problem.add_quality_metric(MinimizeActionCosts(costs, default=1))
    return problem


def to_pddl(
    model: Mapping[str, Any] | FlatModel,
    start: Mapping[str, object] | None,
    goal: str,
    supervisor_guards: Mapping[str, str] | None = None,
    maintenance: bool = False,
    **kwargs: object,
) -> tuple[str, str]:
    """(domain, problem) PDDL text of :func:`to_up_problem`, written by UP's PDDLWriter."""
    problem = to_up_problem(model, start, goal, supervisor_guards, maintenance, **kwargs)  # type: ignore[arg-type]
    writer = PDDLWriter(problem)
    return writer.get_domain(), writer.get_problem()
