"""The layout holds: one place for each question (README, "Layout").

No import circle that runs; every arrow between the top-level folders and between the
planner's sub-packages runs down; no module over ~400 lines without its reason at its top;
no function over 60 lines but the declarative ones.  Measured from the code's own imports
and definitions (`tests.support.structure`).
"""

from __future__ import annotations

from tests.support.structure import Arrow, circles, group_of, modules

FOUND = modules()

# each folder may import those below it, never one above: the pure core at the bottom
FLOORS = ("planner", "hw", "app", "bench")
# the planner's sub-packages, each allowed the ones listed (DESIGN.md: a pure core in layers)
PLANNER = {
    "planner.model": set(),
    "planner.reading": {"planner.model"},
    "planner.bdd": {"planner.model"},
    "planner.planning": {"planner.model", "planner.reading", "planner.bdd"},
    "planner.runner": {"planner.model", "planner.reading", "planner.bdd", "planner.planning"},
    "planner.words": {"planner.model", "planner.reading", "planner.runner"},
}
# long by nature: one declaration each (the argument parser, a migration's tables)
DECLARATIVE = {
    ("app/cli/arguments.py", "parser"),
    ("migrations/versions/0001_station_store.py", "upgrade"),
}


def test_no_import_circle_runs_at_import_or_call_time() -> None:
    assert circles(FOUND, (Arrow.TOP, Arrow.LAZY)) == []


def test_no_arrow_runs_back_up_between_the_top_level_folders() -> None:
    up = [
        f"{m.name} -> {target}"
        for m in FOUND.values()
        for target, _ in m.imports
        if m.name.split(".")[0] in FLOORS
        and target.split(".")[0] in FLOORS
        and FLOORS.index(target.split(".")[0]) > FLOORS.index(m.name.split(".")[0])
    ]
    assert up == []


def test_no_arrow_runs_back_up_between_the_planners_sub_packages() -> None:
    assert set(PLANNER) == {group_of(m) for m in FOUND if m.startswith("planner.")} - {"planner"}
    up = [
        f"{m.name} -> {target} ({how})"
        for m in FOUND.values()
        if m.name.startswith("planner.")
        for target, how in m.imports
        if target.startswith("planner.")
        and group_of(target) != group_of(m.name)
        and group_of(target) not in PLANNER[group_of(m.name)]
    ]
    assert up == []


def test_a_module_over_400_lines_says_why_at_its_top() -> None:
    long = [
        m.relative
        for m in FOUND.values()
        if m.lines > 400 and not m.relative.startswith("bench/") and "\nSize:" not in m.docstring
    ]
    assert long == [], "split them, or give a 'Size:' paragraph in the module docstring"


def test_no_function_over_60_lines_but_the_declarative_ones() -> None:
    long = [
        f"{m.relative}:{line} {name} ({length} lines)"
        for m in FOUND.values()
        if not m.relative.startswith("bench/")
        for name, line, length in m.functions
        if length > 60 and (m.relative, name) not in DECLARATIVE
    ]
    assert long == []
