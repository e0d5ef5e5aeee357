"""Independent reference semantics ("oracle") for flat Sequence Planner models.

Written only from the design contract (section 8), deliberately sharing no code with
``planner/``, so that property tests comparing the two can catch bugs in either.
Everything is explicit-state and brute force: clarity over speed (fine up to ~5,000 states).
"""

from __future__ import annotations

import itertools
import re
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

State = tuple[object, ...]
Pred = Callable[[State], bool]
Update = Callable[[State], State]

TRANSITION_KINDS = ("controlled", "automatic", "effect", "maintenance")
UNCONTROLLABLE_KINDS = frozenset({"automatic", "effect"})
BOOL_DOMAIN: tuple[object, ...] = (False, True)

_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*\Z")
_WORD = r"[A-Za-z0-9_]+(?:\.[A-Za-z0-9_]+)*"
_TOKEN_RE = re.compile(r"->|&&|\|\||==|!=|!|\(|\)|" + _WORD)
_WORD_RE = re.compile(_WORD + r"\Z")
_ACTION_RE = re.compile(r"\s*(" + _WORD + r")\s*:=\s*(" + _WORD + r")\s*\Z")
_KEYWORDS = frozenset({"true", "false"})


@dataclass(frozen=True)
class Variable:
    """A finite-domain variable; bool domains are ``(False, True)``, others are strings."""

    name: str
    domain: tuple[object, ...]
    initial: object
    kind: str


@dataclass(frozen=True)
class Transition:
    """A guarded, deterministic transition; ``enabled``/``update`` are the compiled forms."""

    name: str
    kind: str
    guard: str
    actions: tuple[str, ...]
    enabled: Pred = field(compare=False, repr=False)
    update: Update = field(compare=False, repr=False)


@dataclass(frozen=True)
class Spec:
    """An invariant; a state where ``holds`` is false violates it."""

    name: str
    invariant: str
    holds: Pred = field(compare=False, repr=False)


@dataclass(frozen=True)
class OracleModel:
    """A parsed flat model plus memo tables (the model is immutable, so caching is safe)."""

    variables: tuple[Variable, ...]
    transitions: tuple[Transition, ...]
    specs: tuple[Spec, ...]
    index: Mapping[str, int] = field(compare=False, repr=False)
    _exprs: dict[str, Pred] = field(default_factory=dict, compare=False, repr=False)
    _bad: dict[str | None, frozenset[State]] = field(
        default_factory=dict, compare=False, repr=False
    )
    _unc_preds: dict[State, list[State]] = field(default_factory=dict, compare=False, repr=False)
    _flags: dict[str, bool] = field(default_factory=dict, compare=False, repr=False)


@dataclass(frozen=True)
class OracleResult:
    """Outcome of a planning query: status, minimal plan length if found, violated names."""

    status: str  # "found" | "unreachable" | "bad_start"
    length: int | None
    violated: list[str] = field(default_factory=list)
    maintenance_steps: int | None = None  # with ``maintenance_cost`` > 1: how many it takes


# --------------------------------------------------------------------------- expressions


def _tokenize(text: str) -> list[str]:
    """Split an expression into operator and word tokens; reject any other character."""
    tokens: list[str] = []
    pos = 0
    while pos < len(text):
        if text[pos].isspace():
            pos += 1
            continue
        match = _TOKEN_RE.match(text, pos)
        if match is None:
            raise ValueError(f"unexpected character {text[pos]!r} at {pos} in {text!r}")
        tokens.append(match.group(0))
        pos = match.end()
    return tokens


def _is_bool(domain: tuple[object, ...]) -> bool:
    return domain == BOOL_DOMAIN


