"""What ties a model's variables together: the variables each transition touches, and groups.

Synthesis (components of the bad states), sifting (blocks sifted apart) and planning
(independent parts of a query) each group the variables by a different set of ties; the
grouping itself is this one union-find.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from functools import cache

from planner.model.expressions import variables_of
from planner.model.flat import Transition


@cache
def reads(transition: Transition) -> frozenset[str]:
    """The variables a transition's guard and the sources of its actions read."""
    sources = {a.source for a in transition.actions if a.source is not None}
    return variables_of(transition.guard) | sources


def touched(transition: Transition) -> frozenset[str]:
    """The variables a transition reads (guard, copied sources) or writes."""
    return reads(transition) | transition.written


class Groups:
    """Variables joined into groups (union-find); a group is named by its first variable in
    the given order, and its members keep that order."""

    def __init__(self, names: Iterable[str]) -> None:
        self._order = {name: k for k, name in enumerate(names)}
        self._parent = {name: name for name in self._order}

    def copy(self) -> Groups:
        other = Groups(())
        other._order = self._order
        other._parent = dict(self._parent)
        return other

    def find(self, name: str) -> str:
        parent = self._parent
        while parent[name] != name:
            parent[name] = parent[parent[name]]
            name = parent[name]
        return name

    def join(self, names: Iterable[str]) -> None:
        roots = sorted({self.find(n) for n in names}, key=self._order.__getitem__)
        for root in roots[1:]:
            self._parent[root] = roots[0]

    def members(self) -> Mapping[str, list[str]]:
        """Each group's root and its members, groups in the order of their first members."""
        groups: dict[str, list[str]] = {}
        for name in self._order:
            groups.setdefault(self.find(name), []).append(name)
        return groups
