"""Run Fast Downward (via Unified Planning's ``up-fast-downward`` engines) on exported problems.

``fast-downward-opt`` runs ``astar(lmcut())`` (hard-coded in ``FastDownwardOptimalPDDLPlanner``);
``fast-downward`` runs the ``lama-first`` alias (first iteration of LAMA 2011).  Each solve writes
PDDL to a temp dir and starts a fresh ``fast-downward.py`` driver process (Python translator, then
the C++ search binary), so every call pays process start-up plus translation; ``seconds`` is the
wall time of the whole ``solve`` call and ``process_seconds`` the part spent in the FD process.

Timeouts: UP runs FD in its own session and on expiry SIGTERMs the whole process group, so the
translator and the search are both stopped and the call returns status ``timeout``.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from unified_planning.engines import PlanGenerationResultStatus as S
from unified_planning.model import Problem
from unified_planning.shortcuts import OneshotPlanner

from .pddl_export import transition_of

OPTIMAL_ENGINE = "fast-downward-opt"
SATISFICING_ENGINE = "fast-downward"

_CWD_LOCK = threading.Lock()
_STATUS = {
    S.SOLVED_OPTIMALLY: "optimal",
    S.SOLVED_SATISFICING: "satisficing",
    S.UNSOLVABLE_PROVEN: "unsolvable",
    S.UNSOLVABLE_INCOMPLETELY: "unsolved_incomplete",
    S.TIMEOUT: "timeout",
    S.MEMOUT: "memout",
    S.UNSUPPORTED_PROBLEM: "unsupported",
    S.INTERNAL_ERROR: "error",
}


@dataclass
class FDResult:
    """Outcome of one solve; ``length``/``plan`` are set only when a plan was found.

    ``status`` is one of optimal, satisficing, unsolvable, unsolved_incomplete, timeout, memout,
    unsupported, error.  ``plan`` holds transition names (copy-grounding suffixes stripped).
    """

    status: str
    length: int | None
    plan: list[str]
    seconds: float
    process_seconds: float | None = None
    log: str = ""


def solve_optimal(problem: Problem, timeout_s: float) -> FDResult:
    """Optimal plan (A* + LM-cut); with unit costs ``length`` is the minimal number of steps."""
    return _solve(OPTIMAL_ENGINE, problem, timeout_s)


def solve_satisficing(problem: Problem, timeout_s: float) -> FDResult:
    """Some plan, fast (LAMA, first solution only); ``length`` is an upper bound."""
    return _solve(SATISFICING_ENGINE, problem, timeout_s)


@contextmanager
def _private_cwd() -> Iterator[None]:
    """FD's driver writes ``output.sas`` into the cwd (and runs ``python -m fast_downward...``
    from it), so concurrent or killed runs would clash or litter; give each solve its own cwd.
    ``os.chdir`` is process-wide, hence the lock: solves in one process are serialised."""
    with _CWD_LOCK, tempfile.TemporaryDirectory(prefix="fd-") as tmp:
        old = os.getcwd()
        os.chdir(tmp)
        try:
            yield
        finally:
            os.chdir(old)


def _solve(engine: str, problem: Problem, timeout_s: float) -> FDResult:
    problem.environment.credits_stream = None  # otherwise every planner prints its credits
    with _private_cwd(), OneshotPlanner(name=engine) as planner:
        start = time.perf_counter()
        try:
            with warnings.catch_warnings():
                # on timeout UP SIGTERMs FD but never waits for it nor closes its pipes
                warnings.simplefilter("ignore", ResourceWarning)
                res = planner.solve(problem, timeout=timeout_s)
        except Exception as exc:  # unsupported problem kind, PDDL writer errors, ...
            return FDResult("error", None, [], time.perf_counter() - start, log=repr(exc))
        seconds = time.perf_counter() - start
    status = _STATUS.get(res.status, "error")
    log = "\n".join(m.message for m in res.log_messages or [])
    internal = (res.metrics or {}).get("engine_internal_time")
    process_seconds = float(internal) if internal is not None else None
    if res.plan is None or status not in ("optimal", "satisficing"):
        return FDResult(status, None, [], seconds, process_seconds, log)
    names = (transition_of(a.action.name) for a in res.plan.actions)
    plan = [n for n in names if n is not None]  # drop zero-cost bookkeeping actions
    return FDResult(status, len(plan), plan, seconds, process_seconds, log)