def _resolve(
    variables: tuple[Variable, ...], index: Mapping[str, int], left: int, word: str, ctx: str
) -> tuple[int, object]:
    """Resolve the right-hand word of ``x == w`` / ``x := w``: (var index, None) or (-1, value).

    The contract says a word is a variable if one has that name, else a value of x's domain.
    """
    domain = variables[left].domain
    if word in index:
        j = index[word]
        if set(variables[j].domain) != set(domain):
            raise ValueError(f"{ctx}: {variables[left].name} and {word} have different domains")
        return j, None
    if _is_bool(domain):
        if word in _KEYWORDS:
            return -1, word == "true"
    elif word in domain:
        return -1, word
    raise ValueError(f"{ctx}: {word!r} is not a value of {variables[left].name}")


def _not(a: Pred) -> Pred:
    return lambda s: not a(s)


def _and(a: Pred, b: Pred) -> Pred:
    return lambda s: a(s) and b(s)


def _or(a: Pred, b: Pred) -> Pred:
    return lambda s: a(s) or b(s)


def _implies(a: Pred, b: Pred) -> Pred:
    return lambda s: (not a(s)) or b(s)


def _const(value: bool) -> Pred:
    return lambda s: value


def _var_true(i: int) -> Pred:
    return lambda s: s[i] is True


def _eq_const(i: int, value: object, negate: bool) -> Pred:
    if negate:
        return lambda s: s[i] != value
    return lambda s: s[i] == value


def _eq_var(i: int, j: int, negate: bool) -> Pred:
    if negate:
        return lambda s: s[i] != s[j]
    return lambda s: s[i] == s[j]


class _Parser:
    """Recursive descent: impl := or ['->' impl]; or := and {'||' and}; and := un {'&&' un};
    un := '!' un | atom; atom := '(' impl ')' | true | false | var [('=='|'!=') word].

    Comparisons are atoms, so ``!x == v`` means ``!(x == v)`` (for bools both readings agree).
    """

    def __init__(self, variables: tuple[Variable, ...], index: Mapping[str, int], text: str):
        self.variables = variables
        self.index = index
        self.text = text
        self.tokens = _tokenize(text)
        self.pos = 0

    def parse(self) -> Pred:
        if not self.tokens:
            raise ValueError("empty expression")
        result = self._impl()
        if self.pos != len(self.tokens):
            raise ValueError(f"unexpected {self.tokens[self.pos]!r} in {self.text!r}")
        return result

    def _peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def _accept(self, tok: str) -> bool:
        if self._peek() == tok:
            self.pos += 1
            return True
        return False

    def _word(self) -> str:
        tok = self._peek()
        if tok is None or _WORD_RE.match(tok) is None:
            raise ValueError(f"expected a name or value at token {self.pos} in {self.text!r}")
        self.pos += 1
        return tok

    def _impl(self) -> Pred:
        left = self._or()
        if self._accept("->"):
            return _implies(left, self._impl())
        return left

    def _or(self) -> Pred:
        result = self._and()
        while self._accept("||"):
            result = _or(result, self._and())
        return result

    def _and(self) -> Pred:
        result = self._unary()
        while self._accept("&&"):
            result = _and(result, self._unary())
        return result

    def _unary(self) -> Pred:
        if self._accept("!"):
            return _not(self._unary())
        return self._atom()

    def _atom(self) -> Pred:
        if self._accept("("):
            inner = self._impl()
            if not self._accept(")"):
                raise ValueError(f"missing ')' in {self.text!r}")
            return inner
        word = self._word()
        if word in _KEYWORDS:
            return _const(word == "true")
        if word not in self.index:
            raise ValueError(f"unknown variable {word!r} in {self.text!r}")
        i = self.index[word]
        op = self._peek()
        if op in ("==", "!="):
            self.pos += 1
            j, value = _resolve(self.variables, self.index, i, self._word(), repr(self.text))
            negate = op == "!="
            return _eq_var(i, j, negate) if j >= 0 else _eq_const(i, value, negate)
        if not _is_bool(self.variables[i].domain):
            raise ValueError(f"non-boolean variable {word!r} used as a condition in {self.text!r}")
        return _var_true(i)


