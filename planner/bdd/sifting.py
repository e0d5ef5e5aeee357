"""Sifting the BDD variable order once after synthesis, one independent block at a time.

Sifting moves each variable through every level and keeps it where the BDDs are smallest.
In a model of independent blocks (no transition or specification spans two) a variable
moved out of its block only makes the unions and intersections across blocks a little
bigger, never enough to stop early, so every variable travels the whole order: quadratic in
the model (2.4 s at 1,000 transitions of bench/cells.py; at 10,000, CUDD's cap on swaps cut
it off after 6 s).  So each block is sifted on its own, in a small manager of its own that
holds copies of what the model keeps about it (guards and updates of its transitions, its
specifications, its valid codes, its bad states); the blocks then stand one after another,
in the order of their first bits.  A model of one block is sifted as a whole, as before.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from planner.bdd.symbolic import Function, SymbolicModel, cudd
from planner.bdd.synthesis import BadPart, valid_codes
from planner.model.coupling import Groups, touched
from planner.model.expressions import Equals, SameValue, Value, variables_of
from planner.model.flat import Model

SCRATCH_MEMORY = 64 * 2**20  # bytes: CUDD sizes its tables by it (dd's default is 1 GB)
SCRATCH_CACHE = 2**12  # initial computed-table slots


def blocks(model: Model) -> list[list[str]]:
    """Variables tied together by any transition or specification, in model order."""
    groups = Groups(v.name for v in model.variables)
    for t in model.transitions:
        groups.join(touched(t))
    for spec in model.specifications:
        groups.join(variables_of(spec.invariant))
    return list(groups.members().values())


def sift(sym: SymbolicModel, bad: Sequence[BadPart]) -> None:
    """Sift the order once (deterministic: called at a fixed point), block by block."""
    parts = blocks(sym.model)
    if len(parts) < 2:
        sym.sift()
        return
    bdd = sym.bdd
    block_of = {name: k for k, names in enumerate(parts) for name in names}
    bad_of: list[Function] = [sym.false for _ in parts]
    for part in bad:
        if part.component.variables:
            k = block_of[part.component.variables[0]]
            bad_of[k] |= part.states
    transitions: list[list[int]] = [[] for _ in parts]
    for i, t in enumerate(sym.model.transitions):
        read_or_written = touched(t)
        if read_or_written:
            transitions[block_of[min(read_or_written)]].append(i)
    specifications: list[list[int]] = [[] for _ in parts]
    for i, spec in enumerate(sym.model.specifications):
        read = variables_of(spec.invariant)
        if read:
            specifications[block_of[min(read)]].append(i)
    primed: dict[str, list[str]] = {bit: [] for bit in sym.state_bits}  # of swaps, see symbolic
    for name in bdd.vars:
        if name not in primed and name[:-1] in primed:
            primed[name[:-1]].append(name)
    placed: list[tuple[int, list[str]]] = []
    for k, names in enumerate(parts):
        bits = sorted((b for n in names for b in sym.bits[n]), key=bdd.level_of_var)
        functions = [bad_of[k], valid_codes(sym, names)]
        for i in transitions[k]:
            t = sym.model.transitions[i]
            functions.append(sym.expr(t.guard))
            functions += [_update(sym, a.target, a.value, a.source) for a in t.actions]
        functions += [sym.expr(sym.model.specifications[i].invariant) for i in specifications[k]]
        order = _sifted(sym, bits, functions) if len(bits) > 1 else bits
        placed.append((bdd.level_of_var(bits[0]), order + [p for b in order for p in primed[b]]))
    sym.reorder([bit for _, order in sorted(placed) for bit in order])


def _update(sym: SymbolicModel, target: str, value: Value | None, source: str | None) -> Function:
    """What a transition's action says of the next state (as the images use it)."""
    if source is not None:
        return sym.expr(SameValue(target, source))
    assert value is not None
    return sym.expr(Equals(target, value))


def _sifted(sym: SymbolicModel, bits: list[str], functions: Iterable[Function]) -> list[str]:
    """`bits` (in their current order) as sifting orders them with `functions` alone."""
    scratch = cudd.BDD(memory_estimate=SCRATCH_MEMORY, initial_cache_size=SCRATCH_CACHE)
    scratch.configure(reordering=False)  # sifting only once, below
    scratch.declare(*bits)
    copy = _Copy(sym, scratch)
    kept = [copy(u) for u in functions]  # alive while sifting: what the order is for
    cudd.reorder(scratch)
    assert kept
    return sorted(bits, key=scratch.level_of_var)


class _Copy:
    """Copies BDDs into another manager that declares the same bit names, node by node.

    `dd`'s own copy reads each function's support over every declared bit, which costs a
    pass over all of them per function.  A loop over an explicit stack, not recursion: a
    function's depth is its number of bits.
    """

    def __init__(self, sym: SymbolicModel, target: Any) -> None:
        self.sym = sym
        self.target = target
        self.memo: dict[Function, Function] = {}

    def __call__(self, u: Function) -> Function:
        sym, target, memo = self.sym, self.target, self.memo
        stack = [u if not u.negated else ~u]
        while stack:
            node = stack[-1]
            if node in memo:
                stack.pop()
                continue
            if node == sym.true:
                memo[node] = target.true
                stack.pop()
                continue
            low, high = node.low, node.high
            low_regular = low if not low.negated else ~low
            missing = [c for c in (low_regular, high) if c not in memo]
            if missing:
                stack += missing
                continue
            copied_low = memo[low_regular] if not low.negated else ~memo[low_regular]
            memo[node] = target.ite(target.var(node.var), memo[high], copied_low)
            stack.pop()
        root = memo[u if not u.negated else ~u]
        return root if not u.negated else ~root
