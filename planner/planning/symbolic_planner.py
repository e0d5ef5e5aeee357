"""The `bdd` engine: a query planned part by part, each part a breadth-first search.

Size: one class, one concept (the symbolic search of a query, part by part); splitting it
would scatter one algorithm.

`planner.planning.relevance` says which variables a query can matter to and which parts of the
station are independent for it; this module turns each active part into a `search.Problem`
over its own variables, orders the parts' minimal plans so that their concatenation is a
minimal plan of the whole (or plans the parts jointly when no such order exists), and
replays the plan on full states, checking every step against the concrete semantics.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

from planner.bdd.sifting import blocks as sifting_blocks
from planner.bdd.symbolic import Function, SymbolicModel, SymbolicTransition
from planner.bdd.synthesis import COUNTABLE_BITS, breaking
from planner.model.expressions import Expr, Value, conjunction, conjuncts, variables_of
from planner.model.flat import TransitionKind
from planner.model.semantics import Predicate, Semantics, compile_expr
from planner.planning.query import PlanQuery, PlanResult, PlanStatus, State
from planner.planning.relaxed import goal_may_hold
from planner.planning.relevance import Component, Structure, allowed_conjuncts, cone_of_influence
from planner.planning.search import Outcome, Problem, probe, search
from planner.planning.symmetry import Swapper, Symmetry, find_symmetries, neighbours

PROBE_LAYERS = 12


@dataclass(frozen=True)
class Reductions:
    """The exact reductions the `bdd` engine applies; tests and benchmarks switch them off
    one at a time to check and to measure each."""

    parts: bool = True  # plan independent components apart, freeze the untouched ones
    cone: bool = True  # drop variables nothing the search reads depends on
    symmetry: bool = False  # keep one state per orbit of interchangeable objects


ALL_REDUCTIONS = Reductions()


@dataclass(frozen=True)
class _Sets:
    """A query's sets over every bit, before it is split into parts."""

    usable: tuple[SymbolicTransition, ...]
    allowed: Function
    goal: Function
    always: Function
    goal_parts: tuple[Expr, ...]  # conjuncts of the goal, each within one component
    joint: bool  # plan every active component together (forbidden-state recovery)


@dataclass(frozen=True)
class _Part:
    variables: frozenset[str]  # the component
    plan: tuple[str, ...]
    outcome: Outcome
    searched: tuple[str, ...] = ()  # the variables the search kept (cone of influence)