def _compile_expr(variables: tuple[Variable, ...], index: Mapping[str, int], text: object) -> Pred:
    """Compile an expression (YAML may hand us a bare bool for ``true``/``false``)."""
    if isinstance(text, bool):
        return _const(text)
    if not isinstance(text, str):
        raise ValueError(f"expression must be a string, got {text!r}")
    return _Parser(variables, index, text).parse()


def _compile_actions(
    variables: tuple[Variable, ...], index: Mapping[str, int], actions: tuple[str, ...], ctx: str
) -> Update:
    """Compile simultaneous assignments: every right-hand side reads the pre-state."""
    assigns: list[tuple[int, int, object]] = []
    targets: set[int] = set()
    for action in actions:
        match = _ACTION_RE.match(action)
        if match is None:
            raise ValueError(f"{ctx}: malformed action {action!r}")
        target, source = match.group(1), match.group(2)
        if target not in index:
            raise ValueError(f"{ctx}: unknown variable {target!r} in action {action!r}")
        t = index[target]
        if t in targets:
            raise ValueError(f"{ctx}: variable {target!r} assigned twice")
        targets.add(t)
        j, value = _resolve(variables, index, t, source, ctx)
        assigns.append((t, j, value))
    frozen = tuple(assigns)

    def update(s: State) -> State:
        new = list(s)
        for t, j, value in frozen:
            new[t] = s[j] if j >= 0 else value
        return tuple(new)

    return update


# --------------------------------------------------------------------------- model parsing


def _scalar(value: object, ctx: str) -> str:
    """Enum values are strings; YAML ints (and 1.1 bools like ``on``) map to their text."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (str, int, float)):
        return str(value)
    raise ValueError(f"{ctx}: value {value!r} is not a scalar")


def _name(entry: Mapping[str, Any], ctx: str) -> str:
    name = entry.get("name")
    if not isinstance(name, str) or _NAME_RE.match(name) is None or name in _KEYWORDS:
        raise ValueError(f"{ctx}: bad or missing name {name!r}")
    return name


def _entries(d: Mapping[str, Any], key: str) -> list[Mapping[str, Any]]:
    raw = d.get(key)
    if raw is None:
        return []
    if not isinstance(raw, list) or not all(isinstance(e, Mapping) for e in raw):
        raise ValueError(f"{key} must be a list of mappings")
    return raw


def _parse_variable(entry: Mapping[str, Any]) -> Variable:
    name = _name(entry, "variable")
    raw_domain = entry.get("domain")
    domain: tuple[object, ...]
    if raw_domain == "bool":
        domain = BOOL_DOMAIN
    elif isinstance(raw_domain, list) and raw_domain:
        domain = tuple(_scalar(v, name) for v in raw_domain)
        if len(set(domain)) != len(domain):
            raise ValueError(f"{name}: duplicate domain values")
    else:
        raise ValueError(f"{name}: domain must be 'bool' or a non-empty list")
    initial: object
    if "initial" not in entry or entry["initial"] is None:
        initial = domain[0]
    elif _is_bool(domain):
        raw = entry["initial"]
        initial = raw if isinstance(raw, bool) else {"true": True, "false": False}.get(str(raw))
    else:
        initial = _scalar(entry["initial"], name)
    if initial not in domain or (_is_bool(domain) and not isinstance(initial, bool)):
        raise ValueError(f"{name}: initial value {entry.get('initial')!r} not in domain")
    kind = entry.get("kind", "estimated")
    if not isinstance(kind, str) or not kind:
        raise ValueError(f"{name}: bad kind {kind!r}")
    return Variable(name, domain, initial, kind)


def _unique(names: list[str], what: str) -> None:
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ValueError(f"duplicate {what} names: {dupes}")


def parse_model(d: dict[str, Any]) -> OracleModel:
    """Parse and validate the flat-model dict; ``ValueError`` explains the first problem."""
    if not isinstance(d, Mapping):
        raise ValueError("model must be a mapping")
    variables = tuple(_parse_variable(e) for e in _entries(d, "variables"))
    _unique([v.name for v in variables], "variable")
    index = {v.name: i for i, v in enumerate(variables)}

    transitions: list[Transition] = []
    for entry in _entries(d, "transitions"):
        name = _name(entry, "transition")
        kind = entry.get("kind", "controlled")
        if kind not in TRANSITION_KINDS:
            raise ValueError(f"{name}: unknown transition kind {kind!r}")
        guard_src = entry.get("guard", "true")
        guard = _compile_expr(variables, index, guard_src)
        raw_actions = entry.get("actions") or []
        if not isinstance(raw_actions, list) or not all(isinstance(a, str) for a in raw_actions):
            raise ValueError(f"{name}: actions must be a list of strings")
        actions = tuple(raw_actions)
        update = _compile_actions(variables, index, actions, name)
        transitions.append(Transition(name, kind, str(guard_src), actions, guard, update))
    _unique([t.name for t in transitions], "transition")

    specs: list[Spec] = []
    for entry in _entries(d, "specifications"):
        name = _name(entry, "specification")
        if "invariant" not in entry:
            raise ValueError(f"{name}: missing invariant")
        holds = _compile_expr(variables, index, entry["invariant"])
        specs.append(Spec(name, str(entry["invariant"]), holds))
    _unique([s.name for s in specs], "specification")
    return OracleModel(variables, tuple(transitions), tuple(specs), index)


# --------------------------------------------------------------------------- states


def initial_state(m: OracleModel) -> State:
    """The state made of every variable's initial value."""
    return tuple(v.initial for v in m.variables)


