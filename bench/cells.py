"""Station-form models of N independent pick-and-place cells, to scale the runner benchmark.

The demo station has 83 transitions; DESIGN.md section 7 asks for runner ticks far below the
devices' update period at 10,000.  Scaling the demo itself is not possible (its tools and
zones are shared by two robots), so each cell is a small copy of its patterns instead, in the
station form of docs/models.md, so that everything the runner does per tick (effects to
explain and watch, automatics to check, heartbeats, the supervisor) grows with the model:

- robot `cK_r`: command `ref`, measured `pos` over {home, pick, place}; ability `goto`, one
  instance per pose and one generic `arrive` effect (4 transitions);
- gripper `cK_g`: command `close`, measured `closed`; abilities `grip` and `release` in the
  pattern of seed 003 Table I: controlled start, effect, automatic finish that updates the
  part (3 transitions each);
- decision variable `cK_part.state` in {in, held, done};
- specifications: the gripper opens only standing at `place`, and the robot is at `place`
  only with a part picked (the supervisor extends both over the effects);
- operations `pick_cK`, `place_cK`, `home_cK` and intention `cell_cK` (part done, robot
  home; its action puts a new part in, so it can be started again).

10 transitions and 5 variables (8 BDD bits) per cell.
"""

from __future__ import annotations

from typing import Any

import yaml

TRANSITIONS_PER_CELL = 10
POSES = ["home", "pick", "place"]


def cell_names(cells: int) -> list[str]:
    return [f"c{k}" for k in range(cells)]


def intention(cell: str) -> str:
    return f"cell_{cell}"


def _cell(c: str) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, Any]]]:
    """One cell's resources, specifications and operations."""
    part = f"{c}_part.state"
    robot = {
        "name": f"{c}_r",
        "variables": [
            {"name": "ref", "domain": POSES, "initial": "home", "kind": "command"},
            {"name": "pos", "domain": POSES, "initial": "home", "kind": "measured"},
        ],
        "abilities": [
            {
                "name": "goto",
                "parameter": {"name": "target", "values": POSES},
                "predicates": {
                    "enabled": "pos == ref && ref != {target}",
                    "executing": "pos != ref",
                    "finished": "pos == {target} && ref == {target}",
                },
                "transitions": [
                    {"name": "start", "guard": "enabled", "actions": ["ref := {target}"]},
                    {
                        "name": "arrive",
                        "kind": "effect",
                        "guard": "executing",
                        "actions": ["pos := ref"],
                    },
                ],
            }
        ],
    }
    at = f"{c}_r.pos == {{0}} && {c}_r.ref == {{0}}"
    gripper = {
        "name": f"{c}_g",
        "variables": [
            {"name": "close", "domain": "bool", "initial": False, "kind": "command"},
            {"name": "closed", "domain": "bool", "initial": False, "kind": "measured"},
        ],
        "abilities": [
            {
                "name": "grip",
                "predicates": {
                    "enabled": "!close && !closed",
                    "executing": "close && !closed",
                    "finished": "close && closed",
                },
                "transitions": [
                    {
                        "name": "start",
                        "guard": f"enabled && {at.format('pick')} && {part} == in",
                        "actions": ["close := true"],
                    },
                    {
                        "name": "closes",
                        "kind": "effect",
                        "guard": "executing",
                        "actions": ["closed := true"],
                    },
                    {
                        "name": "finish",
                        "kind": "automatic",
                        "guard": f"finished && {part} == in",
                        "actions": [f"{part} := held"],
                    },
                ],
            },
            {
                "name": "release",
                "predicates": {
                    "enabled": "close && closed",
                    "executing": "!close && closed",
                    "finished": "!close && !closed",
                },
                "transitions": [
                    {
                        "name": "start",
                        "guard": f"enabled && {at.format('place')} && {part} == held",
                        "actions": ["close := false"],
                    },
                    {
                        "name": "opens",
                        "kind": "effect",
                        "guard": "executing",
                        "actions": ["closed := false"],
                    },
                    {
                        "name": "finish",
                        "kind": "automatic",
                        "guard": f"finished && {part} == held && {at.format('place')}",
                        "actions": [f"{part} := done"],
                    },
                ],
            },
        ],
    }
    specifications = [
        {
            "name": f"{c}_opens_only_at_place",
            "invariant": f"!{c}_g.close && {c}_g.closed -> {at.format('place')}",
        },
        {"name": f"{c}_at_place_only_holding", "invariant": f"{c}_r.pos == place -> {part} != in"},
    ]
    operations = [
        {"name": f"pick_{c}", "precondition": f"{part} == in", "effects": [f"{part} := held"]},
        {"name": f"place_{c}", "precondition": f"{part} == held", "effects": [f"{part} := done"]},
        {
            "name": f"home_{c}",
            "precondition": f"{part} == done && {c}_r.pos != home",
            "effects": [f"{c}_r.pos := home"],
            "goal": f"{c}_r.ref == home",
        },
    ]
    return [robot, gripper], specifications, operations


def station(cells: int) -> dict[str, Any]:
    """The station-form model of `cells` cells, as a YAML-ready dict."""
    variables: list[dict[str, Any]] = []
    resources: list[dict[str, Any]] = []
    specifications: list[dict[str, Any]] = []
    operations: list[dict[str, Any]] = []
    intentions: list[dict[str, Any]] = []
    for c in cell_names(cells):
        variables.append(
            {"name": f"{c}_part.state", "domain": ["in", "held", "done"], "kind": "decision"}
        )
        cell_resources, cell_specifications, cell_operations = _cell(c)
        resources += cell_resources
        specifications += cell_specifications
        operations += cell_operations
        intentions.append(
            {
                "name": intention(c),
                "precondition": f"{c}_part.state == in",
                "goal": f"{c}_part.state == done && {c}_r.pos == home",
                "actions": [f"{c}_part.state := in"],
            }
        )
    return {
        "station": f"cells_{cells}",
        "description": f"{cells} independent pick-and-place cells (bench/cells.py)",
        "variables": variables,
        "resources": resources,
        "specifications": specifications,
        "operations": operations,
        "intentions": intentions,
    }


def station_text(cells: int) -> str:
    return yaml.safe_dump(station(cells), sort_keys=False, width=200)


def cells_for(transitions: int) -> int:
    """How many cells make about `transitions` transitions (at least one)."""
    return max(1, round(transitions / TRANSITIONS_PER_CELL))
