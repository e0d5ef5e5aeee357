"""Fast Downward and SymK as whole processes on one written PDDL pair, for the planning benchmark.

Both planners are Unified Planning engines (``up-fast-downward``, ``up-symk``), and each is run
with exactly the command line its engine builds (``_get_cmd``), so the configuration is the
engine's own:

* ``fast-downward-opt``: Fast Downward, ``--search astar(lmcut())`` (hard-coded by the engine);
* ``symk-opt``: SymK, ``--search sym_bd(bound=infinity)``, its optimal bidirectional symbolic
  search (the default of ``SymKOptimalPDDLPlanner``, what ``OneshotPlanner(name="symk-opt")``
  runs).

Unlike `bench.fd_runner` (which goes through ``OneshotPlanner.solve`` in this process and is
what the exporter's tests use), the PDDL is written once, outside any timing, and both drivers
read the same two files: what is timed is the planner's whole process (driver, translator,
search; `bench.process`), as `sp plan` is timed from its model file to its answer.  The plan
file is mapped back to transitions through the writer's names; the zero-cost bookkeeping
actions of the export are dropped, so ``length`` counts steps.
"""

from __future__ import annotations

import json
import re
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench import process

ROOT = Path(__file__).resolve().parent.parent

# Fast Downward's exit codes (driver/returncodes.py, the same in SymK)
_EXIT_STATUS = {0: "found", 10: "unsolvable", 11: "unsolvable", 12: "unsolved_incomplete"}
_EXIT_STATUS |= {20: "memout", 22: "memout", 24: "memout", 21: "timeout", 23: "timeout"}
_EXIT_STATUS |= {34: "unsupported", 37: "unsupported"}
_SEARCH_TIME = re.compile(r"Search time: ([0-9.]+)s")


@dataclass(frozen=True)
class ExternalPlanner:
    label: str  # as the table's column says it
    engine: str  # the Unified Planning engine's name
    search: str  # the configuration its command line passes, checked by the tests

    def installed(self) -> bool:
        try:
            self._engine()
        except (ImportError, KeyError):
            return False
        return True

    def command(self, domain: Path, problem: Path, plan: Path) -> list[str]:
        """The driver's command line, exactly as the engine builds it for a one-shot solve."""
        cmd: list[str] = self._engine()._get_cmd(str(domain), str(problem), str(plan))
        return cmd

    def _engine(self) -> Any:
        from unified_planning.environment import get_environment

        return get_environment().factory.engine(self.engine)()


FAST_DOWNWARD = ExternalPlanner("Fast Downward", "fast-downward-opt", "astar(lmcut())")
SYMK = ExternalPlanner("SymK", "symk-opt", "sym_bd(bound=infinity)")
PLANNERS = (FAST_DOWNWARD, SYMK)


@dataclass(frozen=True)
class PddlTask:
    """A problem written as PDDL, with the PDDL name of each action's exported name."""

    domain: Path
    problem: Path
    names: dict[str, str]


def write_pddl(problem: Any, directory: Path) -> PddlTask:
    """Write a Unified Planning problem (see `bench.pddl_export.to_up_problem`) as PDDL."""
    from unified_planning.io import PDDLWriter
    from unified_planning.model import Action

    writer = PDDLWriter(problem)
    domain, task = directory / "domain.pddl", directory / "problem.pddl"
    writer.write_domain(str(domain))
    writer.write_problem(str(task))
    # the actions the writer named: it leaves out those whose precondition is statically false
    names = {n: i.name for n, i in writer.nto_renamings.items() if isinstance(i, Action)}
    (directory / "names.json").write_text(json.dumps(names))
    return PddlTask(domain, task, names)


def export(model: dict[str, Any], goal: str, directory: Path, timeout: float) -> PddlTask | str:
    """The benchmark's export of `model` and `goal` (the specifications as invariants), written
    by a child process within `timeout` seconds; else why not, as the table should say.

    A child, because UP's PDDL writer takes time quadratic in the number of actions (each new
    name is checked against every action): about a minute at 1,000 transitions, and an
    estimated hour and more at 10,000, which a timeout must be able to stop.
    """
    (directory / "export.json").write_text(json.dumps({"model": model, "goal": goal}))
    command = [sys.executable, "-m", "bench.pddl_planners", str(directory)]
    run = process.run(command, timeout, cwd=ROOT)
    if run.timed_out:
        return f"export timeout ({timeout:g} s)"
    if run.returncode != 0:
        lines = run.stderr.strip().splitlines()
        return f"export failed: {lines[-1] if lines else run.returncode}"
    names = json.loads((directory / "names.json").read_text())
    return PddlTask(directory / "domain.pddl", directory / "problem.pddl", names)


@dataclass(frozen=True)
class ExternalResult:
    """``status``: found, unsolvable, unsolved_incomplete, timeout, memout, unsupported, error
    or "not installed"; ``plan`` holds transition names when found."""

    status: str
    plan: list[str] = field(default_factory=list)
    wall: float | None = None  # seconds, the whole process
    search: float | None = None  # seconds, as the search component prints it
    peak_mb: float | None = None
    log: str = ""

    @property
    def length(self) -> int | None:
        return len(self.plan) if self.status == "found" else None


def solve(planner: ExternalPlanner, task: PddlTask, timeout: float) -> ExternalResult:
    """Run `planner` on `task` as one process; at most `timeout` seconds."""
    if not planner.installed():
        return ExternalResult("not installed")
    with tempfile.TemporaryDirectory(prefix="bench-pddl-") as tmp:
        work = Path(tmp)  # the drivers write output.sas and the plan into their cwd
        plan_file = work / "plan"
        command = planner.command(task.domain, task.problem, plan_file)
        run = process.run(command, timeout, cwd=work)
        log = run.stdout + run.stderr
        searches = _SEARCH_TIME.findall(log)
        search = float(searches[-1]) if searches else None
        if run.timed_out:
            return ExternalResult("timeout", [], run.wall, search, run.peak_mb, log)
        status = _EXIT_STATUS.get(run.returncode, "error")
        written = [p for p in (plan_file, work / "plan.1") if p.exists()]
        if status != "found" or not written:  # "found" without a plan file is an error
            failed = status if status != "found" else "error"
            return ExternalResult(failed, [], run.wall, search, run.peak_mb, log)
        plan = transitions(written[0].read_text().splitlines(), task.names)
        return ExternalResult("found", plan, run.wall, search, run.peak_mb, log)


def transitions(plan_lines: Sequence[str], names: dict[str, str]) -> list[str]:
    """Transition names of a plan file's actions, bookkeeping actions left out."""
    from bench.pddl_export import transition_of

    plan = []
    for line in plan_lines:
        line = line.strip()
        if not line.startswith("("):
            continue  # "; cost = ..." and blank lines
        name = transition_of(names[line.strip("()").split()[0]])
        if name is not None:
            plan.append(name)
    return plan


def _export_here(directory: Path) -> None:
    from bench.pddl_export import to_up_problem

    spec = json.loads((directory / "export.json").read_text())
    problem = to_up_problem(spec["model"], None, spec["goal"], enforce_specifications=True)
    write_pddl(problem, directory)


if __name__ == "__main__":
    _export_here(Path(sys.argv[1]))