def state_from_dict(m: OracleModel, values: dict[str, object]) -> State:
    """Build a state from a full name->value assignment (ints/bools as in YAML accepted)."""
    unknown = sorted(set(values) - set(m.index))
    missing = [v.name for v in m.variables if v.name not in values]
    if unknown or missing:
        raise ValueError(f"state: unknown {unknown}, missing {missing}")
    out: list[object] = []
    for v in m.variables:
        raw = values[v.name]
        value: object
        if _is_bool(v.domain):
            value = raw if isinstance(raw, bool) else {"true": True, "false": False}.get(str(raw))
        else:
            value = _scalar(raw, v.name)
        if value is None or value not in v.domain:
            raise ValueError(f"state: {raw!r} is not a value of {v.name}")
        out.append(value)
    return tuple(out)


def state_to_dict(m: OracleModel, s: State) -> dict[str, object]:
    """Name->value view of a state."""
    return {v.name: s[i] for i, v in enumerate(m.variables)}


def all_states(m: OracleModel) -> Iterator[State]:
    """Every state: the product of the domains in variable order."""
    return itertools.product(*(v.domain for v in m.variables))


def _check_state(m: OracleModel, s: State) -> None:
    if len(s) != len(m.variables) or any(
        x not in v.domain or type(x) is not type(v.domain[0])
        for x, v in zip(s, m.variables, strict=True)
    ):
        raise ValueError(f"not a state of this model: {s!r}")


def _pred(m: OracleModel, expr: str) -> Pred:
    """Compile once per model and expression text."""
    cached = m._exprs.get(expr)
    if cached is None:
        cached = _compile_expr(m.variables, m.index, expr)
        m._exprs[expr] = cached
    return cached


def evaluate(m: OracleModel, expr: str, s: State) -> bool:
    """Truth value of ``expr`` in state ``s``."""
    return _pred(m, expr)(s)


# --------------------------------------------------------------------------- steps


def _check_disabled(m: OracleModel, disabled: frozenset[str]) -> None:
    unknown = sorted(disabled - {t.name for t in m.transitions})
    if unknown:
        raise ValueError(f"disabled names unknown transitions: {unknown}")


