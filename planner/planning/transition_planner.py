"""The transition planner: minimal, safe plans over a station's transitions (seed 000 sec. 4.3).

Built once per model: the BDD encoding, the bad states and the supervisor guards are computed
here, then every query runs on one of the engines (`bdd`: symbolic breadth-first search, the
default; `sat`: incremental SAT bounded model checking, the papers' method).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import cached_property
from typing import TYPE_CHECKING

from planner.bdd.guards import SupervisorGuard, supervisor_guards
from planner.bdd.sifting import sift
from planner.bdd.symbolic import Function, SymbolicModel
from planner.bdd.synthesis import (
    automatic_cycle,
    bad_by_specification,
    bad_parts,
    bad_states,
    breaking,
    violated_by,
)
from planner.model.expressions import TRUE, variables_of
from planner.model.flat import Model, SourceLocation
from planner.model.semantics import compile_expr
from planner.planning import search
from planner.planning.query import PlanQuery, PlanResult, PlanStatus, State
from planner.planning.symbolic_planner import ALL_REDUCTIONS, Reductions, SymbolicPlanner
from planner.reading.yaml_reader import Diagnostic, ModelError

if TYPE_CHECKING:
    from planner.planning.bmc import BoundedModelChecker

ENGINES = ("bdd", "sat")


def check_dynamics(sym: SymbolicModel) -> None:
    """Model errors that need the state space: a cycle of automatic transitions."""
    found = automatic_cycle(sym)
    if found is None:
        return
    cycle, looping = found
    first = sym.model.transition(cycle[0])
    where = first.source or SourceLocation(sym.model.file, 1, 1)
    read = set().union(*(variables_of(sym.model.transition(n).guard) for n in cycle))
    state = sym.pick(looping)
    shown = ", ".join(
        f"{v.name}={_show(value)}"
        for v, value in zip(sym.model.variables, state, strict=True)
        if v.name in read
    )
    path = " -> ".join([*cycle, cycle[0]])
    raise ModelError(
        [
            Diagnostic(
                where,
                f"automatic transitions can cycle forever: {path}"
                + (f" (e.g. from {shown})" if shown else "")
                + "; an automatic transition's actions should make some automatic guard false",
            )
        ]
    )


def _show(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


Restore = Callable[[SymbolicModel], tuple[Function, dict[str, Function]]]
"""Puts a saved variable order into a fresh encoding and returns the saved bad states, and
the states bad for each specification alone."""


class TransitionPlanner:
    """Built once per model; `restore` skips synthesis with a saved supervisor (see `saved`),
    `order` computing the static order when a saved, tuned one is at hand."""

    def __init__(
        self,
        model: Model,
        engine: str = "bdd",
        restore: Restore | None = None,
        reductions: Reductions = ALL_REDUCTIONS,
        order: Sequence[str] | None = None,
    ) -> None:
        if engine not in ENGINES:
            raise ValueError(f"unknown engine '{engine}'; use one of {', '.join(ENGINES)}")
        self.model = model
        self.engine = engine
        self.sym = SymbolicModel(model, order)
        if restore is None:  # a saved supervisor was saved by a build of the same text
            check_dynamics(self.sym)  # and code that checked it (supervisor_cache.key)
            self.bad_by_specification = bad_by_specification(self.sym)
            parts = bad_parts(self.sym, self.bad_by_specification)
            self.bad = bad_states(self.sym, parts)
            sift(self.sym, parts)  # what synthesis leaves in the manager shapes the order
        else:
            self.bad, self.bad_by_specification = restore(self.sym)
        self._search = SymbolicPlanner(self.sym, self.bad, self.bad_by_specification, reductions)
        # CUDD's own policy: it collects when dead nodes fill a share of the unique table.
        # Measured (README, "Garbage collection", bench/gc_policy.py): long searches take
        # 6.2 s and 118 MB with it against 8.3 s and 202 MB without; a station's stream of
        # small queries is 10-25 % slower with it (it empties the computed table) but stays
        # at 70 MB instead of 108 MB.  The long searches decide.
        self.sym.bdd.configure(garbage_collection=True)

    @property
    def tuned(self) -> bool:
        """Whether the variable order was sifted for search (see `SymbolicPlanner.tune`);
        the supervisor cache saves such an order, so later runs start with it."""
        return self._search.tuned

    @tuned.setter
    def tuned(self, value: bool) -> None:
        self._search.tuned = value

    def prepare(self) -> None:
        """Everything a first plan would do once before it searches (choosing the order
        for search), so that a station can do it while it builds its planners."""
        self._search.tune()

    def order(self) -> list[str]:
        """The current BDD variable order, for saving with the bad states."""
        bdd = self.sym.bdd
        return sorted(bdd.vars, key=bdd.level_of_var)

    @cached_property
    def guards(self) -> list[SupervisorGuard]:
        """Computed when first asked for: `sp check` prints them, planning needs only `bad`."""
        return supervisor_guards(self.sym, self.bad)

    @cached_property
    def _bmc(self) -> BoundedModelChecker:
        from planner.planning.bmc import BoundedModelChecker

        return BoundedModelChecker(self.sym, self.bad)

    def plan(self, query: PlanQuery, engine: str | None = None) -> PlanResult:
        chosen = engine or self.engine
        result = self._bmc.plan(query) if chosen == "sat" else self._search.plan(query)
        if result.status is PlanStatus.BAD_START:
            result = PlanResult(
                PlanStatus.BAD_START,
                violated=tuple(self.violated(query)),
                max_steps=query.max_steps,
                engine=result.engine,
            )
        return result

    def reachable(self, start: State, *, maintenance: bool = False) -> Function:
        """The good states plans can reach from `start` (for sizes and benchmarks)."""
        usable = self._search.usable(PlanQuery(start, TRUE, maintenance=maintenance))
        automatic = self._search.automatic(usable)
        return search.reachable(
            self.sym, self.sym.state(start), usable, automatic, self._search.good
        )

    def violated(self, query: PlanQuery) -> list[str]:
        """Why a start state is bad: the specifications it is bad for, then forbidden[i] and
        kept[i]."""
        start = self.sym.state(query.start)
        names = sorted(violated_by(self.sym, start)) if start & self.bad != self.sym.false else []
        index = self.model.variable_index
        for i, predicate in enumerate(query.forbidden):
            if compile_expr(predicate, index)(query.start):
                names.append(f"forbidden[{i}]")
        for i, predicate in enumerate(query.kept):
            if start & breaking(self.sym, predicate) != self.sym.false:
                names.append(f"kept[{i}]")
        return names
