"""Minimal plans by symbolic breadth-first search on BDDs (DESIGN.md section 3.3).

Forward images layer by layer from the start state, each layer holding exactly the states
first reached in that many steps; the first layer that meets the goal gives the minimal
length, and a backward walk through the layers picks one concrete plan.  Unlike bounded
model checking, proving that no shorter plan exists costs nothing extra here: the earlier
layers simply did not meet the goal.

A `Problem` is one search over some of the model's variables (a part of the station, see
`planner.planning.relevance`); its sets mention only those variables' bits.  The plan picked does
not depend on the BDD variable order (it is the least minimal plan by transition order),
so a planner whose order was tuned and cached plans exactly like a fresh one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from planner.bdd.symbolic import Function, SymbolicModel, SymbolicTransition, cudd
from planner.model.coupling import reads
from planner.model.flat import TransitionKind
from planner.planning.symmetry import Swapper, canonical, orbit


@dataclass(frozen=True)
class Problem:
    """One breadth-first search: every set is over the bits of `variables` alone.

    Steps of the `counted` transitions (maintenance, when a query weighs the work it asks
    of people) cost `cost` each instead of 1 and may be taken at most `budget` times; the
    layers are kept apart by how many were taken, so that a state reached with fewer counts
    as reached first.
    """

    start: Function
    goal: Function
    allowed: Function  # states a plan may visit (good, not forbidden, valid)
    always: Function  # must hold in every state before the goal (`phi U goal`)
    automatic: Function  # states where some usable automatic transition is enabled
    transitions: tuple[SymbolicTransition, ...]
    variables: tuple[str, ...]
    max_steps: int
    counted: frozenset[str] = frozenset()
    budget: int = 0
    cost: int = 1
    symmetries: tuple[Swapper, ...] = ()  # swaps of interchangeable objects the query keeps


@dataclass(frozen=True)
class Outcome:
    found: bool
    plan: tuple[str, ...] = ()
    layers: int = 0
    reached: Function | None = field(default=None, compare=False)
    exhausted: bool = False  # no state needed the whole budget: a larger one cannot help
    # the layers searched, per depth and count: a search of the same problem with a larger
    # budget reuses them (`search`'s `known`)
    kept: tuple[tuple[Function, ...], ...] = field(default=(), compare=False, repr=False)


Layer = list[Function]  # one set per number of counted steps taken, 0 .. budget
_Hit = tuple[int, int, int, Function]  # cost, counted steps, depth, the states meeting the goal

CANONICAL_ROUNDS = 3


def search(
    sym: SymbolicModel,
    problem: Problem,
    known: Sequence[Sequence[Function]] = (),
    keep: bool = False,
) -> Outcome:
    """Breadth-first from the start; the first layer meeting the goal gives the plan.

    With counted steps, the plan of least cost (ties: fewer counted steps): a hit found at
    depth k with j counted steps costs k + (cost - 1) j, and is kept until no layer with
    fewer counted steps can still reach the goal as cheaply (those layers grow only from
    themselves, one step deeper per layer).  `known`: the layers (`Outcome.kept`) of this
    problem searched with a smaller budget; the states first reached with j counted steps
    depend only on those reached with j or fewer, so those counts are taken from it as far
    as it goes, and only the larger counts are imaged.  `keep`: return the layers in
    `Outcome.kept` (otherwise they are freed with the search).
    """
    budget = problem.budget
    plain = tuple(t for t in problem.transitions if t.name not in problem.counted)
    counted = tuple(t for t in problem.transitions if t.name in problem.counted)
    false = sym.false
    layers: list[Layer] = [[problem.start] + [false] * budget]
    seen = [problem.start] * (budget + 1)  # seen[j]: reached with at most j counted steps
    best: _Hit | None = None
    # whether a larger budget would reach a state sooner than this search: a counted step
    # out of the last count to a state not reached by the depth it leads to
    escaped = False
    while True:
        depth = len(layers) - 1
        best = _best_hit(sym, problem, layers[-1], depth, best)
        if best is not None and (
            _hopeless(sym, problem, layers[-1], depth, best) or depth >= problem.max_steps
        ):
            _, count, at, hit = best
            plan = _walk(sym, problem, layers[: at + 1], count, hit)
            return Outcome(True, plan, at + 1, seen[-1], kept=_kept(layers, keep))
        if depth >= problem.max_steps:
            break
        sources = [
            # any set between the layer and everything reached has the same new successors;
            # `restrict` picks a small BDD among them
            cudd.restrict(states, states | ~seen[j]) & problem.always
            for j, states in enumerate(layers[-1])
        ]
        depth_known = known[depth + 1] if depth + 1 < len(known) else ()
        frontier = _next_layer(sym, problem, sources, seen, plain, counted, depth_known)
        if counted and not escaped:
            outside = image(sym, problem, sources[budget], counted) & problem.allowed & ~seen[-1]
            escaped = outside != false
        if all(f == false for f in frontier):
            if best is not None:
                layers.append(frontier)  # the lower counts died out too: take the hit
                continue
            break  # fixpoint: the goal is unreachable at any length
        layers.append(frontier)
    kept = _kept(layers, keep)
    return Outcome(False, layers=len(layers), reached=seen[-1], exhausted=not escaped, kept=kept)


def _kept(layers: list[Layer], keep: bool) -> tuple[tuple[Function, ...], ...]:
    return tuple(tuple(layer) for layer in layers) if keep else ()


def _best_hit(
    sym: SymbolicModel, problem: Problem, layer: Layer, depth: int, best: _Hit | None
) -> _Hit | None:
    """The cheapest hit so far: `best`, or one of this layer's that costs less."""
    extra = problem.cost - 1
    for j, states in enumerate(layer):
        if best is not None and (depth + extra * j, j) >= best[:2]:
            continue
        hit = states & problem.goal
        if hit != sym.false:
            best = (depth + extra * j, j, depth, hit)
    return best