def _steps(
    m: OracleModel, s: State, maintenance: bool, disabled: frozenset[str]
) -> list[tuple[Transition, State]]:
    """Enabled automatic transitions pre-empt everything else; disabled ones do not exist."""
    enabled = [t for t in m.transitions if t.name not in disabled and t.enabled(s)]
    auto = [t for t in enabled if t.kind == "automatic"]
    if auto:
        chosen = auto
    else:
        allowed = {"controlled", "effect"} | ({"maintenance"} if maintenance else set())
        chosen = [t for t in enabled if t.kind in allowed]
    return [(t, t.update(s)) for t in chosen]


def steps(
    m: OracleModel, s: State, *, maintenance: bool, disabled: frozenset[str] = frozenset()
) -> list[tuple[str, State]]:
    """Possible steps from ``s`` as (transition name, successor), in transition order."""
    return [(t.name, t2) for t, t2 in _steps(m, s, maintenance, disabled)]


# --------------------------------------------------------------------------- bad states


def _uncontrollable_predecessors(m: OracleModel) -> dict[State, list[State]]:
    """Reverse graph of automatic/effect steps over all states (full model, no query)."""
    if "unc_built" not in m._flags:
        for s in all_states(m):
            for t, succ in _steps(m, s, maintenance=False, disabled=frozenset()):
                if t.kind in UNCONTROLLABLE_KINDS:
                    m._unc_preds.setdefault(succ, []).append(s)
        m._flags["unc_built"] = True
    return m._unc_preds


def _backward_closure(m: OracleModel, specs: tuple[Spec, ...]) -> frozenset[State]:
    """States violating one of ``specs`` plus all that reach one by uncontrollable steps."""
    preds = _uncontrollable_predecessors(m)
    bad = {s for s in all_states(m) if not all(sp.holds(s) for sp in specs)}
    queue = deque(bad)
    while queue:
        for p in preds.get(queue.popleft(), ()):
            if p not in bad:
                bad.add(p)
                queue.append(p)
    return frozenset(bad)


def bad_states(m: OracleModel) -> frozenset[State]:
    """All bad states of the model (a model property, independent of any query)."""
    if None not in m._bad:
        m._bad[None] = _backward_closure(m, m.specs)
    return m._bad[None]


def bad_for_spec(m: OracleModel, spec_name: str) -> frozenset[State]:
    """Bad states when only the named specification is considered."""
    if spec_name not in m._bad:
        chosen = tuple(sp for sp in m.specs if sp.name == spec_name)
        if not chosen:
            raise ValueError(f"unknown specification {spec_name!r}")
        m._bad[spec_name] = _backward_closure(m, chosen)
    return m._bad[spec_name]


def breaking(m: OracleModel, kept: str) -> frozenset[State]:
    """States where ``kept`` is false or from which uncontrollable steps make it false (the
    states a plan that keeps it avoids, ``PlanQuery.kept``): exact, over the whole model."""
    key = f"kept: {kept}"
    if key not in m._bad:
        m._bad[key] = _backward_closure(m, (Spec(key, kept, _pred(m, kept)),))
    return m._bad[key]


def violated(m: OracleModel, s: State) -> list[str]:
    """Sorted names of the specs that, each on its own, make ``s`` bad."""
    return sorted(sp.name for sp in m.specs if s in bad_for_spec(m, sp.name))


def has_automatic_cycle(m: OracleModel) -> bool:
    """True iff some state has an infinite run of automatic steps (self-loops count).

    Repeatedly peel states without remaining automatic successors; anything left lies
    on or leads into a cycle.
    """
    if "auto_cycle" in m._flags:
        return m._flags["auto_cycle"]
    out_degree: dict[State, int] = {}
    preds: dict[State, list[State]] = {}
    for s in all_states(m):
        succs = [t2 for t, t2 in _steps(m, s, False, frozenset()) if t.kind == "automatic"]
        out_degree[s] = len(succs)
        for t2 in succs:
            preds.setdefault(t2, []).append(s)
    queue = deque(s for s, n in out_degree.items() if n == 0)
    removed = 0
    while queue:
        t2 = queue.popleft()
        removed += 1
        for p in preds.get(t2, ()):
            out_degree[p] -= 1
            if out_degree[p] == 0:
                queue.append(p)
    result = removed != len(out_degree)
    m._flags["auto_cycle"] = result
    return result


