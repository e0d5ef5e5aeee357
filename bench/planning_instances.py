"""The planning benchmark's instances, and issue 11's targets for them (see `bench.planning`).

Each instance is one row of the table: a model file, a goal (none for `sp check`), the series
it grows in (a tool that timed out on one instance is not run on the later ones) and, for the
plan rows, how to export it to PDDL.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from bench import cells, family, flat_export
from bench.planning_table import Target

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "models" / "demo_station.yaml"

PEAK = Target("peak < 300 MB")
TARGETS = {  # issue 27's targets (issue 11's were < 0.3 s for B=6 R=2, < 1 s and < 2 s for the
    # demo's goals, < 1 s for one cell's plan), by instance key; 300 MB everywhere
    "b6r2": Target("< 1 s", seconds=1.0),
    "b8r2": Target("< 5 s", seconds=5.0),
    "demo-synthesis": Target("< 2 s, < 300 MB", seconds=2.0),
    "demo-tighten": Target("< 5 s", seconds=5.0),
    "demo-assemble": Target("< 8 s", seconds=8.0),
    "cells1k-synthesis": Target("< 10 s", seconds=10.0),
    "cells1k-plan": Target("< 1 s", seconds=1.0),
    "cells10k-synthesis": Target("< 10 s", seconds=10.0),
    "cells10k-plan": Target("< 2 s (whole sp plan, warm)", seconds=2.0),
}
# every tool on small family rows, a target row, and the cells (the demo's synthesis alone takes
# longer than the whole quick run should)
QUICK = ("b1r1", "b4r1", "b2r2", "b6r2", "cells1k-synthesis", "cells1k-plan")


@dataclass
class Instance:
    key: str  # for --only
    name: str
    model: Path
    goal: str | None  # None for `sp check --no-cache`
    series: str  # later rows of a series are larger
    short: str  # the instance within its series, for "not run: B=5 timed out"
    synthesis: bool = False  # a synthesis row: every run with --no-cache
    # the flat model and goal for the PDDL export (plan rows only)
    pddl: Callable[[], tuple[dict[str, Any], str]] | None = None
    station: bool = False  # the demo or the cells (slow to export: UP's PDDL writer)
    sizes_model: Path | None = None  # model that `sp check` sizes, if not `model`
    scale: int = 1  # sizes_model's variables and transitions times this

    @property
    def target(self) -> Target:
        return TARGETS.get(self.key, PEAK)


def family_instances(directory: Path) -> list[Instance]:
    result = []
    for robots, most in ((1, 6), (2, 8), (3, 4)):
        for bolts in range(1, most + 1):
            model_dict = family.station(bolts, robots)
            path = directory / f"family_b{bolts}_r{robots}.yaml"
            path.write_text(yaml.safe_dump(model_dict, sort_keys=False, width=200))
            goal = family.goal(bolts)
            result.append(
                Instance(
                    f"b{bolts}r{robots}",
                    f"B={bolts} R={robots}",
                    path,
                    goal,
                    f"family R={robots}",
                    f"B={bolts}",
                    pddl=_given(model_dict, goal),
                )
            )
    return result


def _given(model: dict[str, Any], goal: str) -> Callable[[], tuple[dict[str, Any], str]]:
    return lambda: (model, goal)


def _station_pddl(path: Path, goal: str) -> Callable[[], tuple[dict[str, Any], str]]:
    def export() -> tuple[dict[str, Any], str]:
        station = flat_export.read(path)
        model = flat_export.flat_dict(station.model, drop=station.restart_transitions)
        return model, flat_export.goal_text(station, goal)

    return export


def demo_instances() -> list[Instance]:
    if not DEMO.exists():
        return []
    goals = [
        ("demo-bp1", "demo: bp1 tightened", "bp1.state == tightened"),
        ("demo-tighten", "demo: tighten_bolts", "tighten_bolts.goal"),
        ("demo-assemble", "demo: assemble_engine", "assemble_engine.goal"),
    ]
    synthesis = Instance(
        "demo-synthesis",
        "demo: synthesis (sp check --no-cache)",
        DEMO,
        None,
        "demo",
        "synthesis",
        synthesis=True,
    )
    plans = [
        Instance(
            key,
            name,
            DEMO,
            goal,
            "demo",
            name.removeprefix("demo: "),
            pddl=_station_pddl(DEMO, goal),
            station=True,
        )
        for key, name, goal in goals
    ]
    return [synthesis, *plans]


def cell_instances(directory: Path) -> list[Instance]:
    one = directory / "cells_1.yaml"
    one.write_text(cells.station_text(1))
    result = []
    goal = f"{cells.intention('c0')}.goal"
    for transitions, short in ((1_000, "1k"), (10_000, "10k")):
        n = cells.cells_for(transitions)
        path = directory / f"cells_{n}.yaml"
        path.write_text(cells.station_text(n))
        label = f"{transitions:,} transitions"
        common: dict[str, Any] = {"sizes_model": one, "scale": n}
        result += [
            Instance(
                f"cells{short}-synthesis",
                f"{label}: synthesis (sp plan --no-cache)",
                path,
                goal,
                "cells",
                f"{transitions:,} synthesis",
                synthesis=True,
                **common,
            ),
            Instance(
                f"cells{short}-plan",
                f"{label}: {goal}",
                path,
                goal,
                "cells",
                f"{transitions:,}",
                pddl=_station_pddl(path, goal),
                station=True,
                **common,
            ),
        ]
    return result


def all_instances(directory: Path) -> list[Instance]:
    """Every row, in the table's order; generated models are written into `directory`."""
    return family_instances(directory) + demo_instances() + cell_instances(directory)