def _hopeless(sym: SymbolicModel, problem: Problem, layer: Layer, depth: int, best: _Hit) -> bool:
    """No layer with fewer counted steps than the best hit can still do better."""
    cost, count = best[:2]
    extra = problem.cost - 1
    return all(
        states == sym.false or depth + 1 + extra * j > cost
        for j, states in enumerate(layer[:count])
    )


def _next_layer(
    sym: SymbolicModel,
    problem: Problem,
    sources: list[Function],
    seen: list[Function],
    plain: Sequence[SymbolicTransition],
    counted: Sequence[SymbolicTransition],
    known: Sequence[Function] = (),
) -> Layer:
    """The states first reached one step deeper, per number of counted steps taken (a
    counted step moves a state up one count; the first counts as `known` when given);
    `seen` grows by them."""
    frontier: Layer = []
    for j in range(problem.budget + 1):
        if j < len(known):
            frontier.append(known[j])
            for k in range(j, problem.budget + 1):
                seen[k] |= known[j]
            continue
        found = image(sym, problem, sources[j], plain)
        if j > 0:
            found |= image(sym, problem, sources[j - 1], counted)
        found &= problem.allowed & ~seen[j]
        if problem.symmetries and found != sym.false:
            found = canonical(problem.symmetries, found, CANONICAL_ROUNDS) & ~seen[j]
        frontier.append(found)
        for k in range(j, problem.budget + 1):
            seen[k] |= found
    return frontier


def image(
    sym: SymbolicModel,
    problem: Problem,
    states: Function,
    transitions: Sequence[SymbolicTransition],
) -> Function:
    """Every successor of `states` by one of `transitions` (automatic ones first and alone)."""
    result = sym.false
    if states == sym.false:
        return result
    free = states & ~problem.automatic  # only here may controlled, effect, maintenance go
    for t in transitions:
        source = states if t.kind is TransitionKind.AUTOMATIC else free
        if source == sym.false:
            continue
        result |= sym.image(t, source)
    return result


def _predecessors(
    sym: SymbolicModel,
    problem: Problem,
    layer: Function,
    targets: Function,
    transitions: Sequence[SymbolicTransition],
) -> Function:
    candidates = layer & problem.always
    free = candidates & ~problem.automatic
    before = sym.false
    if targets == sym.false:
        return before
    for t in transitions:
        source = candidates if t.kind is TransitionKind.AUTOMATIC else free
        if source != sym.false:
            before |= sym.preimage(t, targets) & source
    return before


