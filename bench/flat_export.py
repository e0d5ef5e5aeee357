"""A compiled station model as the flat dict of DESIGN.md section 8, for the PDDL export.

`planner.reading.load_station(text, path).model` compiles any model, station form included
(resources, abilities, operations), to a flat `planner.model.flat.Model`; :func:`flat_dict` writes
that back as the plain ``variables`` / ``transitions`` / ``specifications`` lists that
`bench.pddl_export` reads, so Fast Downward and SymK can plan on the demo station and on the
generated cells.  Only the model's public values are used (names, domains, kinds, guards and
actions printed in the section 8 syntax), so the export follows whatever the planner compiles.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from planner.model.expression_text import parse_expr
from planner.model.expressions import format_expr, format_value
from planner.model.flat import Model
from planner.model.station import Station
from planner.reading import load_station
from planner.reading.yaml_reader import scope_for


def flat_dict(model: Model, drop: Iterable[str] = ()) -> dict[str, Any]:
    """The flat form of `model`, without the transitions named in `drop`.

    `sp plan` removes the restart transitions from every query unless `--restart` is given, so
    callers drop those (`Station.restart_transitions`) to export the same problem.
    """
    _check_unambiguous(model)
    dropped = frozenset(drop)
    return {
        "variables": [
            {
                "name": v.name,
                "domain": "bool" if v.is_bool else [format_value(x) for x in v.domain],
                "initial": v.initial,
                "kind": v.kind.value,
            }
            for v in model.variables
        ],
        "transitions": [
            {
                "name": t.name,
                "kind": t.kind.value,
                "guard": format_expr(t.guard),
                "actions": [str(a) for a in t.actions],
            }
            for t in model.transitions
            if t.name not in dropped
        ],
        "specifications": [
            {"name": s.name, "invariant": format_expr(s.invariant)} for s in model.specifications
        ],
    }


def _check_unambiguous(model: Model) -> None:
    """Section 8 reads a bare word after `==` as a variable if one has that name: a domain
    value that is also a variable's name would print as a different expression."""
    names = set(model.variable_index)
    for v in model.variables:
        clash = names.intersection(x for x in v.domain if isinstance(x, str))
        if clash:
            raise ValueError(f"{v.name}: value {sorted(clash)[0]!r} is also a variable's name")


def goal_text(station: Station, goal: str) -> str:
    """`goal` with the station's named predicates (`tighten_bolts.goal`) written out."""
    scope = scope_for(station.model.domains, station.predicates)
    return format_expr(parse_expr(goal, scope))


def read(path: Path) -> Station:
    return load_station(path.read_text(encoding="utf-8"), str(path))
