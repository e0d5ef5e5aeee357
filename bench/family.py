"""A scalable station family for benchmarks: B bolt pairs, R robots, one shared nutrunner.

An operator places bolt pairs (any order); a robot fetches the nutrunner from its rack,
starts it, moves onto a placed pair and tightens it when the torque is reached.  The
specifications are the demo station's: the nutrunner must already run when its robot is at a
placed pair, and two robots never share a bolt pair's zone.  The goal is every pair
tightened.  Minimal plans have 8 B + 3 steps (11 ... 51 for B = 1 ... 6); the extra robots
add reachable states, not steps.  Models are the flat form of DESIGN.md section 8.
"""

from __future__ import annotations

from typing import Any


def station(bolt_pairs: int, robots: int) -> dict[str, Any]:
    bolts = [f"bp{i}" for i in range(1, bolt_pairs + 1)]
    robot_names = [f"r{i}" for i in range(1, robots + 1)]
    positions = ["home", "rack", *bolts]
    variables: list[dict[str, Any]] = []
    transitions: list[dict[str, Any]] = []
    specifications: list[dict[str, Any]] = []

    for bolt in bolts:
        variables.append(
            {
                "name": f"{bolt}.state",
                "domain": ["empty", "placed", "tightened"],
                "initial": "empty",
                "kind": "estimated",
            }
        )
        transitions.append(
            {
                "name": f"operator.place_{bolt}",
                "guard": f"{bolt}.state == empty",
                "actions": [f"{bolt}.state := placed"],
            }
        )
    variables += [
        {
            "name": "nr.holder",
            "domain": ["rack", *robot_names],
            "initial": "rack",
            "kind": "estimated",
        },
        {"name": "nr.run", "domain": "bool", "initial": False, "kind": "command"},
        {"name": "nr.running", "domain": "bool", "initial": False, "kind": "measured"},
        {"name": "nr.torque", "domain": "bool", "initial": False, "kind": "measured"},
    ]
    transitions += [
        {
            "name": "nr.start",
            "guard": "nr.holder != rack && !nr.run && !nr.running",
            "actions": ["nr.run := true"],
        },
        {
            "name": "nr.spin_up",
            "kind": "effect",
            "guard": "nr.run && !nr.running",
            "actions": ["nr.running := true"],
        },
        {
            "name": "nr.spin_down",
            "kind": "effect",
            "guard": "!nr.run && nr.running",
            "actions": ["nr.running := false", "nr.torque := false"],
        },
    ]
    for robot in robot_names:
        variables += [
            {"name": f"{robot}.ref", "domain": positions, "initial": "home", "kind": "command"},
            {"name": f"{robot}.pos", "domain": positions, "initial": "home", "kind": "measured"},
        ]
        for target in positions:
            transitions.append(
                {
                    "name": f"{robot}.goto_{target}",
                    "guard": f"{robot}.pos == {robot}.ref && {robot}.ref != {target}",
                    "actions": [f"{robot}.ref := {target}"],
                }
            )
        transitions += [
            {
                "name": f"{robot}.arrive",
                "kind": "effect",
                "guard": f"{robot}.pos != {robot}.ref",
                "actions": [f"{robot}.pos := {robot}.ref"],
            },
            {
                "name": f"{robot}.attach_nr",
                "guard": f"{robot}.pos == rack && {robot}.ref == rack && nr.holder == rack",
                "actions": [f"nr.holder := {robot}"],
            },
            {
                "name": f"{robot}.detach_nr",
                "guard": f"{robot}.pos == rack && {robot}.ref == rack && nr.holder == {robot}"
                " && !nr.run && !nr.running",
                "actions": ["nr.holder := rack"],
            },
        ]
        at_bolt = " || ".join(f"({robot}.pos == {b} && {b}.state == placed)" for b in bolts)
        transitions.append(
            {
                "name": f"nr.torque_{robot}",
                "kind": "effect",
                "guard": f"nr.running && !nr.torque && nr.holder == {robot} && ({at_bolt})",
                "actions": ["nr.torque := true"],
            }
        )
        for bolt in bolts:
            transitions.append(
                {
                    "name": f"nr.tighten_{bolt}_{robot}",
                    "kind": "automatic",
                    "guard": f"nr.run && nr.torque && nr.holder == {robot} && {robot}.pos == {bolt}"
                    f" && {bolt}.state == placed",
                    "actions": ["nr.run := false", f"{bolt}.state := tightened"],
                }
            )
            specifications.append(
                {
                    "name": f"nr_runs_before_{robot}_at_{bolt}",
                    "invariant": f"{robot}.pos == {bolt} && {bolt}.state == placed"
                    f" && nr.holder == {robot} -> nr.running",
                }
            )
    for i, first in enumerate(robot_names):
        for second in robot_names[i + 1 :]:
            for bolt in bolts:
                specifications.append(
                    {
                        "name": f"zone_{bolt}_{first}_{second}",
                        "invariant": f"!({first}.pos == {bolt} && {second}.pos == {bolt})",
                    }
                )
    return {"variables": variables, "transitions": transitions, "specifications": specifications}


def goal(bolt_pairs: int) -> str:
    """Every pair tightened and the nutrunner stopped."""
    return " && ".join(
        [*(f"bp{i}.state == tightened" for i in range(1, bolt_pairs + 1)), "!nr.running"]
    )
