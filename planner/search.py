"""Minimal plans by symbolic breadth-first search on BDDs (DESIGN.md section 3.3).

Forward images layer by layer from the start state, each layer holding exactly the states
first reached in that many steps; the first layer that meets the goal gives the minimal
length, and a backward walk through the layers picks one concrete plan.  Unlike bounded
model checking, proving that no shorter plan exists costs nothing extra here: the earlier
layers simply did not meet the goal.
"""

from __future__ import annotations

from planner.model import TransitionKind
from planner.planning import PlanQuery, PlanResult, PlanStatus, State
from planner.symbolic import Function, SymbolicModel, SymbolicTransition, cudd
from planner.synthesis import automatic_guard

# CUDD counts minterms in doubles, which overflow beyond 2^1024
COUNTABLE_BITS = 1000


class SymbolicSearch:
    """Breadth-first planner over a model whose bad states are already known."""

    name = "bdd"

    def __init__(self, sym: SymbolicModel, bad: Function) -> None:
        self.sym = sym
        self.bad = bad

    def plan(self, query: PlanQuery) -> PlanResult:
        sym = self.sym
        usable = [
            t
            for t in sym.transitions
            if t.name not in query.disabled
            and (query.maintenance or t.kind is not TransitionKind.MAINTENANCE)
        ]
        automatic = automatic_guard(sym, query.disabled)
        goal = sym.expr(query.goal)
        if query.relaxed:
            allowed = sym.true
            for spec in sym.model.specifications:
                if spec.name not in query.relaxed:
                    allowed &= sym.expr(spec.invariant)
            goal &= ~self.bad
        else:
            allowed = ~self.bad
        for predicate in query.forbidden:
            allowed &= ~sym.expr(predicate)
        always = sym.expr(query.always) if query.always is not None else sym.true

        start = sym.state(query.start)
        if start & allowed == sym.false:
            return PlanResult(PlanStatus.BAD_START, max_steps=query.max_steps, engine=self.name)

        layers = [start]
        reached = start
        while True:
            depth = len(layers) - 1
            hit = layers[-1] & goal
            if hit != sym.false:
                plan, states = self._walk_back(layers, hit, usable, automatic, always)
                return PlanResult(
                    PlanStatus.FOUND,
                    plan,
                    states,
                    max_steps=query.max_steps,
                    engine=self.name,
                    statistics=self._statistics(depth + 1, reached),
                )
            if depth >= query.max_steps:
                break
            # any set between the layer and everything reached has the same new successors;
            # `restrict` picks a small BDD among them
            source = cudd.restrict(layers[-1], layers[-1] | ~reached) & always
            frontier = self._image(source, usable, automatic) & allowed & ~reached
            if frontier == sym.false:
                break  # fixpoint: the goal is unreachable at any length
            layers.append(frontier)
            reached |= frontier
        return PlanResult(
            PlanStatus.UNREACHABLE,
            max_steps=query.max_steps,
            engine=self.name,
            statistics=self._statistics(len(layers), reached),
        )

    def _statistics(self, layers: int, reached: Function) -> dict[str, float]:
        """Layers, and states reached where CUDD's double-precision counting can say."""
        out: dict[str, float] = {"layers": layers}
        if len(self.sym.state_bits) <= COUNTABLE_BITS:
            out["reached"] = self.sym.count(reached)
        return out

    def reachable(self, start: State, *, maintenance: bool = False) -> Function:
        """Every good state plans can visit from `start`.

        Chained (each transition's image joins the set at once) rather than layered: the
        fixpoint is the same, reached in far fewer and cheaper iterations, because no exact
        distance layers are kept.
        """
        sym = self.sym
        usable = [
            t for t in sym.transitions if maintenance or t.kind is not TransitionKind.MAINTENANCE
        ]
        automatic = automatic_guard(sym)
        allowed = ~self.bad
        reached = sym.state(start) & allowed
        while True:
            before = reached
            for t in usable:
                source = reached if t.kind is TransitionKind.AUTOMATIC else reached & ~automatic
                reached |= sym.image(t, source) & allowed
            if reached == before:
                return reached

    def _image(
        self, states: Function, usable: list[SymbolicTransition], automatic: Function
    ) -> Function:
        sym = self.sym
        free = states & ~automatic  # only here may controlled, effect, maintenance steps go
        result = sym.false
        for t in usable:
            source = states if t.kind is TransitionKind.AUTOMATIC else free
            if source == sym.false:
                continue
            result |= sym.image(t, source)
        return result

    def _walk_back(
        self,
        layers: list[Function],
        hit: Function,
        usable: list[SymbolicTransition],
        automatic: Function,
        always: Function,
    ) -> tuple[tuple[str, ...], tuple[State, ...]]:
        """One concrete plan: from a goal state, a predecessor in each earlier layer."""
        sym = self.sym
        state = sym.pick(hit)
        states = [state]
        names: list[str] = []
        for layer in reversed(layers[:-1]):
            target = sym.state(state)
            candidates = layer & always
            for t in usable:
                source = (
                    candidates if t.kind is TransitionKind.AUTOMATIC else candidates & ~automatic
                )
                before = sym.preimage(t, target) & source
                if before != sym.false:
                    state = sym.pick(before)
                    states.append(state)
                    names.append(t.name)
                    break
            else:  # pragma: no cover - the layers guarantee a predecessor
                raise AssertionError("no predecessor in the previous layer")
        return tuple(reversed(names)), tuple(reversed(states))
