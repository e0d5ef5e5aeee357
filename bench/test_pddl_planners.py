"""Fast Downward and SymK as whole processes (bench/pddl_planners.py, bench/process.py).

The planners come with the ``bench`` extra (scripts/test installs it); without them their
tests are skipped, as the benchmark then says "not installed".
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from bench import pddl_planners, process
from bench.pddl_export import PlanError, check_plan, to_up_problem
from bench.test_pddl_export import ROBOT_NR, WINDOW

PLANNERS = [
    pytest.param(p, marks=pytest.mark.skipif(not p.installed(), reason=f"{p.label} missing"))
    for p in pddl_planners.PLANNERS
]


def test_configurations_are_the_engines_own(tmp_path: Path) -> None:
    for planner in pddl_planners.PLANNERS:
        if not planner.installed():
            continue
        command = planner.command(tmp_path / "d", tmp_path / "p", tmp_path / "plan")
        assert command[-2:] == ["--search", planner.search]
    assert pddl_planners.SYMK.search.startswith("sym_bd(")  # optimal bidirectional symbolic


@pytest.mark.parametrize("planner", PLANNERS)
def test_whole_process_plans_are_optimal_and_replay(
    planner: pddl_planners.ExternalPlanner, tmp_path: Path
) -> None:
    for goal, length in (("nr.running", 4), ("nr.running && r1.ref == tool", 5)):
        problem = to_up_problem(ROBOT_NR, None, goal)
        directory = tmp_path / str(length)
        directory.mkdir()
        result = pddl_planners.solve(planner, pddl_planners.write_pddl(problem, directory), 60)
        assert result.status == "found", result.log[-2000:]
        assert result.length == length and result.wall is not None and result.peak_mb
        assert result.search is not None  # both print "Search time: ..."
        check_plan(ROBOT_NR, None, goal, result.plan, expected_length=length)
    unreachable = to_up_problem(ROBOT_NR, None, "nr.running && !nr.run")
    result = pddl_planners.solve(planner, pddl_planners.write_pddl(unreachable, tmp_path), 60)
    assert result.status in ("unsolvable", "unsolved_incomplete")  # SymK exits with 12


@pytest.mark.parametrize("planner", PLANNERS)
def test_specifications_only_is_the_relaxed_problem(
    planner: pddl_planners.ExternalPlanner, tmp_path: Path
) -> None:
    """What the benchmark's † marks: with the specifications as invariants the planners find
    the relaxed optimum, through a state section 8 calls bad."""
    problem = to_up_problem(WINDOW, None, "x", enforce_specifications=True)
    result = pddl_planners.solve(planner, pddl_planners.write_pddl(problem, tmp_path), 60)
    assert result.plan == ["r.goto_b", "mark"]
    check_plan(WINDOW, None, "x", result.plan)
    with pytest.raises(PlanError, match="bad state"):
        check_plan(WINDOW, None, "x", result.plan, closure=True)


def test_export_runs_in_a_child_process(tmp_path: Path) -> None:
    task = pddl_planners.export(ROBOT_NR, "nr.running", tmp_path, 60)
    assert isinstance(task, pddl_planners.PddlTask), task
    assert task.domain.read_text().startswith("(define (domain")
    assert "nr.start" in task.names.values()  # PDDL name -> exported action name
    failed = pddl_planners.export(ROBOT_NR, "no_such_variable", tmp_path, 60)
    assert isinstance(failed, str) and failed.startswith("export failed: ")


@pytest.mark.parametrize("planner", PLANNERS)
def test_actions_the_writer_leaves_out(
    planner: pddl_planners.ExternalPlanner, tmp_path: Path
) -> None:
    """UP's writer leaves out an action whose precondition it simplifies to false (the demo
    has 44), which the export's own simplification keeps: the names map must cover exactly
    the written ones."""
    model = {
        "variables": [{"name": "v", "domain": ["a", "b"], "initial": "a"}],
        "transitions": [
            {"name": "never", "guard": "v == a && v != a", "actions": ["v := b"]},
            {"name": "set_b", "guard": "v == a", "actions": ["v := b"]},
        ],
    }
    task = pddl_planners.export(model, "v == b", tmp_path, 60)
    assert isinstance(task, pddl_planners.PddlTask), task
    assert list(task.names.values()) == ["set_b"]
    assert pddl_planners.solve(planner, task, 60).plan == ["set_b"]


def test_missing_planner_says_not_installed(tmp_path: Path) -> None:
    missing = pddl_planners.ExternalPlanner("Nothing", "no-such-engine", "none()")
    assert not missing.installed()
    task = pddl_planners.PddlTask(tmp_path / "d", tmp_path / "p", {})
    assert pddl_planners.solve(missing, task, 1).status == "not installed"


def test_timeout_kills_the_whole_process_group(tmp_path: Path) -> None:
    pid_file = tmp_path / "grandchild"
    script = (
        "import subprocess, sys, time\n"
        f"child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'])\n"
        f"open({str(pid_file)!r}, 'w').write(str(child.pid))\n"
        "time.sleep(60)\n"
    )
    run = process.run([sys.executable, "-c", script], 1.0)
    assert run.timed_out and run.returncode == -9 and run.wall < 10
    grandchild = int(pid_file.read_text())
    stat = Path(f"/proc/{grandchild}/stat")
    assert not stat.exists() or stat.read_text().split(") ")[1].startswith("Z")


def test_process_reports_peak_memory_and_cpu() -> None:
    script = "x = bytearray(200 * 1024 * 1024)\nsum(range(3_000_000))\nprint('done')"
    run = process.run([sys.executable, "-c", script], 60)
    assert (run.stdout.strip(), run.returncode, run.timed_out) == ("done", 0, False)
    assert 200 < run.peak_mb < 400 and run.cpu > 0