def _walk(
    sym: SymbolicModel, problem: Problem, layers: Sequence[Layer], count: int, hit: Function
) -> tuple[str, ...]:
    """One minimal plan, the same whatever the BDD variable order.

    Backwards, the states of each layer that reach the goal in the remaining steps; then
    forwards from the start, at each step the first transition that stays among them,
    preferring one that reads what the step before wrote (finish what was started: after
    "r1 moves to scan", "r1 arrives"), then the model's order.  So among equally short
    plans a station does first what its model lists first, and keeps a resource's chain of
    steps together.
    """
    budget = problem.budget
    plain = tuple(t for t in problem.transitions if t.name not in problem.counted)
    counted = tuple(t for t in problem.transitions if t.name in problem.counted)
    target: Layer = [sym.false] * (budget + 1)
    target[count] = hit
    onward = [_closed(problem, target)]
    for layer in reversed(layers[:-1]):
        after = onward[-1]
        before: Layer = []
        for j in range(budget + 1):
            states = _predecessors(sym, problem, layer[j], after[j], plain)
            if j < budget:
                states |= _predecessors(sym, problem, layer[j], after[j + 1], counted)
            before.append(states)
        onward.append(_closed(problem, before))
    onward.reverse()
    state = problem.start
    used = 0
    names: list[str] = []
    written: frozenset[str] = frozenset()
    readers: dict[str, list[int]] = {}
    for k, t in enumerate(problem.transitions):
        for name in _reads(t):
            readers.setdefault(name, []).append(k)
    for goal in onward[1:]:
        automatic = state & problem.automatic != sym.false
        first = sorted({k for name in written for k in readers.get(name, ())})
        chosen = set(first)
        order = first + [k for k in range(len(problem.transitions)) if k not in chosen]
        for t in (problem.transitions[k] for k in order):
            if automatic and t.kind is not TransitionKind.AUTOMATIC:
                continue
            step = used + (t.name in problem.counted)
            if step > budget:
                continue
            after_state = sym.image(t, state)
            if after_state != sym.false and after_state & goal[step] != sym.false:
                names.append(t.name)
                state, used, written = after_state, step, t.transition.written
                break
        else:  # pragma: no cover - the backward sets guarantee a successor
            raise AssertionError("no step stays on a minimal plan")
    return tuple(names)


def _closed(problem: Problem, layer: Layer) -> Layer:
    """With symmetries, every state of the orbits a layer meets: the layers hold one state
    per orbit, the real plan may pass through any of them."""
    if not problem.symmetries:
        return layer
    return [orbit(problem.symmetries, states) for states in layer]


def _reads(t: SymbolicTransition) -> frozenset[str]:
    return reads(t.transition)


def probe(
    sym: SymbolicModel,
    start: Function,
    transitions: Sequence[SymbolicTransition],
    automatic: Function,
    allowed: Function,
    layers: int,
) -> None:
    """`layers` breadth-first layers from `start`, for the work they take (see
    `SymbolicPlanner.tune`)."""
    frontier = reached = start & allowed
    for _ in range(layers):
        source = cudd.restrict(frontier, frontier | ~reached)
        free = source & ~automatic
        found = sym.false
        for t in transitions:
            found |= sym.image(t, source if t.kind is TransitionKind.AUTOMATIC else free)
        frontier = found & allowed & ~reached
        if frontier == sym.false:
            return
        reached |= frontier


def reachable(
    sym: SymbolicModel,
    start: Function,
    transitions: Sequence[SymbolicTransition],
    automatic: Function,
    allowed: Function,
) -> Function:
    """Every allowed state reachable from `start`.

    Chained (each transition's image joins the set at once) rather than layered: the
    fixpoint is the same, reached in far fewer and cheaper iterations, because no exact
    distance layers are kept.
    """
    reached = start & allowed
    while True:
        before = reached
        for t in transitions:
            source = reached if t.kind is TransitionKind.AUTOMATIC else reached & ~automatic
            reached |= sym.image(t, source) & allowed
        if reached == before:
            return reached
