"""From a totally ordered plan to the start order that matters (DESIGN.md section 3.4).

A minimal plan is a sequence, but steps of different resources need not wait for each
other.  The plan is cut into blocks, one per controlled (or maintenance) step with the
automatic and effect steps that follow it; a block must wait for an earlier block only when
the two touch a common variable, or when an automatic guard, an effect guard or a
specification reads variables both write (so that taking them in either order cannot enable
something different or pass through another state's danger).  Independent blocks may start
in parallel (seed 000 sec. 4.2, seed 001 sec. VIII).

A plan may end where an automatic transition is enabled (the goal holds, so nothing more is
planned).  Automatic transitions have priority, so no controlled step could follow the
block that leaves it enabled: told so, the last block then waits for all the
others.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from planner.model.expressions import Expr, variables_of
from planner.model.flat import UNCONTROLLABLE, Model


@dataclass(frozen=True)
class Block:
    """A controlled step and the uncontrollable steps that follow it in the plan."""

    index: int  # position of the block's first step in the plan
    steps: tuple[str, ...]
    reads: frozenset[str]
    writes: frozenset[str]
    after: frozenset[int]  # indexes of earlier blocks it must wait for

    @property
    def transition(self) -> str:
        return self.steps[0]

    @property
    def variables(self) -> frozenset[str]:
        return self.reads | self.writes


def blocks(
    model: Model,
    plan: Sequence[str],
    extra_guards: Mapping[str, Expr] | None = None,
    automatic_at_end: bool = False,
) -> list[Block]:
    """The plan's blocks with their dependencies; leading uncontrollable steps form block 0.

    `extra_guards` (the supervisor's) count as read by their transitions;
    `automatic_at_end`, whether an automatic transition is enabled where the plan ends,
    orders the last block after all others (see the module's docstring).
    """
    extra = extra_guards or {}
    couplings = [variables_of(t.guard) for t in model.transitions if t.kind in UNCONTROLLABLE]
    couplings += [variables_of(s.invariant) for s in model.specifications]
    raw: list[tuple[int, list[str], set[str], set[str]]] = []
    for i, name in enumerate(plan):
        t = model.transition(name)
        if t.kind not in UNCONTROLLABLE or not raw:
            raw.append((i, [], set(), set()))
        _, steps, reads, writes = raw[-1]
        steps.append(name)
        reads |= variables_of(t.guard)
        if name in extra:
            reads |= variables_of(extra[name])
        for action in t.actions:
            writes.add(action.target)
            if action.source is not None:
                reads.add(action.source)
    # uncontrollable steps before the first controlled one happen before anything can start
    leading = bool(plan) and model.transition(plan[0]).kind in UNCONTROLLABLE
    result: list[Block] = []
    for k, (index, steps, reads, writes) in enumerate(raw):
        after = frozenset(
            j
            for j in range(k)
            if (j == 0 and leading) or _dependent(raw[j][2], raw[j][3], reads, writes, couplings)
        )
        if automatic_at_end and k == len(raw) - 1:
            after = frozenset(range(k))
        result.append(Block(index, tuple(steps), frozenset(reads), frozenset(writes), after))
    return result


def _dependent(
    reads_a: set[str],
    writes_a: set[str],
    reads_b: set[str],
    writes_b: set[str],
    couplings: list[frozenset[str]],
) -> bool:
    if writes_a & (reads_b | writes_b) or writes_b & reads_a:
        return True
    return any(c & writes_a and c & writes_b for c in couplings)


def independent_operations(
    reads_writes: Mapping[str, frozenset[str]], plan: Sequence[str]
) -> list[frozenset[int]]:
    """For each operation in the plan, the earlier ones it must wait for.

    Operations are independent when their variable sets (precondition, goal, effects) are
    disjoint (seed 000 sec. 4.2).
    """
    return [
        frozenset(j for j in range(i) if reads_writes[plan[j]] & reads_writes[plan[i]])
        for i in range(len(plan))
    ]
