"""Minimal plans by incremental SAT bounded model checking (seed 000 sec. 4.2, seed 003 III-B).

The papers' method, kept as the baseline engine and tested against the same oracle as the
symbolic search.  One CaDiCaL instance per query, unrolled k = 0, 1, 2 ...: the goal at
step k is an assumption, so the first satisfiable k is the minimal plan length and every
clause learnt for shorter k is kept.  Encoding: the same log-encoded bits as the BDDs; one
selector per transition and step with exactly-one (sequential counter); frame axioms that
only let a variable change when a transition writing it is selected; automatic priority as
"a non-automatic selector implies no automatic guard holds"; the bad states (a BDD) as a
Tseitin-encoded circuit forbidden at every step.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

from pysat.solvers import Cadical195

from planner.bdd.symbolic import Function, SymbolicModel, SymbolicTransition
from planner.bdd.synthesis import breaking
from planner.model.expressions import And, BoolVar, Const, Equals, Expr, Implies, Not, Or, SameValue
from planner.model.flat import TransitionKind
from planner.planning.query import PlanQuery, PlanResult, PlanStatus, State


@dataclass(frozen=True, slots=True)
class _Gate:
    """One BDD node as `out <-> ite(bit, high, low)`; ids < 0 are negations, 0/1 constants."""

    bit: str
    high: int
    low: int


class BddCircuit:
    """A BDD flattened into if-then-else gates once, to be instantiated at every step."""

    FALSE = 0
    TRUE = 1

    def __init__(self, sym: SymbolicModel, root: Function) -> None:
        self.gates: list[_Gate] = []  # gate i has id i + 2
        self._ids: dict[Function, int] = {}
        self.root = self._flatten(sym, root)

    def _flatten(self, sym: SymbolicModel, root: Function) -> int:
        """The gate of `root`, its children's gates made first; iterative, since a BDD over
        thousands of bits is deeper than Python's recursion limit."""
        stack = [root]
        while stack:
            node = stack[-1]
            if self._known(sym, node) is not None:
                stack.pop()
                continue
            if node.negated:  # CUDD children are those of the regular node
                regular = self._known(sym, ~node)
                if regular is None:
                    stack.append(~node)
                    continue
                self._ids[node] = -regular
            else:
                high, low = self._known(sym, node.high), self._known(sym, node.low)
                if high is None or low is None:
                    stack += [c for c, k in ((node.low, low), (node.high, high)) if k is None]
                    continue
                self.gates.append(_Gate(node.var, high, low))
                self._ids[node] = len(self.gates) + 1
            stack.pop()
        known = self._known(sym, root)
        assert known is not None
        return known

    def _known(self, sym: SymbolicModel, node: Function) -> int | None:
        if node == sym.true:
            return self.TRUE
        if node == sym.false:
            return self.FALSE
        return self._ids.get(node)


