"""Relaxed reachability: which values each variable can ever take, and whether a goal can hold
in them at all (issue 27: "no way out" proven without a search).

States are boxed by one set of values per variable, starting from the start state's.  A
transition may fire when its guard may hold for some choice within the boxes, and then adds
the values it assigns (a copy `x := y` adds all of y's).  Boxes only grow, so the fixpoint
comes after at most as many rounds as there are values to add.  Every reachable state lies in
the final boxes (each of its values was put there by the step that wrote it, or was there at
the start), so a goal that cannot hold in them is unreachable at any horizon, within any
budget, whatever the forbidden states: a goal cut off by a broken device (no usable
transition ever confirms a lock) is answered in a few passes over the transitions.  `True`
says nothing: the search decides.

"May hold" is itself an over-approximation (`a && !a` may hold in a box holding both values);
it never says "cannot" of what can.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from planner.model.expressions import (
    And,
    BoolVar,
    Const,
    Equals,
    Expr,
    Implies,
    Not,
    Or,
    SameValue,
    Value,
    variables_of,
)
from planner.model.flat import Transition
from planner.planning.relevance import cone_of_influence

Boxes = dict[str, set[Value]]


def may_hold(expr: Expr, boxes: Mapping[str, set[Value]]) -> tuple[bool, bool]:
    """(whether `expr` may be true, whether it may be false) for some choice in `boxes`."""
    match expr:
        case Const(value):
            return bool(value), not value
        case BoolVar(name):
            box = boxes[name]
            return True in box, False in box
        case Equals(name, value):
            box = boxes[name]
            return value in box, any(v != value for v in box)
        case SameValue(left, right):
            one, other = boxes[left], boxes[right]
            return bool(one & other), len(one) > 1 or len(other) > 1 or one != other
        case Not(arg):
            true, false = may_hold(arg, boxes)
            return false, true
        case And(args):
            parts = [may_hold(a, boxes) for a in args]
            return all(t for t, _ in parts), any(f for _, f in parts)
        case Or(args):
            parts = [may_hold(a, boxes) for a in args]
            return any(t for t, _ in parts), all(f for _, f in parts)
        case Implies(left, right):
            left_true, left_false = may_hold(left, boxes)
            right_true, right_false = may_hold(right, boxes)
            return left_false or right_true, left_true and right_false
    raise TypeError(expr)


def boxes_reached(
    start: Mapping[str, Value], transitions: Sequence[Transition], always: Expr | None = None
) -> Boxes:
    """The values each variable can take from `start` by `transitions` (module docstring);
    with `always`, a transition fires only where it may hold too (`phi U goal`: every state
    before the goal keeps it)."""
    boxes: Boxes = {name: {value} for name, value in start.items()}
    waiting = list(transitions)
    copying: list[Transition] = []  # fired, with a copy whose source may still grow
    grew = True
    while grew:
        grew = False
        still: list[Transition] = []
        for t in waiting:
            guard = t.guard if always is None else And((t.guard, always))
            if may_hold(guard, boxes)[0]:
                grew |= _assign(t, boxes)
                if any(a.source is not None for a in t.actions):
                    copying.append(t)
            else:
                still.append(t)
        waiting = still
        for t in copying:
            grew |= _assign(t, boxes)
    return boxes


def goal_may_hold(
    goal: Expr,
    start: Mapping[str, Value],
    transitions: Iterable[Transition],
    always: Expr | None = None,
) -> bool:
    """Whether `goal` may hold in some state reachable from `start`; False proves it cannot.

    Only the transitions that write the goal's cone of influence are fired (what it and
    `always` read, and what the guards and sources of those transitions read): the boxes of
    the cone depend on nothing else, and a goal over one cell of thousands asks few."""
    every = tuple(transitions)
    seeds = variables_of(goal) | (frozenset() if always is None else variables_of(always))
    cone = cone_of_influence(seeds, every, start)
    relevant = tuple(t for t in every if not cone.isdisjoint(a.target for a in t.actions))
    boxes = boxes_reached(start, relevant, always)
    return may_hold(goal, boxes)[0]


def _assign(t: Transition, boxes: Boxes) -> bool:
    """Add what `t` assigns to the boxes; whether one grew."""
    grew = False
    for action in t.actions:
        if action.source is not None:
            added = set(boxes[action.source])
        else:
            assert action.value is not None  # an Assign has a value or a source
            added = {action.value}
        box = boxes[action.target]
        if not added <= box:
            box |= added
            grew = True
    return grew
