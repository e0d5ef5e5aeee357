"""The planning benchmark's table and targets (bench/planning_table.py), and one small run."""

from __future__ import annotations

from pathlib import Path

from bench import pddl_planners, planning, planning_instances, process
from bench.planning_table import HEADER, Row, Target, table


def _run(wall: float, peak: float) -> process.ProcessRun:
    return process.ProcessRun("", "", 0, wall, wall, peak, False)


def test_targets_are_judged_on_the_warm_median_and_the_peak() -> None:
    target = Target("< 1 s, < 200 MB", seconds=1.0, megabytes=200)
    row = Row("B=8 R=2", target, cold=_run(5.0, 150), runs=[_run(0.5, 100), _run(0.9, 120)])
    assert row.met() == "yes"  # the cold run's synthesis is not judged against the time
    row.runs += [_run(2.0, 250), _run(3.0, 110)]
    assert row.met() == "**no**: 1.45 s, 250 MB"  # the median of four
    assert Row("x", target, failure="not run: B=7 timed out").met() == "**no**: not run"


def test_table_flags_length_mismatches_and_gives_ratios() -> None:
    found = pddl_planners.ExternalResult("found", ["t"] * 12, wall=2.0, search=1.5, peak_mb=40)
    row = Row("B=1 R=1", Target("peak < 300 MB"), length=11, cold=_run(0.3, 41))
    row.runs = [_run(0.2, 41)]
    row.external = {"Fast Downward": (found, []), "SymK": "not installed"}
    text = table([row])
    header, rule, line = text.splitlines()
    assert header.count("|") == rule.count("|") == line.count("|")
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert "2,000 (1,500), 40 **length 12!**" in cells
    assert "not installed" in cells and "10.0x" in cells and cells[-1] == "yes"


def test_benchmark_end_to_end_on_the_smallest_instance(tmp_path: Path) -> None:
    output = tmp_path / "planning.md"
    planning.main(["--only", "b1r1", "--runs", "1", "--output", str(output)])
    lines = output.read_text().splitlines()
    assert lines[0].startswith("Machine: ")
    row = next(line for line in lines if line.startswith("| B=1 R=1 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1:5] == ["7 (10)", "12", "110", "11"]
    for planner in pddl_planners.PLANNERS:
        column = HEADER.index(f"{planner.label} ms (search), MB")
        if planner.installed():
            assert cells[column][0].isdigit() and "!" not in cells[column], cells[column]
        else:
            assert cells[column] == "not installed"


def test_instances_are_the_issues_rows_with_its_targets(tmp_path: Path) -> None:
    instances = planning_instances.all_instances(tmp_path)
    keys = [i.key for i in instances]
    assert len(set(keys)) == len(keys)
    assert set(planning_instances.TARGETS) | set(planning_instances.QUICK) <= set(keys)
    family = [i.name for i in instances if i.series.startswith("family")]
    assert len(family) == 6 + 8 + 4 and "B=8 R=2" in family
    goals = {i.key: i.goal for i in instances if i.series == "demo"}
    assert goals == {
        "demo-synthesis": None,
        "demo-bp1": "bp1.state == tightened",
        "demo-tighten": "tighten_bolts.goal",
        "demo-assemble": "assemble_engine.goal",
    }
    for i in instances:  # the synthesis rows have no export, every plan row has one
        assert (i.pddl is None) == i.synthesis, i.key