class _Encoding:
    """Clauses over steps 0..k, with Tseitin literals cached per (expression, step)."""

    def __init__(self, sym: SymbolicModel, solver: Cadical195) -> None:
        self.sym = sym
        self.solver = solver
        self.top = 0
        self.true = self.new()
        solver.add_clause([self.true])
        self.bits: list[dict[str, int]] = []
        self._cache: dict[tuple[Expr, int], int] = {}

    def new(self) -> int:
        self.top += 1
        return self.top

    def add(self, clause: list[int]) -> None:
        self.solver.add_clause(clause)

    def add_state(self) -> int:
        step = len(self.bits)
        self.bits.append({bit: self.new() for bit in self.sym.state_bits})
        return step

    def conjoin(self, lits: list[int]) -> int:
        lits = [lit for lit in lits if lit != self.true]
        if not lits:
            return self.true
        if -self.true in lits:
            return -self.true
        if len(lits) == 1:
            return lits[0]
        out = self.new()
        for lit in lits:
            self.add([-out, lit])
        self.add([out, *(-lit for lit in lits)])
        return out

    def disjoin(self, lits: list[int]) -> int:
        return -self.conjoin([-lit for lit in lits])

    def equal_value(self, variable: str, value: object, step: int) -> int:
        code = self.sym.code(variable, value)  # type: ignore[arg-type]
        bits = self.bits[step]
        return self.conjoin([bits[b] if v else -bits[b] for b, v in code.items()])

    def same_value(self, left: str, right: str, step: int) -> int:
        bits = self.bits[step]
        parts = []
        for a, b in zip(self.sym.bits[left], self.sym.bits[right], strict=True):
            same = self.new()  # same <-> (a <-> b)
            x, y = bits[a], bits[b]
            self.add([-same, -x, y])
            self.add([-same, x, -y])
            self.add([same, x, y])
            self.add([same, -x, -y])
            parts.append(same)
        return self.conjoin(parts)

    def lit(self, expr: Expr, step: int) -> int:
        key = (expr, step)
        cached = self._cache.get(key)
        if cached is not None:
            return cached
        match expr:
            case Const(value):
                result = self.true if value else -self.true
            case BoolVar(name):
                result = self.bits[step][self.sym.bits[name][0]]
            case Equals(name, value):
                result = self.equal_value(name, value, step)
            case SameValue(left, right):
                result = self.same_value(left, right, step)
            case Not(arg):
                result = -self.lit(arg, step)
            case And(args):
                result = self.conjoin([self.lit(a, step) for a in args])
            case Or(args):
                result = self.disjoin([self.lit(a, step) for a in args])
            case Implies(left, right):
                result = self.disjoin([-self.lit(left, step), self.lit(right, step)])
            case _:
                raise TypeError(expr)
        self._cache[key] = result
        return result

    def circuit(self, circuit: BddCircuit, step: int) -> int:
        """A literal true exactly when the state at `step` is in the circuit's set."""
        bits = self.bits[step]
        ids: list[int] = []

        def lit_of(ref: int) -> int:
            if ref in (BddCircuit.TRUE, -BddCircuit.TRUE):
                return self.true if ref > 0 else -self.true
            if ref == BddCircuit.FALSE:
                return -self.true
            gate_lit = ids[abs(ref) - 2]
            return gate_lit if ref > 0 else -gate_lit

        for gate in circuit.gates:
            out, v = self.new(), bits[gate.bit]
            high, low = lit_of(gate.high), lit_of(gate.low)
            self.add([-out, -v, high])
            self.add([-out, v, low])
            self.add([out, -v, -high])
            self.add([out, v, -low])
            ids.append(out)
        return lit_of(circuit.root)


