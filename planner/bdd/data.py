"""Named BDDs as plain data (lists of ints and names), and back, in any manager.

The supervisor cache keeps the states bad for each specification: at 10,000 transitions a
thousand small roots.  `dd`'s own JSON reader rebuilds them through a `shelve` file on disk
(2.4 s there, slower than synthesising them); this form is read by one `ite` per node.

A reference is 0 for true, 1 for false, and 2 (i + 1) + c for node i of the list, negated
when c is 1 (CUDD's complement edges: a node and its negation share one entry).  A node
is (bit, low, high), its children listed before it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from planner.bdd.symbolic import Function

TRUE, FALSE = 0, 1


def to_data(roots: Mapping[str, Function]) -> dict[str, Any]:
    """`roots` as {"nodes": [[bit, low, high], ...], "roots": {name: reference}}."""
    nodes: list[list[Any]] = []
    index: dict[int, int] = {}  # a regular node's id: its reference without negation

    def reference(f: Function) -> int:
        negated = 1 if f.negated else 0
        regular = ~f if negated else f
        if regular == regular.bdd.true:
            return FALSE if negated else TRUE
        return index[int(regular)] + negated

    for root in roots.values():
        stack = [~root if root.negated else root]
        while stack:  # children first, without recursion (a root may read every bit)
            f = stack[-1]
            if int(f) in index or f == f.bdd.true:
                stack.pop()
                continue
            children = [~c if c.negated else c for c in (f.low, f.high)]
            waiting = [c for c in children if int(c) not in index and c != c.bdd.true]
            if waiting:
                stack.extend(waiting)
                continue
            stack.pop()
            nodes.append([f.var, reference(f.low), reference(f.high)])
            index[int(f)] = 2 * len(nodes)
    return {"nodes": nodes, "roots": {name: reference(f) for name, f in roots.items()}}


def from_data(bdd: Any, data: Mapping[str, Any]) -> dict[str, Function]:
    """The roots of `to_data`'s form, built in `bdd` (any variable order); a reference to a
    node not listed yet, or a bit `bdd` lacks, is a ValueError."""
    built: list[Function] = [bdd.true, bdd.false]
    bits: dict[str, Function] = {}

    def function(ref: object) -> Function:
        if not isinstance(ref, int) or not 0 <= ref < len(built):
            raise ValueError(f"a BDD reference out of range: {ref!r}")
        if ref < 2:
            return built[ref]
        node = built[ref & ~1]
        return ~node if ref & 1 else node

    for entry in data["nodes"]:
        if not (isinstance(entry, list) and len(entry) == 3 and isinstance(entry[0], str)):
            raise ValueError(f"a BDD node is not [bit, low, high]: {entry!r}")
        bit, low, high = entry
        if bit not in bits:
            if bit not in bdd.vars:
                raise ValueError(f"a BDD node reads an unknown bit '{bit}'")
            bits[bit] = bdd.var(bit)
        node = bdd.ite(bits[bit], function(high), function(low))
        built += [node, node]  # references 2 (i + 1) and 2 (i + 1) + 1 share it
    return {str(name): function(ref) for name, ref in data["roots"].items()}