# --------------------------------------------------------------------------- planning


def _start_violations(m: OracleModel, s: State, forbidden: list[Pred]) -> list[str]:
    """Spec names (sorted) making ``s`` bad, then ``forbidden[i]`` names in index order."""
    return violated(m, s) + [f"forbidden[{i}]" for i, f in enumerate(forbidden) if f(s)]


@dataclass(frozen=True)
class _Rules:
    """What a query lets a plan do, as predicates on single states.

    Without ``relaxed``: every state is neither bad nor forbidden, the last satisfies the
    goal.  With ``relaxed`` (forbidden-state recovery, PlanQuery's docstring): the named
    specifications are dropped, and so is every specification the start is already bad for;
    every state is bad for none of the others (their closure over uncontrollable steps, the
    supervisor of the kept specifications) and not forbidden, and the last state satisfies
    the goal and is good (bad for no specification at all).
    """

    allowed: Pred
    accepts: Pred  # the goal, for the last state
    reasons: Callable[[State], list[str]]  # why a start state is not allowed


def _rules(
    m: OracleModel, goal: str, forbidden: tuple[str, ...], relaxed: frozenset[str], start: State
) -> _Rules:
    unknown = sorted(relaxed - {sp.name for sp in m.specs})
    if unknown:
        raise ValueError(f"relaxed names unknown specifications: {unknown}")
    goal_p = _pred(m, goal)
    forb = [_pred(m, f) for f in forbidden]
    bad = bad_states(m)
    if not relaxed:
        return _Rules(
            lambda s: s not in bad and not any(f(s) for f in forb),
            goal_p,
            lambda s: _start_violations(m, s, forb),
        )
    closures = {sp.name: bad_for_spec(m, sp.name) for sp in m.specs}
    dropped = relaxed | {name for name, states in closures.items() if start in states}
    kept = [(name, states) for name, states in closures.items() if name not in dropped]

    def reasons(s: State) -> list[str]:
        why = sorted(name for name, states in kept if s in states)
        return why + [f"forbidden[{i}]" for i, f in enumerate(forb) if f(s)]

    return _Rules(
        lambda s: all(s not in states for _, states in kept) and not any(f(s) for f in forb),
        lambda s: goal_p(s) and s not in bad,
        reasons,
    )


def _keeping(m: OracleModel, rules: _Rules, kept: tuple[str, ...]) -> _Rules:
    """``rules`` that also avoid the states breaking each of ``kept`` (``kept[i]``)."""
    if not kept:
        return rules
    broken = [breaking(m, k) for k in kept]

    def reasons(s: State) -> list[str]:
        return rules.reasons(s) + [f"kept[{i}]" for i, b in enumerate(broken) if s in b]

    return _Rules(
        lambda s: rules.allowed(s) and not any(s in b for b in broken), rules.accepts, reasons
    )