class BoundedModelChecker:
    name = "sat"

    def __init__(self, sym: SymbolicModel, bad: Function) -> None:
        self.sym = sym
        self.bad_circuit = BddCircuit(sym, bad)
        self._breaking: dict[Expr, BddCircuit] = {}

    def breaking(self, predicate: Expr) -> BddCircuit:
        """Where `predicate` (kept) can be broken, as a circuit (`synthesis.breaking`)."""
        found = self._breaking.get(predicate)
        if found is None:
            found = self._breaking[predicate] = BddCircuit(self.sym, breaking(self.sym, predicate))
        return found

    def plan(self, query: PlanQuery) -> PlanResult:
        if query.relaxed:
            raise ValueError(
                "forbidden-state recovery (relaxed specifications) needs the bdd engine"
            )
        if query.maintenance and query.maintenance_cost > 1:
            raise ValueError("weighing maintenance steps (maintenance_cost) needs the bdd engine")
        sym = self.sym
        usable = [
            t
            for t in sym.transitions
            if t.name not in query.disabled
            and (query.maintenance or t.kind is not TransitionKind.MAINTENANCE)
        ]
        with Cadical195() as solver:
            enc = _Encoding(sym, solver)
            step = enc.add_state()
            for bit, value in self._code(query.start).items():
                enc.add([enc.bits[0][bit] if value else -enc.bits[0][bit]])
            if not self._constrain_state(enc, query, step):
                return PlanResult(PlanStatus.BAD_START, max_steps=query.max_steps, engine=self.name)
            selectors: list[dict[str, int]] = []
            while True:
                goal = enc.lit(query.goal, step)
                if solver.solve(assumptions=[goal]):
                    model = set(lit for lit in solver.get_model() if lit > 0)
                    return self._result(enc, model, selectors, query)
                if step >= query.max_steps:
                    return PlanResult(
                        PlanStatus.UNREACHABLE, max_steps=query.max_steps, engine=self.name
                    )
                if query.always is not None:
                    enc.add([enc.lit(query.always, step)])
                selectors.append(self._add_step(enc, usable, step))
                step += 1
                self._constrain_state(enc, query, step)

    def _code(self, state: State) -> dict[str, bool]:
        code: dict[str, bool] = {}
        for variable, value in zip(self.sym.model.variables, state, strict=True):
            code.update(self.sym.code(variable.name, value))
        return code

    def _constrain_state(self, enc: _Encoding, query: PlanQuery, step: int) -> bool:
        """The state at `step` is neither bad nor forbidden; False if that is impossible."""
        ok = True
        for lit in [
            -enc.circuit(self.bad_circuit, step),
            *(-enc.lit(f, step) for f in query.forbidden),
            *(-enc.circuit(self.breaking(k), step) for k in query.kept),
        ]:
            enc.add([lit])
            if step == 0 and lit == -enc.true:
                ok = False
        if step == 0 and ok:
            ok = bool(enc.solver.solve())
        return ok

    def _add_step(
        self, enc: _Encoding, usable: list[SymbolicTransition], step: int
    ) -> dict[str, int]:
        """The state `step + 1` and the transition selectors into it, exactly one true."""
        sym = self.sym
        before = enc.bits[step]
        after = enc.bits[enc.add_state()]
        selectors = {t.name: enc.new() for t in usable}
        automatic = enc.new()  # some automatic guard holds at `step`
        writers: dict[str, list[int]] = {bit: [] for bit in sym.state_bits}
        for t in usable:
            chosen = selectors[t.name]
            enc.add([-chosen, enc.lit(t.transition.guard, step)])
            if t.kind is TransitionKind.AUTOMATIC:
                enc.add([-enc.lit(t.transition.guard, step), automatic])
            else:
                enc.add([-chosen, -automatic])
            for action in t.transition.actions:
                targets = sym.bits[action.target]
                for bit in targets:
                    writers[bit].append(chosen)
                if action.source is None:
                    for bit, value in sym.code(action.target, action.value).items():  # type: ignore[arg-type]
                        enc.add([-chosen, after[bit] if value else -after[bit]])
                else:
                    for a, b in zip(targets, sym.bits[action.source], strict=True):
                        enc.add([-chosen, -after[a], before[b]])
                        enc.add([-chosen, after[a], -before[b]])
        for bit in sym.state_bits:  # frame: a bit changes only if a writer is selected
            enc.add([-after[bit], before[bit], *writers[bit]])
            enc.add([after[bit], -before[bit], *writers[bit]])
        lits = list(selectors.values())
        enc.add(lits)
        for clause in _at_most_one(lits, enc.new):
            enc.add(clause)
        return selectors

    def _result(
        self,
        enc: _Encoding,
        model: set[int],
        selectors: list[dict[str, int]],
        query: PlanQuery,
    ) -> PlanResult:
        plan = []
        for chosen in selectors:
            names = [name for name, lit in chosen.items() if lit in model]
            assert len(names) == 1, names
            plan.append(names[0])
        states = tuple(
            self.sym.decode({bit: lit in model for bit, lit in bits.items()}) for bits in enc.bits
        )
        return PlanResult(
            PlanStatus.FOUND, tuple(plan), states, max_steps=query.max_steps, engine=self.name
        )


def _at_most_one(lits: list[int], new: Callable[[], int]) -> Iterator[list[int]]:
    """Sequential-counter at-most-one: 3n clauses instead of n^2/2."""
    if len(lits) <= 4:
        for i in range(len(lits)):
            for j in range(i + 1, len(lits)):
                yield [-lits[i], -lits[j]]
        return
    prefix = new()  # prefix_i: some of lits[0..i] is true
    yield [-lits[0], prefix]
    for lit in lits[1:-1]:
        nxt = new()
        yield [-lit, nxt]
        yield [-prefix, nxt]
        yield [-prefix, -lit]
        prefix = nxt
    yield [-prefix, -lits[-1]]