class SymbolicPlanner:
    """Plans `PlanQuery`s on the BDDs of a model whose bad states are known."""

    name = "bdd"

    def __init__(
        self,
        sym: SymbolicModel,
        bad: Function,
        bad_by_specification: Mapping[str, Function],
        reductions: Reductions = ALL_REDUCTIONS,
    ) -> None:
        self.sym = sym
        self.bad_by_specification = bad_by_specification
        self.reductions = reductions
        self.bad = bad
        self.tuned = False
        self.model = sym.model
        self.structure = Structure(sym.model)
        self.semantics = Semantics(sym.model, lazy=True)
        self.good = ~bad & sym.valid
        self._usable: dict[tuple[frozenset[str], bool], tuple[SymbolicTransition, ...]] = {}
        self._automatic: dict[frozenset[str], Function] = {}
        self._predicates: dict[Expr, Predicate] = {}
        self._readers: dict[int, list[int]] | None = None
        self._relaxed: dict[frozenset[str], Function] = {}
        self._broken: dict[Expr, Function] = {}
        self._symmetries: tuple[Symmetry, ...] | None = None
        self._swapper_cache: dict[tuple[str, frozenset[str]], Swapper] = {}

    def tune(self) -> None:
        """Choose the variable order for search, once: the one synthesis left (sifted for the
        bad states and guards) or the static FORCE order the model was declared in, by the
        work a short breadth-first probe from the model's initial state does in each.

        Neither wins everywhere: on the demo station the FORCE order halves the work of
        its long goals, on the station family the sifted one does.  A probe of
        `PROBE_LAYERS` layers predicts which (bench/planning.py); models of independent
        blocks keep their per-block order (planner/bdd/sifting.py), where a probe would image
        every block.  The plans do not depend on the choice, only the time.
        """
        if self.tuned:
            return
        self.tuned = True
        sym = self.sym
        if len(sifting_blocks(self.model)) > 1:
            return
        current = sorted(sym.bdd.vars, key=sym.bdd.level_of_var)
        candidates = [current]
        if sym.initial_order != current:
            candidates.append(sym.initial_order)
        costs = []
        for order in candidates:
            sym.reorder(order)
            costs.append(self._probe())
        best = candidates[costs.index(min(costs))]
        if best != candidates[-1]:
            sym.reorder(best)

    def _probe(self) -> float:
        """The BDD work (CUDD cache lookups, deterministic) of `PROBE_LAYERS` breadth-first
        layers from the initial state over every transition but maintenance ones."""
        sym = self.sym
        usable = tuple(t for t in sym.transitions if t.kind is not TransitionKind.MAINTENANCE)
        automatic = self.automatic(usable)
        start = sym.state(tuple(v.initial for v in self.model.variables))
        before = _lookups(sym)
        probe(sym, start, usable, automatic, self.good, PROBE_LAYERS)
        return _lookups(sym) - before

    def usable(self, query: PlanQuery) -> tuple[SymbolicTransition, ...]:
        key = (query.disabled, query.maintenance)
        found = self._usable.get(key)
        if found is None:
            found = tuple(
                t
                for t in self.sym.transitions
                if t.name not in query.disabled
                and (query.maintenance or t.kind is not TransitionKind.MAINTENANCE)
            )
            self._usable[key] = found
        return found

    def automatic(self, transitions: Sequence[SymbolicTransition]) -> Function:
        """States where one of these transitions that is automatic is enabled."""
        names = frozenset(t.name for t in transitions if t.kind is TransitionKind.AUTOMATIC)
        found = self._automatic.get(names)
        if found is None:
            found = self.sym.false
            for t in transitions:
                if t.kind is TransitionKind.AUTOMATIC:
                    found |= t.guard
            if len(self._automatic) > 256:
                self._automatic.clear()
            self._automatic[names] = found
        return found

    def _sets(self, query: PlanQuery) -> _Sets:
        sym = self.sym
        goal = sym.expr(query.goal)
        if query.relaxed:
            allowed = self._good_without(self._relaxed_at(query))
            goal &= self.good
        else:
            allowed = self.good
        for predicate in query.forbidden:
            allowed &= ~sym.expr(predicate)
        for predicate in query.kept:
            allowed &= ~self._breaking(predicate)
        always = sym.expr(query.always) if query.always is not None else sym.true
        return _Sets(
            self.usable(query),
            allowed,
            goal,
            always,
            conjuncts(query.goal),
            bool(query.relaxed),
        )

    def _breaking(self, predicate: Expr) -> Function:
        """`synthesis.breaking`, kept: the next operations' links recur tick after tick."""
        found = self._broken.get(predicate)
        if found is None:
            found = breaking(self.sym, predicate)
            if len(self._broken) > 256:
                self._broken.clear()
            self._broken[predicate] = found
        return found

    def _relaxed_at(self, query: PlanQuery) -> frozenset[str]:
        """The dropped specifications and those the start is already bad for: a recovery
        cannot keep the supervisor of a specification the world can break from the start."""
        bad = self.bad_by_specification
        start = self.sym.state(query.start)
        already = {name for name, states in bad.items() if states & start != self.sym.false}
        return query.relaxed | already

    def _good_without(self, relaxed: frozenset[str]) -> Function:
        """The valid states not bad for any specification but the `relaxed` ones: where a
        forbidden-state recovery may go, the supervisor of the others still holding."""
        found = self._relaxed.get(relaxed)
        if found is None:
            bad = self.sym.false
            for name, states in self.bad_by_specification.items():
                if name not in relaxed:
                    bad |= states
            found = self.sym.valid & ~bad
            if len(self._relaxed) > 64:
                self._relaxed.clear()
            self._relaxed[relaxed] = found
        return found

    def holds(self, expr: Expr, state: State) -> bool:
        predicate = self._predicates.get(expr)
        if predicate is None:
            predicate = compile_expr(expr, self.model.variable_index)
            if len(self._predicates) > 4096:
                self._predicates.clear()
            self._predicates[expr] = predicate
        return predicate(state)

    def plan(self, query: PlanQuery) -> PlanResult:
        self.tune()
        sym = self.sym
        sets = self._sets(query)
        start = sym.state(query.start)
        if start & sets.allowed == sym.false:
            return PlanResult(PlanStatus.BAD_START, max_steps=query.max_steps, engine=self.name)
        if start & sets.goal != sym.false:
            return self._result(query, (), [], {"layers": 1})
        if start & sets.always == sym.false:
            return self._unreachable(query, {"layers": 1})
        named = {v.name: value for v, value in zip(self.model.variables, query.start, strict=True)}
        usable = (t.transition for t in sets.usable)
        if not goal_may_hold(query.goal, named, usable, query.always):  # no search needed
            return self._unreachable(query, {"layers": 0, "relaxed": 1})
        predicates = list(sets.goal_parts)
        if query.always is not None:
            predicates.extend(conjuncts(query.always))
        for forbidden in query.forbidden:
            predicates.extend(allowed_conjuncts(forbidden))
        predicates.extend(query.kept)
        usable_names = frozenset(t.name for t in sets.usable)
        if self.reductions.parts:
            components = self.structure.components(usable_names, predicates)
            active = self._active(components, query, sets, start)
            if not active:  # every part of the goal that reads a variable holds: it is false
                return self._unreachable(query, {"layers": 1})
        else:
            active = [Component(tuple(v.name for v in self.model.variables))]
        parts, found = self._plan_parts(query, sets, active)
        plan = tuple(name for part in parts for name in part.plan)
        if found and len(plan) > query.max_steps and len(parts) > 1 and self._weighted(query):
            # each part's cheapest plan is not the shortest: together they may not fit in
            # max_steps where plans with more maintenance would
            everything = frozenset(v for c in active for v in c.variables)
            parts = [self._search(query, sets, everything, sets.goal)]
            found = parts[0].outcome.found
            plan = parts[0].plan
        if not found or len(plan) > query.max_steps:
            return self._unreachable(query, self._statistics(parts))
        return self._result(query, plan, parts, self._statistics(parts))

    def _active(
        self, components: Sequence[Component], query: PlanQuery, sets: _Sets, start: Function
    ) -> list[Component]:
        """The components that must move: their part of the goal does not hold at the start,
        or one of their automatic transitions is enabled there (or, in forbidden-state
        recovery, the start is bad for one of their specifications)."""
        where = {name: k for k, c in enumerate(components) for name in c.variables}
        state = query.start
        active: set[int] = set()
        for part in sets.goal_parts:
            names = variables_of(part)
            if names and not self.holds(part, state):
                active.add(where[next(iter(names))])
        for t in sets.usable:
            automatic = t.kind is TransitionKind.AUTOMATIC and t.transition.written
            if automatic and self.semantics.by_name[t.name].guard(state):
                active.add(where[next(iter(t.transition.written))])
        if sets.joint:
            for spec in self.model.specifications:
                bad = self.bad_by_specification.get(spec.name)
                names = variables_of(spec.invariant)
                if names and bad is not None and bad & start != self.sym.false:
                    active.add(where[next(iter(names))])
        return [c for k, c in enumerate(components) if k in active]

    def _plan_parts(
        self, query: PlanQuery, sets: _Sets, active: list[Component]
    ) -> tuple[list[_Part], bool]:
        """The active components' plans in an order whose concatenation is minimal, or the
        joint plan of all of them; and whether every part found one."""
        everything = frozenset(v for c in active for v in c.variables)
        if sets.joint or len(active) == 1:
            part = self._search(query, sets, everything, sets.goal)
            return [part], part.outcome.found
        parts: list[_Part] = []
        for component in active:
            variables = frozenset(component.variables)
            part = self._search(query, sets, variables, self._goal_within(sets, variables))
            parts.append(part)
            if not part.outcome.found:  # the product cannot do better than a part
                return parts, False
        ordered = self._order(query, sets, parts)
        if ordered is not None:
            return ordered, True
        joint = self._search(query, sets, everything, sets.goal)
        return [joint], joint.outcome.found

    def _goal_within(self, sets: _Sets, variables: frozenset[str]) -> Function:
        return self.sym.expr(
            conjunction([p for p in sets.goal_parts if variables_of(p) <= variables])
        )

    def _order(self, query: PlanQuery, sets: _Sets, parts: list[_Part]) -> list[_Part] | None:
        """The parts in an order whose concatenation is minimal: the one whose automatic
        transitions are enabled at the start goes first, each but the last ends where none
        of its automatics is enabled and `always` holds (re-planned to such an end when
        that costs no step), or None when no such order exists."""
        start = query.start
        first = [p.variables for p in parts if self._automatic_enabled(p.variables, sets, start)]
        if len(first) > 1:
            return None
        settled: list[_Part] = []
        unsettled: list[_Part] = []
        for part in parts:
            end = self._replay(start, part.plan)[-1]
            if self._rests(part.variables, query, sets, end):
                settled.append(part)
                continue
            within = self._within(sets, part.variables)
            goal = self._goal_within(sets, part.variables)
            calm = goal & ~self.automatic(within) & sets.always
            again = self._search(query, sets, part.variables, calm)
            if again.outcome.found and self._cost(query, again.plan) == self._cost(
                query, part.plan
            ):
                settled.append(again)
            else:
                unsettled.append(part)
        if len(unsettled) > 1 or (first and unsettled and unsettled[0].variables == first[0]):
            return None
        head = [p for p in settled if first and p.variables == first[0]]
        middle = [p for p in settled if not (first and p.variables == first[0])]
        return head + middle + unsettled

    @staticmethod
    def _weighted(query: PlanQuery) -> bool:
        return query.maintenance and query.maintenance_cost > 1

    def _cost(self, query: PlanQuery, plan: Sequence[str]) -> tuple[int, int]:
        """A plan's cost and maintenance steps (`PlanQuery.maintenance_cost`)."""
        maintenance = sum(self.model.transition(n).kind is TransitionKind.MAINTENANCE for n in plan)
        return len(plan) + (query.maintenance_cost - 1) * maintenance, maintenance

    def _rests(self, variables: frozenset[str], query: PlanQuery, sets: _Sets, end: State) -> bool:
        if self._automatic_enabled(variables, sets, end):
            return False
        if query.always is None:
            return True
        return all(
            self.holds(part, end)
            for part in conjuncts(query.always)
            if variables_of(part) <= variables
        )

    def _automatic_enabled(self, variables: frozenset[str], sets: _Sets, state: State) -> bool:
        return any(
            self.semantics.by_name[t.name].guard(state)
            for t in self._within(sets, variables)
            if t.kind is TransitionKind.AUTOMATIC
        )

    def _within(self, sets: _Sets, variables: frozenset[str]) -> list[SymbolicTransition]:
        """The usable transitions of a part (a transition that writes nothing is a self-loop,
        in no part)."""
        return [t for t in sets.usable if t.transition.written & variables]

    def _search(
        self, query: PlanQuery, sets: _Sets, variables: frozenset[str], goal: Function
    ) -> _Part:
        problem = self.problem(query, sets, variables, goal)
        if not self._weighted(query):
            outcome = search(self.sym, problem)
            return _Part(variables, outcome.plan, outcome, problem.variables)
        counted = frozenset(
            t.name for t in problem.transitions if t.kind is TransitionKind.MAINTENANCE
        )
        layers = 0
        known: Sequence[Sequence[Function]] = ()
        for budget in range(1, query.max_steps + 1):  # most plans need one, or none
            weighted = replace(problem, counted=counted, budget=budget, cost=query.maintenance_cost)
            outcome = search(self.sym, weighted, known, keep=True)  # reused by the next budget
            known = outcome.kept
            layers += outcome.layers
            if outcome.exhausted:
                break
            # the cheapest plan within the budget; one with more counted steps costs at
            # least (budget + 1) * cost
            if outcome.found and self._cost(query, outcome.plan)[0] <= (
                (budget + 1) * query.maintenance_cost
            ):
                break
        outcome = replace(outcome, layers=layers, kept=())
        return _Part(variables, outcome.plan, outcome, problem.variables)

    def problem(
        self, query: PlanQuery, sets: _Sets, variables: frozenset[str], goal: Function
    ) -> Problem:
        """The search for one part: every other variable fixed at its start value, and
        within the part only the cone of influence of what the search reads."""
        sym = self.sym
        index = self.model.variable_index
        outside = {
            v.name: query.start[index[v.name]]
            for v in self.model.variables
            if v.name not in variables
        }
        assignment = _assignment(sym, outside)
        fix: Callable[[Function], Function] = (
            (lambda f: sym.bdd.let(assignment, f)) if assignment else (lambda f: f)
        )
        transitions = self._within(sets, variables)
        allowed, always = fix(sets.allowed), fix(sets.always)
        goal = fix(goal)
        automatic = self.automatic(transitions)
        seeds: set[str] = set()
        for f in (allowed, always, goal, automatic):
            seeds |= sym.variables_of(f)
        keep = (
            cone_of_influence(seeds, [t.transition for t in transitions], variables)
            if self.reductions.cone
            else variables
        )
        kept = tuple(sym.restricted(t, keep) for t in transitions if t.transition.written & keep)
        ordered = tuple(v.name for v in self.model.variables if v.name in keep)
        start = sym.cube({name: query.start[index[name]] for name in ordered})
        swappers = self._swappers(query, sets, variables, keep, goal)
        return Problem(
            start,
            goal,
            allowed,
            always,
            automatic,
            kept,
            ordered,
            query.max_steps,
            symmetries=swappers,
        )

    @property
    def symmetries(self) -> tuple[Symmetry, ...]:
        if self._symmetries is None:
            self._symmetries = find_symmetries(self.sym)
        return self._symmetries

    def _swappers(
        self,
        query: PlanQuery,
        sets: _Sets,
        variables: frozenset[str],
        keep: frozenset[str],
        goal: Function,
    ) -> tuple[Swapper, ...]:
        """The model's symmetries that this query and part keep (see `planner.planning.symmetry`):
        every usable transition has a usable image, the swap moves nothing outside the
        part, and the goal, `always`, the forbidden predicates and the dropped
        specifications are unchanged by it."""
        if not self.reductions.symmetry or not self.symmetries:
            return ()
        sym = self.sym
        usable = frozenset(t.name for t in sets.usable)
        valid: list[Symmetry] = []
        for symmetry in self.symmetries:
            if symmetry.broken & usable or not symmetry.moved <= variables:
                continue
            if any(symmetry.transitions.get(n, n) not in usable for n in usable):
                continue
            if any((v in keep) != (symmetry.variable(v) in keep) for v in symmetry.moved):
                continue
            if query.relaxed and (
                symmetry.specifications is None
                or any(symmetry.specifications[r] not in query.relaxed for r in query.relaxed)
            ):
                continue
            predicates = [*query.forbidden] + ([query.always] if query.always is not None else [])
            if any(sym.expr(symmetry.expr(p)) != sym.expr(p) for p in predicates):
                continue
            if self._swapper(symmetry, keep).image(goal) != goal:
                continue
            valid.append(symmetry)
        return tuple(self._swapper(s, keep) for s in neighbours(valid))

    def _swapper(self, symmetry: Symmetry, keep: frozenset[str]) -> Swapper:
        key = (symmetry.name, keep)
        swapper = self._swapper_cache.get(key)
        if swapper is None:
            swapper = Swapper(self.sym, symmetry, keep)
            if len(self._swapper_cache) > 512:
                self._swapper_cache.clear()
            self._swapper_cache[key] = swapper
        return swapper

    def _statistics(self, parts: Sequence[_Part]) -> dict[str, float]:
        out: dict[str, float] = {
            "layers": sum(p.outcome.layers for p in parts),
            "parts": len(parts),
        }
        searched = 0
        reached = 0
        countable = True
        for part in parts:
            bits = sum(len(self.sym.bits[v]) for v in part.searched)
            searched += bits
            if bits > COUNTABLE_BITS or part.outcome.reached is None:
                countable = False
                continue
            reached += int(self.sym.bdd.count(part.outcome.reached, nvars=bits))
        if countable:
            out["reached"] = reached
        out["searched_bits"] = searched
        return out

    def _unreachable(self, query: PlanQuery, statistics: dict[str, float]) -> PlanResult:
        return PlanResult(
            PlanStatus.UNREACHABLE,
            max_steps=query.max_steps,
            engine=self.name,
            statistics=statistics,
        )

    def _result(
        self,
        query: PlanQuery,
        plan: tuple[str, ...],
        parts: Sequence[_Part],
        statistics: dict[str, float],
    ) -> PlanResult:
        states = self._replay(query.start, plan, check=query)
        return PlanResult(
            PlanStatus.FOUND,
            plan,
            states,
            max_steps=query.max_steps,
            engine=self.name,
            statistics=statistics,
        )

    def _automatic_readers(self) -> dict[int, list[int]]:
        """Variable index -> the automatic transitions (index in `semantics.automatic`)
        whose guards read it."""
        if self._readers is None:
            index = self.model.variable_index
            self._readers = {}
            for k, a in enumerate(self.semantics.automatic):
                for name in variables_of(a.transition.guard):
                    self._readers.setdefault(index[name], []).append(k)
        return self._readers

    def _replay(
        self, start: State, plan: Sequence[str], check: PlanQuery | None = None
    ) -> tuple[State, ...]:
        """The full states a plan visits; with `check`, every step is verified against the
        concrete semantics (a reduction that broke a plan fails loudly here)."""
        states = [start]
        state = start
        semantics = self.semantics
        automatic, readers = semantics.automatic, self._automatic_readers()
        disabled = check.disabled if check is not None else frozenset()
        usable = [a.name not in disabled for a in automatic]
        enabled = {k for k, a in enumerate(automatic) if usable[k] and a.guard(state)}
        for name in plan:
            if check is not None:
                problem = semantics.step_allowed(
                    state,
                    name,
                    maintenance=check.maintenance,
                    disabled=check.disabled,
                    enabled_automatic=[automatic[k].name for k in sorted(enabled)],
                )
                if problem is not None:
                    raise AssertionError(f"planned step {name} is not possible: {problem}")
            after = semantics.by_name[name].apply(state)
            if check is not None:  # only automatics reading what changed can change
                changed = [i for i, (u, v) in enumerate(zip(state, after, strict=True)) if u != v]
                for k in {k for i in changed for k in readers.get(i, ())}:
                    if usable[k] and automatic[k].guard(after):
                        enabled.add(k)
                    else:
                        enabled.discard(k)
            state = after
            states.append(state)
        return tuple(states)


def _lookups(sym: SymbolicModel) -> float:
    with warnings.catch_warnings():  # dd warns that another of its statistics changed unit
        warnings.simplefilter("ignore", UserWarning)
        return float(sym.bdd.statistics()["cache_lookups"])


def _assignment(sym: SymbolicModel, values: Mapping[str, Value]) -> dict[str, bool]:
    assignment: dict[str, bool] = {}
    for name, value in values.items():
        assignment.update(sym.code(name, value))
    return assignment