def plan(
    m: OracleModel,
    start: State,
    goal: str,
    *,
    max_steps: int,
    maintenance: bool = False,
    forbidden: tuple[str, ...] = (),
    phi: str | None = None,
    disabled: frozenset[str] = frozenset(),
    relaxed: frozenset[str] = frozenset(),
    maintenance_cost: int = 1,
    kept: tuple[str, ...] = (),
) -> OracleResult:
    """Breadth-first search for a minimal plan of at most ``max_steps`` steps.

    Plain BFS over states is exact because every constraint (allowed, phi before the end,
    goal at the end) depends on the current state only.  With ``maintenance_cost`` c > 1
    (and ``maintenance``) the plan has the least cost, a maintenance step costing c and any
    other 1, ties broken by fewer maintenance steps, then fewer steps: BFS over (state,
    maintenance steps so far) pairs, exact for the same reason, gives each pair's fewest
    steps, and the cheapest goal pair wins (``maintenance_steps``).
    """
    _check_state(m, start)
    _check_disabled(m, disabled)
    if max_steps < 0:
        raise ValueError("max_steps must be >= 0")
    rules = _keeping(m, _rules(m, goal, forbidden, relaxed, start), kept)
    phi_p = _pred(m, phi) if phi is not None else None
    counting = maintenance_cost > 1 and maintenance
    kinds = {t.name: t.kind for t in m.transitions}

    if not rules.allowed(start):
        return OracleResult("bad_start", None, rules.reasons(start))
    if rules.accepts(start):
        return OracleResult("found", 0, [], 0 if counting else None)

    # a node is (state, maintenance steps taken); without counting the count stays 0
    first_hit: dict[int, int] = {}  # count -> least depth where a goal state has it
    frontier = [(start, 0)]
    seen = {(start, 0)}
    for depth in range(1, max_steps + 1):
        next_frontier: list[tuple[State, int]] = []
        for s, count in frontier:
            if phi_p is not None and not phi_p(s):
                continue  # may only be the last state of a plan, and it is not a goal
            for name, succ in steps(m, s, maintenance=maintenance, disabled=disabled):
                node = (succ, count + (counting and kinds[name] == "maintenance"))
                if node in seen or not rules.allowed(succ):
                    continue
                seen.add(node)
                if rules.accepts(succ):
                    first_hit.setdefault(node[1], depth)
                    continue  # a plan may stop here; going on only costs more
                next_frontier.append(node)
        if first_hit and not counting:
            return OracleResult("found", first_hit[0], [])
        frontier = next_frontier
        if not frontier:
            break
    if not first_hit:
        return OracleResult("unreachable", None, [])
    cheapest = min(first_hit, key=lambda k: (first_hit[k] + (maintenance_cost - 1) * k, k))
    return OracleResult("found", first_hit[cheapest], [], cheapest if counting else None)


def replay(
    m: OracleModel,
    start: State,
    plan: list[str],
    goal: str,
    *,
    maintenance: bool = False,
    forbidden: tuple[str, ...] = (),
    phi: str | None = None,
    disabled: frozenset[str] = frozenset(),
    relaxed: frozenset[str] = frozenset(),
) -> str | None:
    """Check a concrete plan against the semantics; ``None`` if legal, else why not."""
    _check_state(m, start)
    _check_disabled(m, disabled)
    rules = _rules(m, goal, forbidden, relaxed, start)
    phi_p = _pred(m, phi) if phi is not None else None

    if not rules.allowed(start):
        return f"start state is bad or forbidden: {rules.reasons(start)}"
    s = start
    for i, name in enumerate(plan):
        if phi_p is not None and not phi_p(s):
            return f"step {i} ({name}): phi {phi!r} does not hold in the state before it"
        possible = dict(steps(m, s, maintenance=maintenance, disabled=disabled))
        if name not in possible:
            return (
                f"step {i} ({name}): not a possible step in {state_to_dict(m, s)}; "
                f"possible: {sorted(possible)}"
            )
        s = possible[name]
        if not rules.allowed(s):
            return (
                f"step {i} ({name}): reaches bad or forbidden state {state_to_dict(m, s)} "
                f"{rules.reasons(s) or violated(m, s)}"
            )
    if not rules.accepts(s):
        extra = " and be good" if relaxed else ""
        return f"final state {state_to_dict(m, s)} does not satisfy goal {goal!r}{extra}"
    return None


def maintenance_steps(m: OracleModel, plan: Iterable[str]) -> int:
    """How many steps of a plan are maintenance transitions."""
    kinds = {t.name: t.kind for t in m.transitions}
    return sum(kinds[name] == "maintenance" for name in plan)
